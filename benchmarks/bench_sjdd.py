"""SJDD-Net benchmarks: deformable-convolution speed and the Table-1 sweep against baselines.

Writes, under ``benchmarks/results/``:

* ``sjdd_deform.{json,md}`` — CPU time of the deformable convolution (pure
  PyTorch; torchvision too when it is installed) at the published and lite
  sizes, forward and forward+backward, beside an ordinary ``conv2d`` of the
  same shape;
* ``sjdd_sweep.{json,md,png}`` — the evaluation harness's sweep (the same sets
  as ``baselines_sweep``: GN 0/5/10/15 and random GPN on the object- and
  camera-motion sets, 64×96, 2 frames per scene, median of 3 timed calls) for
  SJDD-Net (the ``sjdd`` method's weights unless ``--weights`` names others,
  with two views and with one), the classical pipelines, and the methods of
  ``--compare`` (default ``sjdd@sjdd-lite``) in the same run;
* ``sjdd_summary.md`` — per noise level, SJDD-Net against the best classical
  pipeline, and the goal on the sweep mean (≥ 2 dB);
* ``sjdd_speed_table.{json,md}`` — speed bins × scenes at GN σ = 10: the
  sweep's six scenes (sprites, fan, disk; astronaut pan, coffee shake,
  chelsea zoom) static, at 150 px/s (slow: under one pixel per 39-readout
  window), 1500 and 3000 px/s; each cell is SJDD-Net minus the best classical
  pipeline of that cell (dB, PSNR linear), with the column means (one view and
  each ``--compare`` method too).

* ``sjdd_held_out.{json,md}`` (``--held-out``, alone) — generalisation: the
  held-out pictures of :mod:`spikejdd.heldout` (packages that training and
  validation never read), static, 150, 1500 and 3000 px/s, GN 0/5/10/15 and
  random GPN (``--quick``: GN 10 only), one 48×64 frame per cell; SJDD-Net
  (``method="sjdd"``: the shipped default, two views) minus the best of six
  classical pipelines per cell, per picture, per category and per noise level.

Usage::

    python benchmarks/bench_sjdd.py [--weights NAME|PATH] [--compare sjdd@sjdd-lite]
        [--threads 1] [--skip-sweep] [--skip-deform] [--skip-table] [--table-size 64x96]
        [--table-frames 2]
    python benchmarks/bench_sjdd.py --held-out [--quick] [--held-out-size 48x64]
        [--weights NAME|PATH] [--compare sjdd@sjdd-lite] [--threads 2]
        [--out benchmarks/results/sjdd_held_out]

Every result file records the machine as it describes itself, with the load
average at the start and the end (``benchmarks/machine.py``).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import machine
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
           "note": "median of 5 after one warm-up", "machine": machine.describe()}
    (RESULTS / "sjdd_deform.json").write_text(json.dumps(res, indent=1))
    md = ["# sjdd_deform: deformable convolution on CPU", "",
          f"torch {torch.__version__}, {threads} thread(s); torchvision "
          f"{'installed' if torchvision_available() else 'NOT installed (its column is absent)'}."
          " Median of 5 calls after a warm-up, ms.", "", f"Machine: {res['machine']}.", "",
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


def _sjdd_name(weights: str) -> str:
    """The registered method name of ``weights`` ("sjdd" for the shipped default,
    with the method's default self-ensemble)."""
    from spikejdd.models import sjdd_method
    from spikejdd.models.pretrained import DEFAULT_WEIGHTS
    from spikejdd.registry import register_method

    if weights == DEFAULT_WEIGHTS:
        return "sjdd"
    name = f"sjdd-{Path(weights).stem}"
    register_method(name, _with_window(
        lambda s, c, k, rate=0.6: sjdd_method(s, c, k, rate, weights=weights), weights),
        overwrite=True)
    return name


def _with_window(fn, weights: str):
    """``fn`` with the ``window_for`` of ``weights``' model (reported as readouts used)."""
    from spikejdd.models import sjdd_method

    fn.window_for = lambda n_readouts, **_: sjdd_method.window_for(n_readouts, weights=weights)
    return fn


def _one_view_name(weights: str) -> str:
    """A method for ``weights`` without the self-ensemble (``ensemble=1``): one
    forward pass, the speed end of the trade-off."""
    from spikejdd.models import sjdd_method
    from spikejdd.registry import register_method

    name = f"{_sjdd_name(weights)}-1view"
    register_method(name, _with_window(
        lambda s, c, k, rate=0.6: sjdd_method(s, c, k, rate, weights=weights, ensemble=1),
        weights), overwrite=True)
    return name


#: Speed bins of the table, px/s (0 = static; 150 px/s is under one pixel per window).
TABLE_SPEEDS = (0.0, 150.0, 1500.0, 3000.0)


def bench_table(weights: str, threads: int, size=(64, 96), frames: int = 2,
                compare: tuple = ()) -> dict:
    """Speed bins × scenes at GN σ = 10: SJDD-Net minus the best classical pipeline, dB."""
    import spikesim as ss
    from spikejdd import evaluate
    from spikesim.scenes.procedural import procedural

    torch.set_num_threads(threads)
    name = _sjdd_name(weights)
    one = _one_view_name(weights)
    methods = CLASSICAL + [name, one, *compare]
    sensor = ss.Sensor(height=size[0], width=size[1], cfa="RGGB", clock_hz=20_000.0,
                       full_scale_rate=0.6, noise=ss.noise.PaperNoise(sigma_g=10.0, sigma_p=0.0))
    context = 41
    gts = [context // 2 + 10 * i for i in range(frames)]
    all_frames = []
    for scenes in evaluate.SWEEP_SETS.values():
        for scene_name, motion in scenes:
            for speed in TABLE_SPEEDS:
                if motion is None:  # object scenes: their classes need a speed > 0
                    scene = procedural(scene_name, size=tuple(size), speed=speed or 1e-6)
                elif speed == 0:
                    scene = procedural(scene_name, motion="static", size=tuple(size))
                else:
                    scene = procedural(scene_name, motion=motion, size=tuple(size), speed=speed)
                label = f"{scene_name}, {motion}" if motion else scene_name
                all_frames += evaluate.frames_from_simulation(
                    scene, sensor, label, gts, context, seed=0,
                    group={"scene": label, "speed_px_s": speed})
    result = evaluate.run(all_frames, methods, repeats=1, progress=True)
    cells: dict = {}
    for r in result["rows"]:
        cells.setdefault((r["scene"], r["speed_px_s"]), {}).setdefault(r["method"], []).append(
            r["PSNR[linear]"])
    table = {}
    for (scene, speed), by_method in cells.items():
        means = {m: float(np.mean(v)) for m, v in by_method.items()}
        best = max(CLASSICAL, key=lambda m: means[m])
        table.setdefault(scene, {})[str(speed)] = {
            "sjdd": means[name], "best_classical": best, "classical": means[best],
            "delta_db": means[name] - means[best], "delta_db_one_view": means[one] - means[best],
            "delta_db_compared": {m: means[m] - means[best] for m in compare}}
    res = {"weights": weights, "method": name, "size": list(size), "frames_per_cell": frames,
           "noise": "GN sigma_g=10", "speeds_px_s": list(TABLE_SPEEDS), "table": table,
           "command": f"python benchmarks/bench_sjdd.py --weights {weights} --threads {threads} "
                      f"--skip-deform --skip-sweep --table-size {size[0]}x{size[1]} "
                      f"--table-frames {frames}", "machine": machine.describe()}
    (RESULTS / "sjdd_speed_table.json").write_text(json.dumps(res, indent=1))
    md = speed_table_md(res)
    (RESULTS / "sjdd_speed_table.md").write_text(md)
    print(md)
    return res


def speed_table_md(res: dict) -> str:
    """Markdown of :func:`bench_table`'s result (rows: scenes; columns: speed bins)."""
    speeds = [str(s) for s in res["speeds_px_s"]]
    head = ["static" if float(s) == 0 else f"{float(s):g} px/s" for s in speeds]
    lines = [f"# {res['method']} minus the best classical pipeline, GN σ = 10 (dB)", "",
             f"`{res['command']}`; {res['size'][0]}×{res['size'][1]}, "
             f"{res['frames_per_cell']} frame(s) per cell, PSNR linear; the best of "
             f"{', '.join(CLASSICAL)} per cell.", "",
             *([f"Machine: {res['machine']}.", ""] if "machine" in res else []),
             "| scene | " + " | ".join(head) + " |", "|---" * (len(head) + 1) + "|"]
    for scene, row in res["table"].items():
        lines.append(f"| {scene} | " + " | ".join(f"{row[s]['delta_db']:+.2f}" for s in speeds)
                     + " |")
    means = [np.mean([row[s]["delta_db"] for row in res["table"].values()]) for s in speeds]
    lines.append("| **mean** | " + " | ".join(f"**{m:+.2f}**" for m in means) + " |")
    if all("delta_db_one_view" in row[s] for row in res["table"].values() for s in speeds):
        one = [np.mean([row[s]["delta_db_one_view"] for row in res["table"].values()])
               for s in speeds]
        lines.append("| mean, one view (`ensemble=1`) | " + " | ".join(f"{m:+.2f}" for m in one)
                     + " |")
    first = next(iter(res["table"].values()))[speeds[0]]
    for m in first.get("delta_db_compared", {}):
        other = [np.mean([row[s]["delta_db_compared"][m] for row in res["table"].values()])
                 for s in speeds]
        lines.append(f"| mean, `{m}` | " + " | ".join(f"{v:+.2f}" for v in other) + " |")
    return "\n".join(lines) + "\n"


def bench_sweep(weights: str, threads: int, compare: tuple = ()) -> dict:
    from spikejdd import evaluate
    from spikejdd.models import load_checkpoint
    from spikejdd.models.pretrained import resolve_weights

    torch.set_num_threads(threads)
    name = _sjdd_name(weights)
    one = _one_view_name(weights)
    methods = CLASSICAL + [name, one, *compare]
    result = evaluate.sweep(methods, size=(64, 96), context=41, frames_per_scene=2, repeats=3,
                            seed=0, progress=True)
    cmd = f"python benchmarks/bench_sjdd.py --weights {weights} --threads {threads}"
    blob = load_checkpoint(resolve_weights(weights))
    result["sjdd"] = {"weights": weights, "threads": threads, "train": {
        k: blob["train"].get(k) for k in ("step",)}, "eval_during_training": blob["eval"]}
    evaluate.write_report(result, methods, RESULTS / "sjdd_sweep", command=cmd)
    summary = summarize(result, methods, name, one, compare)
    (RESULTS / "sjdd_summary.md").write_text(summary)
    print(summary)
    return result


def summarize(result: dict, methods: list[str], name: str, one_view: str | None = None,
              compare: tuple = ()) -> str:
    from spikejdd.evaluate import SWEEP_LEVELS

    lines = ["# SJDD-Net against the best classical pipeline", "",
             "PSNR[linear] (dB) averaged over the object- and camera-motion sets of the sweep "
             "(64×96, 6 scenes × 2 frames per level); the best classical pipeline is chosen per "
             "level. The goal: SJDD-Net ≥ best classical + 2 dB on the sweep mean, and at "
             "GN σ = 10 on static and slow scenes (`sjdd_speed_table.md`).", "",
             "| noise | best classical | its PSNR | SJDD-Net PSNR | Δ (dB) | SJDD SSIM |",
             "|---|---|---|---|---|---|"]
    deltas = []
    for label, *_ in SWEEP_LEVELS:
        def mean(m, key="PSNR[linear]", label=label):
            vals = [result["table"][m][f"{s}/{label}"][key] for s in ("object", "camera")]
            return float(np.mean(vals))
        classical = [m for m in methods if m in CLASSICAL]
        best = max(classical, key=mean)
        d = mean(name) - mean(best)
        deltas.append(d)
        lines.append(f"| {label} | {best} | {mean(best):.2f} | {mean(name):.2f} | {d:+.2f} | "
                     f"{mean(name, 'SSIM-gauss11[linear]'):.4f} |")
    e = result["summary"]
    lines += ["", "Time per frame (CPU, median of 3): SJDD-Net "
              f"{e[name]['all']['ms_per_frame']:.0f} ms; tfp+menon2007+nlm "
              f"{e['tfp+menon2007+nlm']['all']['ms_per_frame']:.0f} ms."]
    if one_view is not None:
        def overall(m):
            return float(np.mean([result["table"][m][f"{s}/{lb}"]["PSNR[linear]"]
                                  for lb, *_ in SWEEP_LEVELS for s in ("object", "camera")]))
        lines += ["", f"Sweep mean PSNR: SJDD-Net {overall(name):.2f} dB "
                  f"({e[name]['all']['ms_per_frame']:.0f} ms per frame); one view "
                  f"(`ensemble=1`) {overall(one_view):.2f} dB "
                  f"({e[one_view]['all']['ms_per_frame']:.0f} ms); tfp+menon2007+nlm "
                  f"{overall('tfp+menon2007+nlm'):.2f} dB."]
        lines += [f"Compared in the same run: `{m}` {overall(m):.2f} dB "
                  f"({e[m]['all']['ms_per_frame']:.0f} ms per frame)." for m in compare]
    d = float(np.mean(deltas))
    lines += ["", f"Mean over the levels of Δ: {d:+.2f} dB; the ≥ 2 dB goal on the sweep mean is "
              + ("met" if d >= 2.0 else "NOT met by this model") + "."]
    return "\n".join(lines) + "\n"


def bench_held_out(weights: str, threads: int, size=(48, 64), quick: bool = False,
                   out: Path | None = None, compare: tuple = ()) -> dict:
    """The held-out benchmark (see the module doc); writes ``out``.json and ``out``.md.
    Methods of ``compare`` are scored in the same run (their tables under ``compared``)."""
    from spikejdd import evaluate
    from spikejdd.heldout import CLASSICAL as HELD_CLASSICAL
    from spikejdd.heldout import held_out_frames, held_out_tables

    torch.set_num_threads(threads)
    out = Path(out) if out else RESULTS / "sjdd_held_out"
    name = _sjdd_name(weights)
    levels = ["GN10"] if quick else None
    t0 = time.perf_counter()
    frames = held_out_frames(size=size, levels=levels, progress=True)
    t_sim = time.perf_counter() - t0
    compare = tuple(m for m in compare if m != name)
    result = evaluate.run(frames, list(HELD_CLASSICAL) + [name, *compare], repeats=1,
                          progress=True)
    tables = held_out_tables(result["rows"], name, HELD_CLASSICAL)
    compared = {m: held_out_tables(result["rows"], m, HELD_CLASSICAL) for m in compare}
    for t in compared.values():
        t.pop("cells")
    cmd = (f"python benchmarks/bench_sjdd.py --held-out --weights {weights} --threads {threads}"
           f" --held-out-size {size[0]}x{size[1]} --compare '{','.join(compare)}'"
           + (" --quick" if quick else ""))
    res = {"command": cmd, "weights": weights, "method": name, "size": list(size),
           "levels": levels or [lv[0] for lv in evaluate.SWEEP_LEVELS], "frames": len(frames),
           "seconds": {"simulate": t_sim, "total": time.perf_counter() - t0},
           "ms_per_frame": {m: v["all"]["ms_per_frame"] for m, v in result["summary"].items()},
           "machine": machine.describe(), **tables, "compared": compared}
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").write_text(json.dumps(res, indent=1))
    md = held_out_md(res)
    out.with_suffix(".md").write_text(md)
    print(md)
    return res


def held_out_md(res: dict) -> str:
    """Markdown of :func:`bench_held_out`'s result."""
    from spikejdd.heldout import HELD_OUT

    speeds = [str(s) for s in res["speeds_px_s"]]
    head = ["static" if float(s) == 0 else f"{float(s):g} px/s" for s in speeds]
    gn10 = "GN10" in res["levels"]
    sm = res["summary"]
    lines = [f"# Held-out benchmark: {res['method']} ({res['weights']}) against the best "
             "classical pipeline", "",
             f"`{res['command']}`; {len(res['by_picture'])} pictures from packages that "
             "training and validation never read (`spikejdd.heldout`), "
             f"{res['size'][0]}×{res['size'][1]}, one frame per cell (picture × speed × noise "
             f"level; levels {', '.join(res['levels'])}), PSNR linear (peak 1, clamped). "
             "Each cell's delta is SJDD-Net minus the best of "
             f"{', '.join(res['classical'])} in that cell.", "",
             f"Machine: {res['machine']}. {res['frames']} frames; "
             f"{res['seconds']['total'] / 60:.1f} min in all.", "",
             "## Summary", "",
             f"* mean delta over every cell: **{sm['mean_delta_db']:+.2f} dB**"]
    if gn10:
        worst = sm["worst_gn10_static_slow"]
        lines += [f"* mean delta at GN σ = 10: **{sm['mean_delta_db_gn10']:+.2f} dB** "
                  "(acceptance: ≥ +1.5 dB; goal ≥ +2 dB)",
                  f"* smallest delta at GN σ = 10 on a static or slow cell: "
                  f"{sm['min_delta_db_gn10_static_slow']:+.2f} dB ({worst['picture']}, "
                  f"{worst['speed_px_s']:g} px/s); pictures at least equal to the best "
                  "classical pipeline on both: "
                  f"{len(sm['pictures_at_least_equal_gn10_static_slow'])} of "
                  f"{len(res['by_picture'])}"]
    wins = ", ".join(f"{m} {n}" for m, n in sorted(res["wins"].items(), key=lambda x: -x[1]))
    lines += [f"* best classical pipeline (cells won): {wins}", ""]
    key = "delta_db_gn10" if gn10 else "delta_db"
    label = "GN σ = 10" if gn10 else "mean over the levels"
    lines += [f"## Per category, delta (dB), {label}", "",
              "| category | pictures | " + " | ".join(head) + " | mean |",
              "|---" * (len(head) + 3) + "|"]
    for cat, row in res["by_category"].items():
        vals = [row[s][key] for s in speeds]
        lines.append(f"| {cat} | {', '.join(row['pictures'])} | "
                     + " | ".join(f"{v:+.2f}" for v in vals) + f" | {np.mean(vals):+.2f} |")
    means = [np.mean([row[s][key] for row in res["by_picture"].values()]) for s in speeds]
    lines.append("| **all pictures** | | " + " | ".join(f"**{v:+.2f}**" for v in means)
                 + f" | **{np.mean(means):+.2f}** |")
    lines += ["", f"## Per picture, delta (dB) and SJDD-Net PSNR (dB), {label}", "",
              "| picture | categories | " + " | ".join(head) + " |",
              "|---" * (len(head) + 2) + "|"]
    psnr_key = "psnr_gn10" if gn10 else "psnr"
    for pic, row in res["by_picture"].items():
        lines.append(f"| {pic} | {', '.join(HELD_OUT[pic].categories)} | " + " | ".join(
            f"{row[s][key]:+.2f} ({row[s][psnr_key]:.2f})" for s in speeds) + " |")
    means = [np.mean([row[s][key] for row in res["by_picture"].values()]) for s in speeds]
    lines.append("| **mean** | | " + " | ".join(f"**{m:+.2f}**" for m in means) + " |")
    lines += ["", "## Per noise level (every picture and speed)", "",
              "| noise | SJDD-Net PSNR | best classical PSNR | delta |", "|---|---|---|---|"]
    for n, row in res["by_noise"].items():
        lines.append(f"| {n} | {row['psnr']:.2f} | {row['classical_psnr']:.2f} | "
                     f"{row['delta_db']:+.2f} |")
    for m, t in res.get("compared", {}).items():
        lines += ["", f"## Compared in the same run: `{m}`, delta per category (dB), {label}",
                  "", f"Mean delta {t['summary']['mean_delta_db']:+.2f} dB"
                  + (f", at GN σ = 10 {t['summary']['mean_delta_db_gn10']:+.2f} dB; smallest "
                     f"static or slow delta at GN σ = 10 "
                     f"{t['summary']['min_delta_db_gn10_static_slow']:+.2f} dB"
                     if gn10 else "") + ".", "",
                  "| category | " + " | ".join(head) + " | mean |",
                  "|---" * (len(head) + 2) + "|"]
        for cat, row in t["by_category"].items():
            vals = [row[s][key] for s in speeds]
            lines.append(f"| {cat} | " + " | ".join(f"{v:+.2f}" for v in vals)
                         + f" | {np.mean(vals):+.2f} |")
        means = [np.mean([row[s][key] for row in t["by_picture"].values()]) for s in speeds]
        lines.append("| **all pictures** | " + " | ".join(f"**{v:+.2f}**" for v in means)
                     + f" | **{np.mean(means):+.2f}** |")
    ms = res["ms_per_frame"]
    lines += ["", "Time per frame (CPU, ms): " + ", ".join(f"{m} {v:.0f}" for m, v in ms.items())
              + "."]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--weights", default=None,
                   help="shipped name or checkpoint (default: the sjdd method's weights)")
    p.add_argument("--compare", default="sjdd@sjdd-lite",
                   help="comma-separated methods added to the sweep and the table "
                        "('' for none; default: the lite shipped model)")
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--skip-sweep", action="store_true")
    p.add_argument("--skip-deform", action="store_true")
    p.add_argument("--skip-table", action="store_true")
    p.add_argument("--table-size", default="64x96", help="HxW of the speed table's frames")
    p.add_argument("--table-frames", type=int, default=2, help="frames per table cell")
    p.add_argument("--held-out", action="store_true",
                   help="run the held-out benchmark only (spikejdd.heldout)")
    p.add_argument("--quick", action="store_true", help="held-out: GN 10 only")
    p.add_argument("--held-out-size", default="48x64", help="HxW of the held-out frames")
    p.add_argument("--out", default=None, help="held-out: result stem (default "
                   "benchmarks/results/sjdd_held_out)")
    args = p.parse_args(argv)
    try:
        held_size = tuple(int(v) for v in args.held_out_size.lower().split("x"))
        if len(held_size) != 2 or min(held_size) < 12:
            raise ValueError
    except ValueError:
        p.error(f"--held-out-size {args.held_out_size!r}: expected HxW with sides >= 12, "
                "e.g. 48x64")
    try:
        size = tuple(int(v) for v in args.table_size.lower().split("x"))
        if len(size) != 2 or min(size) < 12:
            raise ValueError
    except ValueError:
        p.error(f"--table-size {args.table_size!r}: expected HxW with sides >= 12, e.g. 64x96")
    if args.table_frames < 1:
        p.error(f"--table-frames {args.table_frames}: expected an integer >= 1")
    if args.threads < 1:
        p.error(f"--threads {args.threads}: expected an integer >= 1")
    from spikejdd.models.pretrained import DEFAULT_WEIGHTS, resolve_weights
    from spikejdd.registry import get_method
    from spikesim.errors import SpikeSimError

    weights = args.weights or DEFAULT_WEIGHTS
    try:
        resolve_weights(weights)
    except SpikeSimError as exc:
        p.error(f"--weights {weights!r}: {exc}")
    compare = tuple(dict.fromkeys(m.strip() for m in args.compare.split(",") if m.strip()))
    for m in compare:
        try:
            get_method(m)
        except SpikeSimError as exc:
            p.error(f"--compare {m!r}: {exc}")
    RESULTS.mkdir(parents=True, exist_ok=True)
    if args.held_out:
        from spikejdd.heldout import held_out_packages
        from spikejdd.train.pictures import package_folder

        for pkg in sorted(held_out_packages()):
            try:
                package_folder(pkg)
            except SpikeSimError as exc:
                p.error(f"--held-out: {exc}")
        bench_held_out(weights, args.threads, held_size, args.quick,
                       Path(args.out) if args.out else None, compare)
        return 0
    if not args.skip_deform:
        bench_deform(args.threads)
    if not args.skip_sweep:
        bench_sweep(weights, args.threads, compare)
    if not args.skip_table:
        bench_table(weights, args.threads, size, args.table_frames, compare)
    return 0


if __name__ == "__main__":
    sys.exit(main())
