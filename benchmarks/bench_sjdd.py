"""SJDD-Net benchmarks: deformable-convolution speed and the Table-1 sweep against baselines.

Writes, under ``benchmarks/results/``:

* ``sjdd_deform.{json,md}`` — CPU time of the deformable convolution (pure
  PyTorch; torchvision too when it is installed) at the published and lite
  sizes, forward and forward+backward, beside an ordinary ``conv2d`` of the
  same shape;
* ``sjdd_sweep.{json,md,png}`` — the evaluation harness's sweep (the same sets
  as ``baselines_sweep``: GN 0/5/10/15 and random GPN on the object- and
  camera-motion sets, 64×96, 2 frames per scene, median of 3 timed calls) for
  the shipped SJDD-Net weights and the best classical pipelines;
* ``sjdd_summary.md`` — per noise level, SJDD-Net against the best classical
  pipeline and the acceptance check (≥ 2 dB at GN 10, GN 15 and GPN).

Usage::

    python benchmarks/bench_sjdd.py [--weights sjdd-lite] [--threads 1] [--skip-sweep]

Machine note: a 2-core AMD EPYC VM shared with other work; times are indicative.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

RESULTS = Path(__file__).resolve().parent / "results"
CLASSICAL = ["tfp+malvar2004", "tfp+menon2007", "tfp+menon2007+bilateral", "tfp+menon2007+nlm"]


def _time(fn, repeats=5):
    fn()
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return 1000 * float(np.median(ts))


def bench_deform(threads: int) -> dict:
    from spikejdd.models.deform import deform_conv2d, torchvision_available

    torch.set_num_threads(threads)
    rows = []
    shapes = [("published", 1, 64, 4, 4, 64, 64), ("published", 1, 64, 4, 4, 128, 128),
              ("lite", 1, 24, 1, 1, 64, 96), ("lite-train", 8, 24, 1, 1, 32, 32)]
    backends = ["torch"] + (["torchvision"] if torchvision_available() else [])
    for label, n, c, og, groups, h, w in shapes:
        g = torch.Generator().manual_seed(0)
        x = torch.randn(n, c, h, w, generator=g, requires_grad=True)
        off = torch.randn(n, 18 * og, h, w, generator=g, requires_grad=True)
        wt = torch.randn(c, c // groups, 3, 3, generator=g, requires_grad=True)
        b = torch.randn(c, generator=g, requires_grad=True)
        row = {"model": label, "shape": [n, c, h, w], "offset_groups": og, "groups": groups}
        args = (x, off, wt, b)
        for be in backends:
            with torch.no_grad():
                row[f"{be}_fwd_ms"] = _time(lambda be=be, a=args: deform_conv2d(
                    *a, 1, 1, 1, backend=be))
            row[f"{be}_fwd_bwd_ms"] = _time(lambda be=be, a=args: deform_conv2d(
                *a, 1, 1, 1, backend=be).sum().backward())
        with torch.no_grad():
            row["conv2d_fwd_ms"] = _time(lambda a=args, gr=groups: torch.nn.functional.conv2d(
                a[0], a[2], a[3], 1, 1, 1, gr))
        rows.append(row)
    res = {"threads": threads, "torchvision": torchvision_available(), "rows": rows,
           "torch": str(torch.__version__),
           "note": "median of 5 after one warm-up; 2-core VM shared with other work"}
    (RESULTS / "sjdd_deform.json").write_text(json.dumps(res, indent=1))
    md = ["# sjdd_deform: deformable convolution on CPU", "",
          f"torch {torch.__version__}, {threads} thread(s); torchvision "
          f"{'installed' if torchvision_available() else 'NOT installed (its column is absent)'}."
          " Median of 5 calls after a warm-up, ms.", "",
          "| model | input (N,C,H,W) | offset groups | weight groups | "
          + " | ".join(f"{be} fwd | {be} fwd+bwd" for be in backends) + " | conv2d fwd |",
          "|---" * (5 + 2 * len(backends)) + "|"]
    for r in rows:
        cells = " | ".join(f"{r[f'{be}_fwd_ms']:.1f} | {r[f'{be}_fwd_bwd_ms']:.1f}"
                           for be in backends)
        md.append(f"| {r['model']} | {tuple(r['shape'])} | {r['offset_groups']} | {r['groups']} "
                  f"| {cells} | {r['conv2d_fwd_ms']:.1f} |")
    (RESULTS / "sjdd_deform.md").write_text("\n".join(md) + "\n")
    print("\n".join(md))
    return res


def bench_sweep(weights: str, threads: int) -> dict:
    from spikejdd import evaluate
    from spikejdd.models import load_checkpoint, pretrained_path, sjdd_method
    from spikejdd.registry import register_method

    torch.set_num_threads(threads)
    name = "sjdd" if weights == "sjdd-lite" else f"sjdd[{weights}]"
    if name != "sjdd":
        register_method(name.replace("[", "-").replace("]", ""),
                        lambda s, c, k, rate=0.6: sjdd_method(s, c, k, rate, weights=weights),
                        overwrite=True)
        name = name.replace("[", "-").replace("]", "")
    methods = CLASSICAL + [name]
    result = evaluate.sweep(methods, size=(64, 96), context=41, frames_per_scene=2, repeats=3,
                            seed=0, progress=True)
    cmd = f"python benchmarks/bench_sjdd.py --weights {weights} --threads {threads}"
    blob = load_checkpoint(pretrained_path(weights))
    result["sjdd"] = {"weights": weights, "threads": threads, "train": {
        k: blob["train"].get(k) for k in ("step",)}, "eval_during_training": blob["eval"]}
    evaluate.write_report(result, methods, RESULTS / "sjdd_sweep", command=cmd)
    summary = summarize(result, methods, name)
    (RESULTS / "sjdd_summary.md").write_text(summary)
    print(summary)
    return result


def summarize(result: dict, methods: list[str], name: str) -> str:
    from spikejdd.evaluate import SWEEP_LEVELS

    lines = ["# SJDD-Net against the best classical pipeline", "",
             "PSNR[linear] (dB) averaged over the object- and camera-motion sets of the sweep "
             "(64×96, 6 scenes × 2 frames per level); the best classical pipeline is chosen per "
             "level. Acceptance: SJDD-Net ≥ best classical + 2 dB at GN10, GN15 and GPN.", "",
             "| noise | best classical | its PSNR | SJDD-Net PSNR | Δ (dB) | SJDD SSIM | "
             "target met |", "|---|---|---|---|---|---|---|"]
    verdict = []
    for label, *_ in SWEEP_LEVELS:
        def mean(m, key="PSNR[linear]", label=label):
            vals = [result["table"][m][f"{s}/{label}"][key] for s in ("object", "camera")]
            return float(np.mean(vals))
        classical = [m for m in methods if m != name]
        best = max(classical, key=mean)
        d = mean(name) - mean(best)
        target = label in ("GN10", "GN15", "GPN-rand")
        ok = d >= 2.0
        if target:
            verdict.append(ok)
        lines.append(f"| {label} | {best} | {mean(best):.2f} | {mean(name):.2f} | {d:+.2f} | "
                     f"{mean(name, 'SSIM-gauss11[linear]'):.4f} | "
                     f"{('yes' if ok else 'NO') if target else '-'} |")
    e = result["summary"]
    lines += ["", "Time per frame (CPU, median of 3): SJDD-Net "
              f"{e[name]['all']['ms_per_frame']:.0f} ms; tfp+menon2007+nlm "
              f"{e['tfp+menon2007+nlm']['all']['ms_per_frame']:.0f} ms.",
              "", "Acceptance (≥ 2 dB at GN10, GN15, GPN): "
              + ("MET" if all(verdict) else "NOT MET by this model") + "."]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--weights", default="sjdd-lite")
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--skip-sweep", action="store_true")
    p.add_argument("--skip-deform", action="store_true")
    args = p.parse_args(argv)
    RESULTS.mkdir(parents=True, exist_ok=True)
    if not args.skip_deform:
        bench_deform(args.threads)
    if not args.skip_sweep:
        bench_sweep(args.weights, args.threads)
    return 0


if __name__ == "__main__":
    sys.exit(main())
