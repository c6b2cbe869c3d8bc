"""Evaluation harness: error (PSNR/SSIM) beside time per frame, for any methods.

* :func:`frames_from_dataset` — GT frames of spikesim HDF5 files with the
  readout window around each, labelled with their noise and motion (from the
  sequence metadata);
* :func:`frames_from_simulation` — the same from a scene simulated in memory;
* :func:`run` — reconstruct every frame with every method, score it
  (:func:`spikejdd.metrics.score`, every convention labelled) and time it:
  one untimed warm-up call per method, then the median of ``repeats`` timed
  calls per frame (wall clock, ``time.perf_counter``);
* :func:`sweep` — the shape of SJDD-Net's Table 1 (AAAI 2024): Gaussian noise
  σ ∈ {0, 5, 10, 15} and random Gaussian–Poisson noise, on an object-motion
  and a camera-motion set simulated on the fly;
* :func:`write_report` — JSON, Markdown (tables per noise label and per
  motion, image panels of the ground truth and every method on the same
  crop, the machine as it describes itself) and a speed-against-error PNG.
"""

from __future__ import annotations

import contextlib
import json
import os
import secrets
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

from spikejdd.metrics import score
from spikejdd.registry import call_method, get_method
from spikejdd.runtime import describe_machine, machine_info
from spikesim.errors import SpikeSimError, SpikeSimFileError, SpikeSimValueError, bad_value
from spikesim.io import sequence_labels  # shared with `spikesim info`
from spikesim.io.atomic import atomic_path
from spikesim.srgb import linear_to_srgb8

__all__ = ["Frame", "frames_from_dataset", "frames_from_simulation", "run", "sweep",
           "write_report", "SWEEP_LEVELS", "SWEEP_SETS", "machine_info", "sequence_labels",
           "DEFAULT_CONTEXT"]

#: Readouts cut around each GT frame by default (fewer where the stream is shorter).
DEFAULT_CONTEXT = 41

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
    origin: str = ""  # where it came from: file, window and readout (for error messages)

    @property
    def place(self) -> str:
        """Where the frame came from, for messages: its ``origin``, else sequence and readout."""
        return self.origin or f"sequence {self.sequence!r} readout {self.readout}"


#: Smallest frame side the headline scores take (SSIM-gauss11's 11×11 window).
MIN_SIDE = 11


def _check_side(height: int, width: int, name: str) -> None:
    if min(height, width) < MIN_SIDE:
        raise bad_value(name, f"{height}x{width} pixels",
                        f"frames of at least {MIN_SIDE}x{MIN_SIDE} pixels (SSIM's 11x11 window)")


def _check_context(context: int) -> int:
    if isinstance(context, bool) or not isinstance(context, int) or context < 1:
        raise bad_value("context", context, "an integer >= 1 readouts")
    return context


def _fit(g: int, n: int) -> int:
    """Largest odd window centred on readout ``g`` of an ``n``-readout stream."""
    return 2 * min(g, n - 1 - g) + 1


