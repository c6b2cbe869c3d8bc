"""The main job on built-in scenes: build a small dataset, preview it, reconstruct it.

``run_demo`` (``spikejdd demo``, ``make demo``) runs the simulation half
(:func:`spikesim.demo.build_demo`: the built-in ``demo`` manifest, 8
procedural sequences, 256×256 RGGB at 20 kHz, Gaussian and Poisson–Gaussian
paper-mode noise, a TFP preview of each), then reconstructs every
ground-truth window with the classical pipelines and the shipped SJDD-Net
weights, scoring PSNR/SSIM and time per frame.  Everything lands in
``report.md`` and ``summary.json`` in the output folder.
"""

from __future__ import annotations

import json
from contextlib import nullcontext
from pathlib import Path

import numpy as np

from spikesim.demo import Stages, build_demo, demo_report, preview_report
from spikesim.errors import SpikeSimError
from spikesim.srgb import linear_to_srgb8

__all__ = ["run_demo", "DEMO_METHODS"]

#: Classical pipelines reconstructed by the demo (SJDD-Net is added when its weights load).
DEMO_METHODS = ("tfp39+bilinear", "tfp39+malvar2004", "tfi+malvar2004", "tfp39+menon2007+nlm")
#: SJDD-Net in the demo on a CPU: the lite weights, since the default (full-size) model
#: takes about 26 s a 256×256 frame and view on one CPU thread, 4 times the lite one's.
CPU_SJDD = "sjdd@sjdd-lite"


def _default_methods(device: str = "cpu") -> list[str]:
    from spikejdd.registry import get_method

    sjdd = "sjdd" if str(device).startswith("cuda") else CPU_SJDD
    try:
        get_method(sjdd)
    except (SpikeSimError, ImportError):  # no weights: classical only
        return list(DEMO_METHODS)
    return [*DEMO_METHODS, sjdd]


def run_demo(out_dir: str | Path = "demo_out", size: int | None = None,
             limit: int | None = None, methods: list[str] | None = None,
             progress: bool = True, device: str | None = None,
             threads: int | None = None, say_stages: bool = False) -> dict:
    """Run the demo into ``out_dir``; returns the report data (also in summary.json).

    ``device`` and ``threads`` apply to learned methods (SJDD-Net): the torch
    device, and torch threads per process (default 1 on the CPU, see
    :func:`spikejdd.runtime.set_threads`); both are checked before any work.
    ``say_stages``: say each stage (simulate, preview, reconstruct, report) on
    stderr as it starts and ends, with its seconds (:class:`spikesim.demo.Stages`).
    """
    from spikejdd.runtime import configure

    device, threads = configure(device, threads)
    methods = _default_methods(device) if methods is None else list(methods)
    stages = Stages("spikejdd demo", 4 if methods else 3) if say_stages else None
    stage = stages or (lambda what: nullcontext())
    out = Path(out_dir)
    result = build_demo(out, size=size, limit=limit, progress=progress, stages=stages)
    result["reconstruction"] = None
    if methods:
        with stage(f"reconstructing with {len(methods)} methods ({', '.join(methods)})"):
            result["reconstruction"] = _reconstruct(Path(result["data_dir"]), out, methods,
                                                    result["window"], progress, device)
    with stage("writing report.md and summary.json"):
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
        tiles = [linear_to_srgb8(f.gt)] + [linear_to_srgb8(outputs[(m, i)]) for m in methods]
        path = out / f"{f.sequence}_methods.png"
        save_image(path, [np.concatenate(tiles, axis=1)])
        panels.append({"sequence": f.sequence, "path": path.name})
    return {"methods": methods, "summary": res["summary"], "panels": panels,
            "frames": len(frames)}


def _report(r: dict) -> str:
    lines = demo_report(r, title="spikesim + spikejdd demo")
    rec = r.get("reconstruction")
    if rec:
        lines += [
            "",
            "## Reconstruction",
            "",
            f"{rec['frames']} ground-truth windows (one per sequence); PSNR/SSIM on RGB, peak 1, "
            "no crop, in linear light and sRGB-encoded; time = wall clock per frame on this "
            "machine's CPU (one timed call after a warm-up)."
            + (f" SJDD-Net runs with the lite weights (`{CPU_SJDD}`) on a CPU, 4 times faster "
               "than the default full-size model; `--methods sjdd` (or `--device cuda`) "
               "runs the default." if CPU_SJDD in rec["methods"] else ""),
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
    return "\n".join(lines + preview_report(r))
