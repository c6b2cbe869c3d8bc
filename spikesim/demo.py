"""The simulation half of the main job: build a small dataset from built-in scenes
and preview it.

``build_demo`` builds the built-in ``demo`` manifest (8 procedural sequences,
256×256 RGGB at 20 kHz, Gaussian and Poisson–Gaussian paper-mode noise, three
39-readout windows each) with the dataset builder and writes a TFP preview of
every sequence next to its ground truth; ``demo_report`` turns its result into
Markdown.  ``spikejdd.demo.run_demo`` (``spikejdd demo``, ``make demo``) adds
the reconstruction half: classical pipelines and SJDD-Net, scored and timed.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from spikesim.errors import bad_value
from spikesim.srgb import linear_to_srgb8

__all__ = ["build_demo", "demo_report", "preview_report"]


def _demo_manifest(size: int | None):
    import tomllib

    from spikesim.dataset.manifest import builtin_manifest_path, parse_manifest

    data = tomllib.loads(builtin_manifest_path("demo").read_text())
    if size is not None:
        if isinstance(size, bool) or not isinstance(size, int) or size < 16:
            raise bad_value("size", size, "an integer >= 16 pixels")
        data["dataset"]["size"] = [size, size]
    return parse_manifest(data, origin="builtin:demo")


def build_demo(out_dir: str | Path = "demo_out", size: int | None = None,
               limit: int | None = None, progress: bool = True) -> dict:
    """Build the demo dataset into ``<out_dir>/demo`` and a preview PNG per sequence.

    Returns ``{"size", "window", "data_dir", "sequences", "build_seconds", "built",
    "reused"}``; a sequence that fails raises ``RuntimeError`` naming it.
    """
    from spikesim.dataset import build_dataset
    from spikesim.io import open_dataset
    from spikesim.io.preview import estimate_image, save_image

    out = Path(out_dir)
    manifest = _demo_manifest(size)
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
        save_image(preview, [np.concatenate([linear_to_srgb8(est), linear_to_srgb8(gt)],
                                            axis=1)])
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
    return {"size": list(manifest.size), "window": manifest.window, "data_dir": str(data_dir),
            "sequences": sequences, "build_seconds": build_s, "built": summary.done,
            "reused": summary.skipped}


def demo_report(r: dict, title: str = "spikesim demo") -> list[str]:
    """Markdown lines of :func:`build_demo`'s result: the sequence table."""
    h, w = r["size"]
    lines = [
        f"# {title}",
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
    return lines


def preview_report(r: dict) -> list[str]:
    """Markdown lines showing every sequence's preview PNG."""
    lines = ["", "## Previews (TFP over 39 readouts, Malvar 2004, sRGB | ground truth)", ""]
    for s in r["sequences"]:
        lines.append(f"**{s['name']}** ({s['noise']})\n\n![{s['name']}]({s['preview']})\n")
    return lines