def frames_from_dataset(path, context: int | None = None, per_sequence: int = 1) -> list[Frame]:
    """Frames of a spikesim file or folder: up to ``per_sequence`` GT readouts per
    sequence (spread evenly over those with a full ``context``-readout window).

    ``context=None`` takes :data:`DEFAULT_CONTEXT` (41) readouts, or per
    sequence the largest centred window that fits around ``per_sequence`` of
    its GT readouts when 41 does not (a dataset of 39-readout windows gives
    39); each frame records the context it got.  An explicit ``context`` that
    fits no GT readout raises; one that leaves out some of the frames asked
    for warns, with the context that would score them all.
    """
    from spikesim.io import open_dataset

    if context is not None:
        _check_context(context)
    ds = open_dataset(path)
    frames = []
    left_out, widest, any_gt = 0, None, False
    for name in ds.names:
        seq = ds.sequence(name)
        n = seq.n_readouts
        any_gt = any_gt or len(seq.gt_index) > 0
        fits = sorted((_fit(int(g), n) for g in seq.gt_index if 0 <= g < n), reverse=True)
        wanted = min(per_sequence, len(fits))
        length = context
        if length is None:
            length = min(DEFAULT_CONTEXT, fits[wanted - 1]) if wanted else 0
        half = length // 2
        ok = [(k, int(g)) for k, g in enumerate(seq.gt_index)
              if length and g - half >= 0 and g - half + length <= n]
        if len(ok) < wanted:
            left_out += wanted - len(ok)
            widest = fits[wanted - 1] if widest is None else min(widest, fits[wanted - 1])
        if not ok:
            continue
        pick = np.unique(np.linspace(0, len(ok) - 1, min(per_sequence, len(ok))).round())
        rate = float((seq.meta.get("sensor") or {}).get("full_scale_rate", 0.6))
        group = sequence_labels(seq.meta)
        for j in pick.astype(int):
            k, g = ok[j]
            origin = f"{seq.path} window {k + 1} of {len(seq.gt_index)} (readout {g})"
            frames.append(Frame(name, g, seq.read_window(g - half, length), half, seq.cfa,
                                rate, seq.read_gt(k), dict(group), origin))
        if hasattr(seq, "close"):
            seq.close()
    if not any_gt:
        raise SpikeSimValueError(f"{path} holds no ground truth, which evaluate scores against "
                                 "(a capture converted from .dat has none): spikejdd "
                                 "reconstruct makes images without it")
    if not frames:
        raise bad_value("context", context, f"a window that fits some GT readout in {path}")
    if left_out:
        warnings.warn(f"context={context} leaves out {left_out} of the GT frames asked for "
                      "(their windows would cross a sequence's end); a context of at most "
                      f"{widest} readouts scores them all", UserWarning, stacklevel=2)
    return frames


def frames_from_simulation(scene, sensor, name: str, gt_readouts, context: int = 41,
                           seed: int = 0, group: dict | None = None, backend: str = "numba",
                           device=None) -> list[Frame]:
    """Simulate ``scene`` just long enough and cut a window around each GT readout
    (``backend``, ``device``: those of ``spikesim.simulate``)."""
    import spikesim as ss

    half = _check_context(context) // 2
    gt_readouts = [int(g) for g in gt_readouts]
    n = max(gt_readouts) - half + context
    if min(gt_readouts) - half < 0:
        raise bad_value("gt_readouts", gt_readouts, f"readouts >= {half} (half the context)")
    stream = ss.simulate(scene, sensor, n_readouts=n, seed=seed, gt_readouts=gt_readouts,
                         backend=backend, device=device)
    spikes = stream.unpack()
    gts = dict(zip(np.asarray(stream.gt_index).tolist(), stream.gt, strict=True))
    noise = f", noise {group['noise']}" if group and "noise" in group else ""
    return [Frame(name, g, spikes[g - half:g - half + context], half, stream.cfa,
                  float(sensor.full_scale_rate), gts[g], dict(group or {}),
                  f"simulated sequence {name!r}{noise} (readout {g})") for g in gt_readouts]


def _time_call(fn, repeats: int):
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = fn()
        times.append(time.perf_counter() - t0)
        out = res if out is None else out
    return out, float(np.median(times))


#: What a report says of the self-ensemble when no ``ensemble`` was given.
DEFAULT_VIEWS = "each method's default"


