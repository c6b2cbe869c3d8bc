"""Simulation in the data loader against the model's step time.

Measures, on this machine's CPU with one torch thread per process:

* samples/s of :func:`spikejdd.train.online.simulate_sample` (one process) at
  each crop — scene drawing, ``spikesim.simulate`` of 39 readouts and the GT;
* samples/s through ``DataLoader(OnlineSpikeDataset, num_workers=W, spawn)``
  for each ``W`` (after the workers have started);
* the training step time (forward + backward + Adam) of each model at batch 8,

and writes ``benchmarks/results/train_data.{json,md}`` with the number of
loader workers needed to keep one step fed (``samples per step / (samples/s
per worker)`` ÷ step time).

Usage::

    python benchmarks/bench_train_data.py [--crops 32 64] [--workers 0 2] [--models lite]
        [--samples 16] [--steps 2]

The result records the machine as it describes itself, load average
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


def sample_rate(crop: int, n: int) -> float:
    from spikejdd.train.online import simulate_sample

    simulate_sample(0, 10_000, crop)  # warm-up: numba, picture cache
    t0 = time.perf_counter()
    for i in range(n):
        simulate_sample(0, i, crop)
    return n / (time.perf_counter() - t0)


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
    p.add_argument("--workers", type=int, nargs="+", default=[0, 2])
    p.add_argument("--models", nargs="+", default=["lite"])
    p.add_argument("--samples", type=int, default=16)
    p.add_argument("--steps", type=int, default=2)
    p.add_argument("--out", default=str(RESULTS / "train_data"))
    args = p.parse_args(argv)
    torch.set_num_threads(1)
    rows = []
    for crop in args.crops:
        row = {"crop": crop, "samples_s_1proc": sample_rate(crop, args.samples)}
        for w in args.workers:
            row[f"loader_samples_s_w{w}"] = loader_rate(crop, w, max(1, args.samples // 8))
        for m in args.models:
            row[f"step_s_{m}"] = step_time(m, crop, args.steps)
            row[f"workers_to_feed_{m}"] = 8 / row["samples_s_1proc"] / row[f"step_s_{m}"]
        rows.append(row)
        print(json.dumps(row))
    cmd = "python benchmarks/bench_train_data.py " + " ".join(sys.argv[1:] if argv is None
                                                              else argv)
    res = {"command": cmd.strip(), "rows": rows, "cpus": os.cpu_count(),
           "machine": machine.describe(), "torch": torch.__version__,
           "threads": 1, "batch": 8}
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").write_text(json.dumps(res, indent=1))
    keys = [k for k in rows[0] if k != "crop"]
    md = ["# Simulation in the data loader against the step time", "",
          f"`{res['command']}` — {res['cpus']} CPUs (shared), 1 torch thread per process, batch 8.",
          "`workers_to_feed_M` = loader processes needed so that simulation keeps up with one "
          "training step of model M on this CPU.", "",
          "| crop | " + " | ".join(keys) + " |", "|---" * (len(keys) + 1) + "|"]
    for r in rows:
        md.append(f"| {r['crop']} | " + " | ".join(f"{r[k]:.2f}" for k in keys) + " |")
    out.with_suffix(".md").write_text("\n".join(md) + "\n")
    print("\n".join(md))
    return 0


if __name__ == "__main__":
    sys.exit(main())
