"""Evaluation harness: error (PSNR/SSIM) beside time per frame, for any methods.

* :func:`frames_from_dataset` — GT frames of spikesim HDF5 files with the
  readout window around each;
* :func:`frames_from_simulation` — the same from a scene simulated in memory;
* :func:`run` — reconstruct every frame with every method, score it
  (:func:`spikejdd.metrics.score`, every convention labelled) and time it:
  one untimed warm-up call per method, then the median of ``repeats`` timed
  calls per frame (wall clock, ``time.perf_counter``);
* :func:`sweep` — the shape of SJDD-Net's Table 1 (AAAI 2024): Gaussian noise
  σ ∈ {0, 5, 10, 15} and random Gaussian–Poisson noise, on an object-motion
  and a camera-motion set simulated on the fly;
* :func:`write_report` — JSON, Markdown and a speed-against-error PNG.
"""

from __future__ import annotations

import json
import os
import platform
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

from spikejdd.metrics import score
from spikejdd.registry import get_method
from spikesim.errors import bad_value

__all__ = ["Frame", "frames_from_dataset", "frames_from_simulation", "run", "sweep",
           "write_report", "SWEEP_LEVELS", "SWEEP_SETS", "machine_info"]

HEADLINE = ("PSNR[linear]", "SSIM-gauss11[linear]", "PSNR[srgb]", "SSIM-gauss11[srgb]")


@dataclass
class Frame:
    """One scored frame: spikes around a GT readout and the GT itself."""

    sequence: str
    readout: int
    spikes: np.ndarray  # (L, H, W) uint8
    center: int  # index into spikes
    cfa: str | None
    rate: float
    gt: np.ndarray  # (H, W, 3) float32
    group: dict = field(default_factory=dict)


def _check_context(context: int) -> int:
    if isinstance(context, bool) or not isinstance(context, int) or context < 1:
        raise bad_value("context", context, "an integer >= 1 readouts")
    return context


def frames_from_dataset(path, context: int = 41, per_sequence: int = 1) -> list[Frame]:
    """Frames of a spikesim file or folder: up to ``per_sequence`` GT readouts per
    sequence (spread evenly over those with a full ``context``-readout window)."""
    from spikesim.io import open_dataset

    _check_context(context)
    ds = open_dataset(path)
    frames = []
    for name in ds.names:
        seq = ds.sequence(name)
        half = context // 2
        ok = [(k, int(g)) for k, g in enumerate(seq.gt_index)
              if g - half >= 0 and g - half + context <= seq.n_readouts]
        if not ok:
            continue
        pick = np.unique(np.linspace(0, len(ok) - 1, min(per_sequence, len(ok))).round())
        rate = float((seq.meta.get("sensor") or {}).get("full_scale_rate", 0.6))
        for j in pick.astype(int):
            k, g = ok[j]
            frames.append(Frame(name, g, seq.read_window(g - half, context), half, seq.cfa,
                                rate, seq.read_gt(k)))
        if hasattr(seq, "close"):
            seq.close()
    if not frames:
        raise bad_value("context", context, f"a window that fits some GT readout in {path}")
    return frames


def frames_from_simulation(scene, sensor, name: str, gt_readouts, context: int = 41,
                           seed: int = 0, group: dict | None = None) -> list[Frame]:
    """Simulate ``scene`` just long enough and cut a window around each GT readout."""
    import spikesim as ss

    half = _check_context(context) // 2
    gt_readouts = [int(g) for g in gt_readouts]
    n = max(gt_readouts) - half + context
    if min(gt_readouts) - half < 0:
        raise bad_value("gt_readouts", gt_readouts, f"readouts >= {half} (half the context)")
    stream = ss.simulate(scene, sensor, n_readouts=n, seed=seed, gt_readouts=gt_readouts)
    spikes = stream.unpack()
    gts = dict(zip(np.asarray(stream.gt_index).tolist(), stream.gt, strict=True))
    return [Frame(name, g, spikes[g - half:g - half + context], half, stream.cfa,
                  float(sensor.full_scale_rate), gts[g], dict(group or {})) for g in gt_readouts]


def _time_call(fn, repeats: int):
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = fn()
        times.append(time.perf_counter() - t0)
        out = res if out is None else out
    return out, float(np.median(times))