def run(frames: list[Frame], methods: list[str], repeats: int = 3, progress: bool = True,
        outputs: dict | None = None, device: str | None = None,
        ensemble: int | None = None, keep_going: bool = False) -> dict:
    """Score and time every method on every frame; see the module doc for the timing rule.

    When ``outputs`` is a dict it receives each reconstruction under
    ``(method, frame index)`` (for image panels, without reconstructing again).
    ``device`` and ``ensemble`` (the views of
    :func:`spikejdd.models.run_ensemble`; None: each method's default) reach
    methods that take them (torch methods); torch threads
    are a per-process setting (:func:`spikejdd.runtime.set_threads`).  Each
    row records the readouts the method used (``window``) when it says.

    A method that fails (raises, or returns a wrong shape, dtype or
    non-finite values) stops the run, unless ``keep_going``: then its error
    goes to ``result["failed"][method]`` (one line), it has no rows, and the
    other methods go on.  Every method failing is an error either way.
    """
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise bad_value("repeats", repeats, "an integer >= 1")
    if not frames:
        raise bad_value("frames", frames, "at least one frame")
    for f in frames:
        _check_side(*f.gt.shape[:2], name=f"frames ({f.sequence})")
    fns = {m: get_method(m) for m in methods}  # validates every name up front
    opts = {} if device is None else {"device": device}
    if ensemble is not None:
        opts["ensemble"] = ensemble  # checked by each call (spikejdd.registry.Method)
    rows: list[dict] = []
    failed: dict[str, str] = {}
    bar = tqdm(total=len(frames) * len(methods), desc="evaluate", disable=not progress)
    for k, (m, fn) in enumerate(fns.items()):
        try:
            rows += _method_rows(m, fn, frames, repeats, opts, outputs, bar)
        except SpikeSimError as exc:  # the method's failure (its own, or its output's)
            if not keep_going or len(fns) == 1:
                raise
            failed[m] = str(exc)
            if len(failed) == len(fns):
                raise SpikeSimError("every method failed: " + "; ".join(failed.values())) from exc
            if outputs is not None:
                for i in range(len(frames)):
                    outputs.pop((m, i), None)
            bar.update((k + 1) * len(frames) - bar.n)
    bar.close()
    ok = [m for m in fns if m not in failed]
    result = {"rows": rows, "summary": summarize(rows, ok),
              "runtime": {"device": device or "cpu", "repeats": repeats,
                          "ensemble": ensemble or DEFAULT_VIEWS}}
    if failed:
        result["failed"] = failed
    for key in ("noise", "motion"):
        if any(key in r for r in rows):
            result[f"by_{key}"] = summarize(rows, ok, by=(key,))
    return result


def succeeded(result: dict, methods: list[str]) -> list[str]:
    """The ``methods`` that did not fail in ``result`` (see ``keep_going`` of :func:`run`)."""
    failed = result.get("failed") or {}
    return [m for m in methods if m not in failed]


def _method_rows(m: str, fn, frames: list[Frame], repeats: int, opts: dict,
                 outputs: dict | None, bar) -> list[dict]:
    """One method's rows of :func:`run`: an untimed warm-up call, then every frame."""
    bar.set_postfix_str(f"{m} (warm-up)")
    _call_on(fn, frames[0], opts)  # not timed
    bar.set_postfix_str(m)
    rows = []
    for i, f in enumerate(frames):
        out, sec = _time_call(lambda f=f, fn=fn: _call_on(fn, f, opts), repeats)
        if outputs is not None:
            outputs[(m, i)] = out
        rows.append({"method": m, "sequence": f.sequence, "readout": f.readout,
                     **f.group, "context": int(f.spikes.shape[0]),
                     "window": fn.window_for(int(f.spikes.shape[0])),
                     "seconds": sec, **score(out, f.gt)})
        bar.update()
    return rows


