"""Simulation in the data loader against the model's step time.

Measures, on this machine's CPU with one torch thread per process:

* samples/s of :func:`spikejdd.train.online.simulate_sample` (one process) at
  each crop — scene drawing, ``spikesim.simulate`` of 39 readouts and the GT —
  ``--repeats`` times over the same ``--samples`` samples, as wall-clock rate
  and as the rate per CPU-second of the process (``time.process_time``: on a
  machine shared with other work this is the rate one core gives; numba and
  OpenCV on one thread, as in a loader worker), with the
  median and range of the repeats; and the share of the time spent drawing the
  scene (:func:`spikejdd.train.scenes.draw_scene`, the same samples);
* samples/s through ``DataLoader(OnlineSpikeDataset, num_workers=W, spawn)``
  for each ``W`` (after the workers have started);
* the training step time (forward + backward + Adam) of each model at batch 8,

and writes ``benchmarks/results/train_data.{json,md}`` with the number of
loader workers needed to keep one step fed (``samples per step / (samples/s
per worker)`` ÷ step time).

Usage::

    python benchmarks/bench_train_data.py [--crops 32 64] [--workers 0 2] [--models lite]
        [--samples 16] [--steps 2] [--repeats 3]

``--workers`` and ``--models`` with no value skip the loader and the step
time.  The result records the machine as it describes itself, load average
included.  On the GPU machine (16 cores) run it there to size ``--workers``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import machine
import torch

RESULTS = Path(__file__).resolve().parent / "results"


def sample_rates(crop: int, n: int, repeats: int) -> dict:
    """Wall-clock and per-CPU-second samples/s of ``simulate_sample`` over samples 0..n−1,
    ``repeats`` times, and the same for ``draw_scene`` alone (its share of the time)."""
    import numpy as np

    from spikejdd.train.online import _one_thread, simulate_sample
    from spikejdd.train.scenes import draw_scene

    _one_thread()  # as in a loader worker: numba and OpenCV on one thread
    simulate_sample(0, 10_000, crop)  # warm-up: numba, picture cache
    for i in range(n):  # every content's one-off cost paid (pictures, colour pool, scans)
        draw_scene(np.random.default_rng([0, i]), (crop, crop))
    wall, cpu, draw_cpu = [], [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        for i in range(n):
            simulate_sample(0, i, crop)
        wall.append(n / (time.perf_counter() - t0))
        cpu.append(n / (time.process_time() - c0))
        c0 = time.process_time()
        for i in range(n):  # the draws of simulate_sample: its generator's first draws
            draw_scene(np.random.default_rng([0, i]), (crop, crop))
        draw_cpu.append(1000 * (time.process_time() - c0) / n)

    def stats(v):
        v = sorted(v)
        return {"median": v[len(v) // 2], "min": v[0], "max": v[-1], "runs": v}

    sample_ms = [1000 / r for r in cpu]
    return {"samples_s_wall": stats(wall), "samples_s_cpu": stats(cpu),
            "ms_per_sample_cpu": stats(sample_ms), "draw_ms_cpu": stats(draw_cpu),
            "simulate_ms_cpu": stats([a - b for a, b in zip(sample_ms, draw_cpu,
                                                             strict=True)])}


def loader_rate(crop: int, workers: int, batches: int, batch: int = 8) -> float:
    from spikejdd.train.online import OnlineSpikeDataset

    ds = OnlineSpikeDataset(batch, crop, seed=0)
    loader = torch.utils.data.DataLoader(ds, batch_size=None, num_workers=workers,
                                         multiprocessing_context="spawn" if workers else None)
    it = iter(loader)
    next(it)  # workers started and warm
    t0 = time.perf_counter()
    for _ in range(batches):
        next(it)
    rate = batches * batch / (time.perf_counter() - t0)
    del it
    return rate


def step_time(model: str, crop: int, steps: int, batch: int = 8) -> float:
    from spikejdd.models import SJDDNet
    from spikejdd.train.config import MODEL_PRESETS
    from spikejdd.train.online import OnlineSpikeDataset

    torch.manual_seed(0)
    net = SJDDNet(MODEL_PRESETS[model])
    opt = torch.optim.Adam(net.parameters(), lr=5e-4)
    b = OnlineSpikeDataset(batch, crop, seed=0).batch(0)
    times = []
    for _ in range(steps + 1):
        t0 = time.perf_counter()
        rgb, _ = net(b["spikes"], b["mask"])
        loss = torch.nn.functional.mse_loss(rgb, b["gt"])
        opt.zero_grad()
        loss.backward()
        opt.step()
        times.append(time.perf_counter() - t0)
    return float(sorted(times[1:])[len(times[1:]) // 2])


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--crops", type=int, nargs="+", default=[32, 64])
    p.add_argument("--workers", type=int, nargs="*", default=[0, 2])
    p.add_argument("--models", nargs="*", default=["lite"])
    p.add_argument("--samples", type=int, default=16)
    p.add_argument("--steps", type=int, default=2)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--out", default=str(RESULTS / "train_data"))
    args = p.parse_args(argv)
    if args.samples < 1 or args.repeats < 1:
        p.error("--samples and --repeats: expected integers >= 1")
    torch.set_num_threads(1)
    rows = []
    for crop in args.crops:
        rates = sample_rates(crop, args.samples, args.repeats)
        row = {"crop": crop, **rates}
        for w in args.workers:
            row[f"loader_samples_s_w{w}"] = loader_rate(crop, w, max(1, args.samples // 8))
        for m in args.models:
            row[f"step_s_{m}"] = step_time(m, crop, args.steps)
            row[f"workers_to_feed_{m}"] = (8 / rates["samples_s_cpu"]["median"]
                                           / row[f"step_s_{m}"])
        rows.append(row)
        print(json.dumps(row))
    res = {"command": machine.command_line(__file__, argv), "rows": rows,
           "cpus": os.cpu_count(), "machine": machine.describe(), "torch": torch.__version__,
           "threads": 1, "batch": 8, "samples": args.samples, "repeats": args.repeats}
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").write_text(json.dumps(res, indent=1))
    md = train_data_md(res)
    out.with_suffix(".md").write_text(md)
    print(md)
    return 0


def train_data_md(res: dict) -> str:
    """Markdown of the result: per crop, the rates as median [range] of the repeats."""
    def mr(d, digits=1):
        return f"{d['median']:.{digits}f} [{d['min']:.{digits}f}–{d['max']:.{digits}f}]"

    extra = [k for k in res["rows"][0] if k.startswith(("loader_", "step_s_", "workers_"))]
    lines = ["# Simulation in the data loader against the step time", "",
             f"`{res['command']}` — {res['cpus']} CPUs (shared), 1 torch thread per process, "
             f"batch 8; {res['samples']} samples, {res['repeats']} repeats: median [range].",
             "`samples/s per CPU-second` counts the process's own CPU time "
             "(`time.process_time`): the rate one core gives, whatever else shares the "
             "machine; `draw` is `draw_scene` alone, `simulate` the rest of a sample "
             "(`spikesim.simulate` with its key frames and GT, unpacking, the mask).",
             *(["`workers_to_feed_M` = loader processes needed so that simulation keeps up "
                "with one training step of model M on this CPU."]
               if any(k.startswith("workers_") for k in extra) else []),
             "", f"Machine: {res['machine']}.", "",
             "| crop | samples/s per CPU-second | samples/s (wall) | ms per sample (CPU) | "
             "draw (ms CPU) | simulate (ms CPU) |" + "".join(f" {k} |" for k in extra),
             "|---" * (6 + len(extra)) + "|"]
    for r in res["rows"]:
        lines.append(f"| {r['crop']} | {mr(r['samples_s_cpu'])} | {mr(r['samples_s_wall'])} | "
                     f"{mr(r['ms_per_sample_cpu'], 2)} | {mr(r['draw_ms_cpu'], 2)} | "
                     f"{mr(r['simulate_ms_cpu'], 2)} |" + "".join(f" {r[k]:.2f} |" for k in extra))
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.exit(main())