def run(frames: list[Frame], methods: list[str], repeats: int = 3, progress: bool = True,
        outputs: dict | None = None) -> dict:
    """Score and time every method on every frame; see the module doc for the timing rule.

    When ``outputs`` is a dict it receives each reconstruction under
    ``(method, frame index)`` (for image panels, without reconstructing again).
    """
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise bad_value("repeats", repeats, "an integer >= 1")
    if not frames:
        raise bad_value("frames", frames, "at least one frame")
    fns = {m: get_method(m) for m in methods}  # validates every name up front
    rows = []
    bar = tqdm(total=len(frames) * len(methods), desc="evaluate", disable=not progress)
    for m, fn in fns.items():
        f0 = frames[0]
        fn(f0.spikes, f0.cfa, f0.center, rate=f0.rate)  # warm-up, not timed
        for i, f in enumerate(frames):
            out, sec = _time_call(lambda f=f, fn=fn: fn(f.spikes, f.cfa, f.center, rate=f.rate),
                                  repeats)
            if outputs is not None:
                outputs[(m, i)] = out
            rows.append({"method": m, "sequence": f.sequence, "readout": f.readout,
                         **f.group, "seconds": sec, **score(out, f.gt)})
            bar.update()
    bar.close()
    return {"rows": rows, "summary": summarize(rows, methods)}


def summarize(rows: list[dict], methods: list[str], by: tuple[str, ...] = ()) -> dict:
    """Mean of every metric and of the time per frame, per method (and per ``by`` keys)."""
    out: dict = {}
    for m in methods:
        sel = [r for r in rows if r["method"] == m]
        groups: dict = {}
        for r in sel:
            groups.setdefault(tuple(r.get(k) for k in by), []).append(r)
        for key, rs in groups.items():
            entry = {lab: float(np.mean([r[lab] for r in rs])) for lab in rs[0]
                     if "[" in lab}
            entry["ms_per_frame"] = 1000.0 * float(np.mean([r["seconds"] for r in rs]))
            entry["frames"] = len(rs)
            out.setdefault(m, {})["/".join(str(k) for k in key) or "all"] = entry
    return out


def machine_info() -> dict:
    return {"machine": platform.machine(), "processor": platform.processor() or "unknown",
            "cpus": os.cpu_count(), "python": platform.python_version(),
            "note": "2-core AMD EPYC VM shared with other work while measuring; times are "
                    "indicative (median of repeats, warm-up excluded)"}


# --- sweep -----------------------------------------------------------------
#: (label, sigma_g, sigma_p) in 8-bit DN; ``None`` = drawn per sequence (random GPN).
SWEEP_LEVELS: tuple[tuple[str, float | None, float | None], ...] = (
    ("GN0", 0.0, 0.0), ("GN5", 5.0, 0.0), ("GN10", 10.0, 0.0), ("GN15", 15.0, 0.0),
    ("GPN-rand", None, None),
)
#: Set → list of (scene name, motion) for ``spikesim.scenes.procedural``.
SWEEP_SETS: dict[str, list[tuple[str, str | None]]] = {
    "object": [("sprites", None), ("fan", None), ("disk", None)],
    "camera": [("astronaut", "pan"), ("coffee", "shake"), ("chelsea", "zoom")],
}
#: Random GPN draws (our choice; the paper samples both levels at random too).
GPN_RANGE = {"sigma_g": (0.0, 15.0), "sigma_p": (0.0, 1.0)}


def sweep(methods: list[str], size=(64, 96), context: int = 41, frames_per_scene: int = 2,
          repeats: int = 3, seed: int = 0, progress: bool = True) -> dict:
    """Table-1-shaped sweep on sets simulated on the fly (see module doc)."""
    import spikesim as ss
    from spikesim.scenes.procedural import procedural

    rng = np.random.default_rng(seed)
    frames = []
    half = context // 2
    gt_readouts = [half + 10 * i for i in range(frames_per_scene)]
    jobs = [(lv, s, sc) for lv in SWEEP_LEVELS for s in SWEEP_SETS for sc in SWEEP_SETS[s]]
    # one simulation seed for every condition: common random numbers, so the
    # noise levels and methods are compared on paired realisations
    for (label, sg, sp), set_name, (name, motion) in tqdm(
            jobs, desc="simulate", disable=not progress):
        if sg is None:
            sg = float(rng.uniform(*GPN_RANGE["sigma_g"]))
            sp = float(rng.uniform(*GPN_RANGE["sigma_p"]))
        noise = ss.noise.PaperNoise(sigma_g=sg, sigma_p=sp) if (sg or sp) else None
        sensor = ss.Sensor(height=size[0], width=size[1], cfa="RGGB", clock_hz=20_000.0,
                           full_scale_rate=0.6, noise=noise)
        scene = procedural(name, motion=motion, size=tuple(size))
        seq = f"{name}-{motion}" if motion else name
        frames += frames_from_simulation(
            scene, sensor, seq, gt_readouts, context, seed=seed,
            group={"set": set_name, "noise": label, "sigma_g": sg, "sigma_p": sp})
    result = run(frames, methods, repeats=repeats, progress=progress)
    result["table"] = summarize(result["rows"], methods, by=("set", "noise"))
    result["config"] = {"size": list(size), "context": context,
                        "frames_per_scene": frames_per_scene,
                        "repeats": repeats, "seed": seed, "sets": SWEEP_SETS,
                        "levels": [lv[0] for lv in SWEEP_LEVELS], "gpn_range": GPN_RANGE,
                        "sensor": "RGGB, 20 kHz, full_scale_rate 0.6, modulo reset, paper noise"}
    return result