def _call_on(fn, f: Frame, opts: dict) -> np.ndarray:
    """``fn`` on frame ``f`` (:func:`spikejdd.registry.call_method`); its failure says where:
    ``method 'mine' failed on seq_003.h5 window 2 of 3 (readout 60): ValueError: ...``."""
    try:
        return call_method(fn, f.spikes, f.cfa, f.center, rate=f.rate, **opts)
    except SpikeSimError as exc:  # the same error, its message naming the frame
        head = f"method {getattr(fn, 'name', fn)!r}"
        msg = str(exc)
        rest = msg[len(head):].lstrip(":").strip() if msg.startswith(head) else msg
        rest = rest.removeprefix("failed:").strip()
        exc.args = (f"{head} failed on {f.place}: {rest}",)
        raise


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
            entry["windows"] = sorted({int(r["window"]) for r in rs
                                       if r.get("window") is not None})
            out.setdefault(m, {})["/".join(str(k) for k in key) or "all"] = entry
    return out


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
          repeats: int = 3, seed: int = 0, progress: bool = True, outputs: dict | None = None,
          device: str | None = None, frames_out: list | None = None,
          ensemble: int | None = None, keep_going: bool = False) -> dict:
    """Table-1-shaped sweep on sets simulated on the fly (see module doc).

    ``outputs``, ``device`` and ``keep_going`` as in :func:`run`; a ``frames_out`` list
    receives the simulated frames (for :func:`write_report`'s image panels).
    """
    import spikesim as ss
    from spikesim.scenes.procedural import procedural

    _check_side(*size, name="size")
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
            group={"set": set_name, "noise": label, "motion": motion or "object",
                   "sigma_g": sg, "sigma_p": sp})
    result = run(frames, methods, repeats=repeats, progress=progress, outputs=outputs,
                 device=device, ensemble=ensemble, keep_going=keep_going)
    if frames_out is not None:
        frames_out.extend(frames)
    result["table"] = summarize(result["rows"], succeeded(result, methods), by=("set", "noise"))
    result["config"] = {"size": list(size), "context": context,
                        "frames_per_scene": frames_per_scene,
                        "repeats": repeats, "seed": seed, "sets": SWEEP_SETS,
                        "levels": [lv[0] for lv in SWEEP_LEVELS], "gpn_range": GPN_RANGE,
                        "sensor": "RGGB, 20 kHz, full_scale_rate 0.6, modulo reset, paper noise"}
    return result


# --- report ----------------------------------------------------------------
CONVENTIONS = ("PSNR peak 1.0, RGB, clamp [0,1], no crop; SSIM gauss11 = 11x11 Gaussian sigma "
               "1.5, uniform7 = 7x7 uniform (scikit-image); [linear] = linear light, [srgb] = "
               "sRGB-encoded; time = median of the timed calls per frame after one untimed "
               "warm-up call per method, wall clock")
#: Largest crop (pixels per side) shown in the image panels.
PANEL_CROP = 128


def _windows(e: dict) -> str:
    w = e.get("windows") or []
    if not w:
        return "-"
    return str(w[0]) if len(w) == 1 else f"{w[0]}-{w[-1]}"


def _md_table(summary: dict, methods: list[str]) -> list[str]:
    lines = ["| method | " + " | ".join(HEADLINE) + " | ms/frame | readouts used | frames |",
             "|---" * (len(HEADLINE) + 4) + "|"]
    for m in methods:
        e = summary[m]["all"]
        vals = [f"{e[k]:.2f}" if k.startswith("PSNR") else f"{e[k]:.4f}" for k in HEADLINE]
        lines.append(f"| {m} | " + " | ".join(vals) +
                     f" | {e['ms_per_frame']:.1f} | {_windows(e)} | {e['frames']} |")
    return lines


def _natural(label: str) -> list:
    """Sort key that orders numbers inside labels by value (GN5 before GN10)."""
    import re

    return [(0, int(t), "") if t.isdigit() else (1, 0, t) for t in re.split(r"(\d+)", str(label))]


