"""Baseline sweep (SJDD-Net Table 1 shape) for every classical pipeline.

Writes benchmarks/results/baselines_sweep.{json,md,png}.  Equivalent to::

    spikejdd evaluate --sweep --size 64x96 --frames-per-scene 2 --repeats 3 \
        --out benchmarks/results/baselines_sweep

The report records the machine as it describes itself (CPU, cores, load
average); see ``spikejdd.runtime.machine_info``.
"""

from __future__ import annotations

import sys
from pathlib import Path

from spikejdd.cli import main

if __name__ == "__main__":
    out = Path(__file__).resolve().parent / "results" / "baselines_sweep"
    sys.exit(main(["evaluate", "--sweep", "--size", "64x96", "--frames-per-scene", "2",
                   "--repeats", "3", "--out", str(out), *sys.argv[1:]]))