# --- report ----------------------------------------------------------------
def _md_table(result: dict, methods: list[str]) -> list[str]:
    lines = ["| method | " + " | ".join(HEADLINE) + " | ms/frame |",
             "|---" * (len(HEADLINE) + 2) + "|"]
    for m in methods:
        e = result["summary"][m]["all"]
        vals = [f"{e[k]:.2f}" if k.startswith("PSNR") else f"{e[k]:.4f}" for k in HEADLINE]
        lines.append(f"| {m} | " + " | ".join(vals) + f" | {e['ms_per_frame']:.1f} |")
    return lines


def write_report(result: dict, methods: list[str], stem, command: str = "") -> list[Path]:
    """Write ``stem.json``, ``stem.md`` and ``stem.png``; returns the paths."""
    stem = Path(stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    result = dict(result, methods=methods, machine=machine_info(), command=command,
                  conventions="PSNR peak 1.0, RGB, clamp [0,1], no crop; SSIM gauss11 = 11x11 "
                              "Gaussian sigma 1.5, uniform7 = 7x7 uniform (scikit-image); "
                              "[linear] = linear light, [srgb] = sRGB-encoded")
    paths = [stem.with_suffix(".json"), stem.with_suffix(".md"), stem.with_suffix(".png")]
    paths[0].write_text(json.dumps(result, indent=1, default=float))
    md = [f"# {stem.name}", "", f"Command: `{command}`" if command else "", "",
          f"Machine: {result['machine']['note']} ({result['machine']['cpus']} CPUs).", "",
          f"Conventions: {result['conventions']}.", "", "## Mean over all frames", ""]
    md += _md_table(result, methods)
    if "table" in result:
        cols = [(s, lv[0]) for s in SWEEP_SETS for lv in SWEEP_LEVELS]
        md += ["", "## PSNR[linear] / SSIM-gauss11[linear] by set and noise (Table 1 shape)", "",
               "| method | " + " | ".join(f"{s} {lv}" for s, lv in cols) + " |",
               "|---" * (len(cols) + 1) + "|"]
        for m in methods:
            cells = []
            for s, lv in cols:
                e = result["table"][m].get(f"{s}/{lv}")
                cells.append("-" if e is None else
                             f"{e['PSNR[linear]']:.2f} / {e['SSIM-gauss11[linear]']:.3f}")
            md.append(f"| {m} | " + " | ".join(cells) + " |")
    else:
        md += ["", "## PSNR[linear] per sequence", ""]
        seqs = sorted({r["sequence"] for r in result["rows"]})
        md += ["| method | " + " | ".join(seqs) + " |", "|---" * (len(seqs) + 1) + "|"]
        for m in methods:
            cells = [f"{np.mean([r['PSNR[linear]'] for r in result['rows'] if r['method'] == m and r['sequence'] == s]):.2f}" for s in seqs]  # noqa: E501
            md.append(f"| {m} | " + " | ".join(cells) + " |")
    paths[1].write_text("\n".join(md) + "\n")
    _scatter(result, methods, paths[2])
    return paths


def _scatter(result: dict, methods: list[str], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for m in methods:
        e = result["summary"][m]["all"]
        ax.scatter(e["ms_per_frame"], e["PSNR[linear]"])
        ax.annotate(m, (e["ms_per_frame"], e["PSNR[linear]"]), fontsize=7,
                    xytext=(3, 3), textcoords="offset points")
    ax.set_xscale("log")
    ax.set_xlabel("time per frame (ms, median of repeats, warm-up excluded)")
    ax.set_ylabel("mean PSNR, linear light (dB)")
    ax.set_title("speed against error")
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