def _group_table(table: dict, methods: list[str], title: str) -> list[str]:
    cols = sorted({k for m in methods for k in table.get(m, {})}, key=_natural)
    lines = ["", f"## {title}: PSNR[linear] dB / SSIM-gauss11[linear] (frames)", "",
             "| method | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for m in methods:
        cells = []
        for c in cols:
            e = table.get(m, {}).get(c)
            cells.append("-" if e is None else f"{e['PSNR[linear]']:.2f} / "
                         f"{e['SSIM-gauss11[linear]']:.3f} ({e['frames']})")
        lines.append(f"| {m} | " + " | ".join(cells) + " |")
    return lines


def panel_image(tiles: list[np.ndarray], labels: list[str], crop: int = PANEL_CROP) -> np.ndarray:
    """Side-by-side sRGB 8-bit panel of linear (H, W, 3) images, the same centred crop of each
    (at most ``crop`` pixels a side), small crops enlarged to >= 96 px (nearest neighbour),
    each under a label strip."""
    import cv2

    h, w = tiles[0].shape[:2]
    ch, cw = min(h, crop), min(w, crop)
    top, left = (h - ch) // 2, (w - cw) // 2
    scale = max(1, int(np.ceil(96 / max(ch, cw))))
    line = 14  # pixels per label line
    wrapped = [_wrap_label(label, cw * scale - 4) for label in labels]
    strip = line * max(len(w) for w in wrapped)
    out = []
    for img, lines in zip(tiles, wrapped, strict=True):
        t = linear_to_srgb8(img[top:top + ch, left:left + cw])
        t = np.repeat(np.repeat(t, scale, axis=0), scale, axis=1)
        head = np.full((strip, t.shape[1], 3), 255, np.uint8)
        face, size, thick = _LABEL_FONT
        for k, text in enumerate(lines):
            cv2.putText(head, text, (2, line * (k + 1) - 4), face, size, (0, 0, 0), thick,
                        cv2.LINE_AA)
        tile = np.concatenate([head, t], axis=0)
        out += [tile, np.full((tile.shape[0], 2, 3), 255, np.uint8)]
    return np.concatenate(out[:-1], axis=1)


#: The label font (OpenCV's plain Hershey font at this scale, 1 pixel thick).
_LABEL_FONT = (1, 0.8, 1)  # cv2.FONT_HERSHEY_PLAIN (1), scale, thickness


def _text_width(text: str) -> int:
    import cv2

    face, scale, thick = _LABEL_FONT
    return cv2.getTextSize(text, face, scale, thick)[0][0]


def _wrap_label(label: str, width: int) -> list[str]:
    """``label`` in lines at most ``width`` pixels wide in the label font, broken after
    ``+ : @ /`` where possible (``tfp+menon2007+`` / ``nlm``), so that every character
    shows and no two labels are cut alike."""
    lines, rest = [], label
    while rest and _text_width(rest) > width:
        fit = max(n for n in range(1, len(rest) + 1)
                  if n == 1 or _text_width(rest[:n]) <= width)  # at least one character
        cut = max(rest.rfind(c, 0, fit) for c in "+:@/") + 1
        cut = cut if cut > 0 else fit
        lines.append(rest[:cut])
        rest = rest[cut:]
    return lines + [rest] if rest else lines or [""]


def _pick_panels(frames: list[Frame], limit: int) -> list[int]:
    """One frame per (noise, motion) group first, then the rest, up to ``limit``."""
    seen, first, rest = set(), [], []
    for i, f in enumerate(frames):
        key = (f.group.get("noise"), f.group.get("motion"))
        (rest if key in seen else first).append(i)
        seen.add(key)
    return (first + rest)[:limit]


def _write_panels(frames, outputs, methods, result, folder: Path, limit: int,
                  temp) -> tuple[list[str], set[str]]:
    """Write the image panels, each to ``temp(final path)``; returns their Markdown and
    their file names."""
    import cv2

    folder.mkdir(parents=True, exist_ok=True)
    psnr = {(r["method"], r["sequence"], r["readout"]): r["PSNR[linear]"]
            for r in result["rows"]}
    md, names = [], set()
    for i in _pick_panels(frames, limit):
        f = frames[i]
        labels = ["ground truth"] + list(methods)
        img = panel_image([f.gt] + [outputs[(m, i)] for m in methods], labels)
        name = f"{i:03d}_{f.sequence}_{f.readout}.png".replace("/", "_")
        ok, png = cv2.imencode(".png", img[..., ::-1])
        if not ok:
            raise SpikeSimFileError(f"could not encode {str(folder / name)!r} as PNG")
        temp(folder / name).write_bytes(png.tobytes())
        names.add(name)
        group = ", ".join(f"{k} {f.group[k]}" for k in ("noise", "motion") if k in f.group)
        scores = "; ".join(f"{m} {psnr[(m, f.sequence, f.readout)]:.2f} dB" for m in methods)
        md += [f"**{f.sequence}**, readout {f.readout}" + (f" ({group})" if group else "") +
               f": {scores}", "", f"![{f.sequence} {f.readout}]({folder.name}/{name})", ""]
    return md, names


def _new_run_id() -> str:
    """An id of one report: its UTC time and 8 random hex digits."""
    return time.strftime("%Y%m%dT%H%M%SZ", time.gmtime()) + "-" + secrets.token_hex(4)


def _remove_earlier(json_path: Path, folder: Path, keep: set[str]) -> None:
    """Remove what an earlier report leaves that this one does not replace: its ``.json``
    (so that a set cut short while renaming has none) and the panels not in ``keep``."""
    json_path.unlink(missing_ok=True)
    if folder.is_dir():
        for old in folder.glob("*.png"):
            if old.name not in keep:
                old.unlink(missing_ok=True)


def write_report(result: dict, methods: list[str], stem, command: str = "",
                 frames: list[Frame] | None = None, outputs: dict | None = None,
                 panels: int = 6) -> list[Path]:
    """Write ``stem.json``, ``stem.md`` and ``stem.png`` (and ``stem_panels/*.png``).

    The Markdown holds the machine as it describes itself
    (:func:`spikejdd.runtime.machine_info`), the mean table, tables per noise
    label and per motion, and — given ``frames`` and the ``outputs`` of
    :func:`run` — up to ``panels`` image panels (ground truth and every
    method on the same crop).  Methods in ``result["failed"]`` are listed
    with their errors and left out of the tables.  A ``stem`` that is a
    folder (it exists, or ends with ``/``) holds them as ``evaluation.*``.
    Returns the paths written.

    The files form one set: each is written to a temporary, then an earlier
    report's ``stem.json`` and panels are removed, the others are renamed into
    place, and ``stem.json`` last.  A ``stem.json`` therefore always sits
    beside files of its own run (its ``run_id`` is in the Markdown and in the
    PNG's ``Description``), and a report killed while renaming has none.
    """
    is_folder = Path(stem).is_dir() or str(stem).endswith(("/", os.sep))
    stem = Path(stem) / "evaluation" if is_folder else Path(stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    torch_used = "torch" in sys.modules  # before machine_info, which imports it to describe it
    machine = machine_info()
    if not torch_used:
        machine.pop("torch_threads", None)  # torch's default would be read as what ran
    machine["description"] = describe_machine(machine)
    run_id = _new_run_id()
    result = dict(result, run_id=run_id, methods=methods, machine=machine, command=command,
                  conventions=CONVENTIONS)
    paths = [stem.with_suffix(".json"), stem.with_suffix(".md"), stem.with_suffix(".png")]
    with contextlib.ExitStack() as stack:
        def temp(final: Path) -> Path:  # renamed over ``final`` at the end, the first last
            return stack.enter_context(atomic_path(final))

        temp(paths[0]).write_text(json.dumps(result, indent=1, default=float))
        md_tmp, png_tmp = temp(paths[1]), temp(paths[2])
        folder = stem.parent / f"{stem.name}_panels"
        md, names = _report_md(result, methods, stem, frames, outputs, panels, folder, temp)
        md_tmp.write_text("\n".join(md) + "\n")
        _scatter(result, succeeded(result, methods), png_tmp, run_id)
        _remove_earlier(paths[0], folder, names)
    return paths


def _report_md(result: dict, methods: list[str], stem: Path, frames, outputs, panels: int,
               folder: Path, temp) -> tuple[list[str], set[str]]:
    """The lines of :func:`write_report`'s Markdown, and the panels it wrote (``temp``)."""
    machine, command, run_id = result["machine"], result["command"], result["run_id"]
    failed = result.get("failed") or {}
    methods = succeeded(result, methods)  # a failed method has no rows
    rt = result.get("runtime") or {}
    md = [f"# {stem.name}", "",
          f"Run id `{run_id}`, the `run_id` of {stem.with_suffix('.json').name} too (a report "
          "without that file was cut short).", ""]
    if command:
        md += [f"Command: `{command}`", ""]
    md += [f"Machine: {machine['description']}.", "",
           f"Device: {rt.get('device', 'cpu')}; torch threads per process: "
           f"{machine.get('torch_threads', 'torch not used')}; "
           "self-ensemble of learned methods: "
           f"{rt.get('ensemble', DEFAULT_VIEWS)}.", "",
           f"Conventions: {CONVENTIONS}.", ""]
    if failed:
        md += ["## Methods that failed", "", "These have no results below:", ""]
        md += [f"- `{m}`: {msg}" for m, msg in failed.items()] + [""]
    md += ["## Mean over all frames", ""]
    md += _md_table(result["summary"], methods)
    if "by_noise" in result:
        md += _group_table(result["by_noise"], methods, "By noise label")
    if "by_motion" in result:
        md += _group_table(result["by_motion"], methods, "By motion")
    if "table" in result:
        md += _group_table(result["table"], methods, "By set and noise (Table 1 shape)")
    md += ["", "## PSNR[linear] per sequence", ""]
    seqs = sorted({r["sequence"] for r in result["rows"]})
    md += ["| method | " + " | ".join(seqs) + " |", "|---" * (len(seqs) + 1) + "|"]
    for m in methods:
        cells = [f"{np.mean([r['PSNR[linear]'] for r in result['rows'] if r['method'] == m and r['sequence'] == s]):.2f}" for s in seqs]  # noqa: E501
        md.append(f"| {m} | " + " | ".join(cells) + " |")
    png = stem.with_suffix(".png").name
    md += ["", "## Speed against error", "", f"![speed against error]({png})", ""]
    names: set[str] = set()
    if frames is not None and outputs is not None and panels > 0:
        md += ["## Image panels", "",
               "Left to right: ground truth, " + ", ".join(methods) + f"; the same centred "
               f"crop (at most {PANEL_CROP}×{PANEL_CROP} px) of each, sRGB-encoded.", ""]
        lines, names = _write_panels(frames, outputs, methods, result, folder, panels, temp)
        md += lines
    return md, names


def _scatter(result: dict, methods: list[str], path: Path, run_id: str = "") -> None:
    """Speed against error, one colour per method: the mean (marker) and the range over
    frames of both time and PSNR (bars); small markers per noise label.  Written as PNG
    whatever ``path``'s name, ``run_id`` in its ``Description``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    cmap = plt.get_cmap("tab10" if len(methods) <= 10 else "tab20")
    for j, m in enumerate(methods):
        color = cmap(j % cmap.N)
        rows = [r for r in result["rows"] if r["method"] == m]
        ms = np.array([1000.0 * r["seconds"] for r in rows])
        ps = np.array([r["PSNR[linear]"] for r in rows])
        e = result["summary"][m]["all"]
        x, y = e["ms_per_frame"], e["PSNR[linear]"]
        ax.errorbar(x, y, xerr=[[x - ms.min()], [ms.max() - x]],
                    yerr=[[y - ps.min()], [ps.max() - y]], fmt="o", color=color, capsize=3,
                    label=m, markersize=7)
        for label, e2 in (result.get("by_noise") or {}).get(m, {}).items():
            ax.scatter(e2["ms_per_frame"], e2["PSNR[linear]"], s=12, color=color, alpha=0.5)
            ax.annotate(str(label), (e2["ms_per_frame"], e2["PSNR[linear]"]), fontsize=6,
                        color=color, xytext=(3, 2), textcoords="offset points")
    ax.set_xscale("log")
    ax.set_xlabel("time per frame (ms, log scale; median of repeats, warm-up excluded)")
    ax.set_ylabel("PSNR, linear light (dB)")
    ax.set_title("speed against error (marker: mean, bars: range over frames; "
                 "dots: per noise label)", fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    fig.savefig(path, dpi=120, format="png",
                metadata={"Description": f"spikejdd evaluate report, run id {run_id}"})
    plt.close(fig)
