"""torch threads per process for SJDD-Net inference on the CPU: 1 thread against all cores.

Each measurement is a fresh process (``spawn``-free: ``subprocess`` of this
interpreter) that sets ``torch.set_num_threads(N)``, loads the shipped
``sjdd-lite`` weights, reconstructs one 64×96 RGGB frame (one forward pass,
``ensemble=1``) once untimed and then ``--calls`` times; its median is one
run.  Runs alternate between the thread counts so that background load
affects both alike.  Writes
``benchmarks/results/threads.{json,md}`` with the median and range over runs
and the ratio to one thread.  The machine is described from itself
(:func:`spikejdd.runtime.describe_machine`).

Usage::

    python benchmarks/bench_threads.py [--runs 3] [--calls 5] [--threads 1,2]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

RESULTS = Path(__file__).resolve().parent / "results"

CHILD = r"""
import sys, time, numpy as np, torch
torch.set_num_threads(int(sys.argv[1]))
from spikejdd.models import sjdd_method
rng = np.random.default_rng(0)
spikes = (rng.random((39, 64, 96)) < 0.3).astype(np.uint8)
sjdd_method(spikes, "RGGB", 19, ensemble=1)  # one forward pass (the default runs two)
ts = []
for _ in range(int(sys.argv[2])):
    t0 = time.perf_counter(); sjdd_method(spikes, "RGGB", 19, ensemble=1)
    ts.append(time.perf_counter() - t0)
print(1000 * float(np.median(ts)))
"""


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--runs", type=int, default=3)
    p.add_argument("--calls", type=int, default=5)
    p.add_argument("--threads", default=f"1,{os.cpu_count()}")
    args = p.parse_args(argv)
    counts = [int(t) for t in args.threads.split(",")]
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1]) + os.pathsep
               + os.environ.get("PYTHONPATH", ""))
    times: dict[int, list[float]] = {n: [] for n in counts}
    for r in range(args.runs):
        for n in counts:
            out = subprocess.run([sys.executable, "-c", CHILD, str(n), str(args.calls)],
                                 capture_output=True, text=True, env=env, check=True)
            times[n].append(float(out.stdout.strip().splitlines()[-1]))
            print(f"run {r + 1}: {n} thread(s) {times[n][-1]:.1f} ms/frame", flush=True)
    from spikejdd.runtime import describe_machine, machine_info

    machine = describe_machine(machine_info())
    ref = float(np.median(times[counts[0]]))
    rows = [{"threads": n, "median_ms": float(np.median(t)), "min_ms": min(t), "max_ms": max(t),
             "ratio_to_first": float(np.median(t)) / ref, "runs": t} for n, t in times.items()]
    cmd = "python benchmarks/bench_threads.py " + " ".join(argv or sys.argv[1:])
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "threads.json").write_text(json.dumps(
        {"command": cmd.strip(), "machine": machine, "calls": args.calls, "rows": rows},
        indent=1))
    md = ["# torch threads per process: SJDD-Net (sjdd-lite) inference, 64×96 frame", "",
          f"Command: `{cmd.strip()}`", "", f"Machine: {machine}.", "",
          f"Each run: a fresh process, one untimed call, then the median of {args.calls} calls; "
          f"{args.runs} runs per setting, alternating.", "",
          "| threads | median ms/frame | range over runs | × time of " + f"{counts[0]} thread |",
          "|---:|---:|---:|---:|"]
    md += [f"| {r['threads']} | {r['median_ms']:.0f} | {r['min_ms']:.0f}–{r['max_ms']:.0f} | "
           f"{r['ratio_to_first']:.2f} |" for r in rows]
    (RESULTS / "threads.md").write_text("\n".join(md) + "\n")
    print("\n".join(md))
    return 0


if __name__ == "__main__":
    sys.exit(main())
