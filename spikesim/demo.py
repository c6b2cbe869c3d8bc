"""The main job on built-in scenes: build a small dataset, preview it, reconstruct it.

``run_demo`` builds the built-in ``demo`` manifest (8 procedural sequences,
256×256 RGGB at 20 kHz, Gaussian and Poisson–Gaussian paper-mode noise, three
39-readout windows each) with the dataset builder, writes a TFP preview of
every sequence next to its ground truth, and — when the reconstruction package
``spikejdd`` is installed — reconstructs every ground-truth window with the
classical baselines and the shipped SJDD-Net weights, scoring PSNR/SSIM and
time per frame.  Everything lands in ``report.md`` in the output folder.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from spikesim.errors import bad_value

__all__ = ["run_demo", "DEMO_METHODS"]

#: Classical pipelines reconstructed by the demo (SJDD-Net is added when available).
DEMO_METHODS = ("tfp39+bilinear", "tfp39+malvar2004", "tfi+malvar2004", "tfp39+menon2007+nlm")


def _demo_manifest(size: int | None, limit: int | None):
    import tomllib

    from spikesim.dataset.manifest import _BUILTIN_DIR, parse_manifest

    data = tomllib.loads((_BUILTIN_DIR / "demo.toml").read_text())
    if size is not None:
        if isinstance(size, bool) or not isinstance(size, int) or size < 16:
            raise bad_value("size", size, "an integer >= 16 pixels")
        data["dataset"]["size"] = [size, size]
    return parse_manifest(data, origin="builtin:demo")


def _srgb8(img: np.ndarray) -> np.ndarray:
    from spikesim.io.preview import srgb_encode

    return np.rint(srgb_encode(img) * 255.0).astype(np.uint8)


def _available_methods() -> list[str]:
    try:
        import spikejdd
    except ImportError:
        return []
    from spikesim.errors import SpikeSimError

    methods = list(DEMO_METHODS)
    try:
        spikejdd.registry.get_method("sjdd")
    except (SpikeSimError, ImportError):  # no model package or weights: classical only
        return methods
    return [*methods, "sjdd"]


def run_demo(out_dir: str | Path = "demo_out", size: int | None = None,
             limit: int | None = None, methods: list[str] | None = None,
             progress: bool = True, device: str | None = None,
             threads: int | None = None) -> dict:
    """Run the demo into ``out_dir``; returns the report data (also in summary.json).

    ``device`` and ``threads`` apply to learned methods (SJDD-Net): the torch
    device, and torch threads per process (default 1 on the CPU, see
    :func:`spikejdd.runtime.set_threads`); both are checked before any work.
    """
    from spikesim.dataset import build_dataset
    from spikesim.io import open_dataset
    from spikesim.io.preview import estimate_image, save_image

    out = Path(out_dir)
    manifest = _demo_manifest(size, limit)
    if _available_methods():  # spikejdd installed: check the device, set torch threads
        from spikejdd.runtime import configure

        device, threads = configure(device, threads)
    t0 = time.perf_counter()
    summary = build_dataset(manifest, out, workers=1, progress=progress, limit=limit)
    build_s = time.perf_counter() - t0
    if summary.failed:
        raise RuntimeError("demo sequences failed: " + "; ".join(
            f"{r['file']}: {r['error']}" for r in summary.failures))
    data_dir = out / "demo"
    ds = open_dataset(data_dir)
    records = {r["id"]: r for r in summary.records}
    sequences = []
    for name in ds.names:
        seq = ds.sequence(name)
        g = int(seq.gt_index[0])
        est = estimate_image(seq, g, "tfp", window=39)
        gt = seq.read_gt(0)
        preview = out / f"{name}_preview.png"
        save_image(preview, [np.concatenate([_srgb8(est), _srgb8(gt)], axis=1)])
        counts = seq.read_window(0, seq.n_readouts).mean(dtype=np.float64)
        noise = (seq.meta.get("sensor") or {}).get("noise") or {}
        rec = records.get(name, {})
        sequences.append({
            "name": name, "noise": seq.meta.get("dataset", {}).get("noise_label", ""),
            "sigma_g": noise.get("sigma_g", 0.0), "sigma_p": noise.get("sigma_p", 0.0),
            "readouts": seq.n_readouts, "firing_rate": float(counts),
            "bytes": (data_dir / f"{name}.h5").stat().st_size,
            "sim_seconds": rec.get("seconds", {}).get("total"),
            "preview": preview.name,
        })
        seq.close()
    result = {"size": list(manifest.size), "sequences": sequences, "build_seconds": build_s,
              "built": summary.done, "reused": summary.skipped, "reconstruction": None}
    methods = _available_methods() if methods is None else list(methods)
    if methods:
        result["reconstruction"] = _reconstruct(data_dir, out, methods, manifest.window,
                                                progress, device)
    (out / "summary.json").write_text(json.dumps(result, indent=1, default=str))
    (out / "report.md").write_text(_report(result))
    return result


def _reconstruct(data_dir: Path, out: Path, methods: list[str], window: int,
                 progress: bool, device: str | None = None) -> dict:
    from spikejdd import evaluate
    from spikesim.io.preview import save_image

    # one GT window per sequence and one timed call per frame keep the demo within
    # minutes on 2 cores even with SJDD-Net on the CPU
    frames = evaluate.frames_from_dataset(data_dir, context=window, per_sequence=1)
    outputs: dict = {}
    res = evaluate.run(frames, methods, repeats=1, progress=progress, outputs=outputs,
                       device=device)
    panels = []
    for i, f in enumerate(frames):
        tiles = [_srgb8(f.gt)] + [_srgb8(outputs[(m, i)]) for m in methods]
        path = out / f"{f.sequence}_methods.png"
        save_image(path, [np.concatenate(tiles, axis=1)])
        panels.append({"sequence": f.sequence, "path": path.name})
    return {"methods": methods, "summary": res["summary"], "panels": panels,
            "frames": len(frames)}


def _report(r: dict) -> str:
    h, w = r["size"]
    lines = [
        "# spikesim demo",
        "",
        f"{len(r['sequences'])} sequences ({h}×{w} RGGB, 20 kHz, three 39-readout windows "
        f"each, paper-mode noise) from the dataset builder (`spikesim dataset builtin:demo`): "
        f"{r['built']} simulated in {r['build_seconds']:.1f} s, {r['reused']} reused from an "
        "earlier run.",
        "",
        "| sequence | noise | σ_g (DN) | σ_p | readouts | mean firing rate | file (KiB) |"
        " simulate+write (s) |",
        "|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    for s in r["sequences"]:
        sec = s["sim_seconds"]
        lines.append(f"| {s['name']} | {s['noise']} | {s['sigma_g']:.1f} | {s['sigma_p']:.1f} | "
                     f"{s['readouts']} | {s['firing_rate']:.3f} | {s['bytes'] / 1024:.0f} | "
                     f"{'—' if sec is None else f'{sec:.2f}'} |")
    rec = r.get("reconstruction")
    if rec:
        lines += [
            "",
            "## Reconstruction",
            "",
            f"{rec['frames']} ground-truth windows (one per sequence); PSNR/SSIM on RGB, peak 1, "
            "no crop, in linear light and sRGB-encoded; time = wall clock per frame on this "
            "machine's CPU (one timed call after a warm-up).",
            "",
            "| method | PSNR linear (dB) | SSIM linear | PSNR sRGB (dB) | SSIM sRGB | ms/frame |",
            "|---|---:|---:|---:|---:|---:|",
        ]
        for m in rec["methods"]:
            e = rec["summary"][m]["all"]
            lines.append(f"| {m} | {e['PSNR[linear]']:.2f} | {e['SSIM-gauss11[linear]']:.4f} | "
                         f"{e['PSNR[srgb]']:.2f} | {e['SSIM-gauss11[srgb]']:.4f} | "
                         f"{e['ms_per_frame']:.1f} |")
        lines += ["", "Panels, left to right: ground truth, " + ", ".join(rec["methods"]) + ".",
                  ""]
        for p in rec["panels"]:
            lines.append(f"**{p['sequence']}**\n\n![{p['sequence']}]({p['path']})\n")
    lines += ["", "## Previews (TFP over 39 readouts, Malvar 2004, sRGB | ground truth)", ""]
    for s in r["sequences"]:
        lines.append(f"**{s['name']}** ({s['noise']})\n\n![{s['name']}]({s['preview']})\n")
    return "\n".join(lines)
