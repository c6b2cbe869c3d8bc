"""spikesim beside a peer simulator: Spike-Zoo's ``video2spike_simulation``.

Spike-Zoo (PyPI ``spikezoo``) ships the integrate-and-fire simulator used to
make spike data from video in NumPy: per readout it adds the frame to an
accumulator, compares with the threshold and subtracts it where it fired.
This script runs it and ``spikesim.simulate`` on the same scene — a
1000×1000 monochrome static image (linear light), 200 readouts, noise-free —
in alternating runs, and reports per-run times, their medians and the ratio
of the two in each pair (the box may be shared, so only same-run ratios mean
anything).  Overheads are included on both sides: spikesim's call builds its
key frame, initial charge and metadata; Spike-Zoo's call receives the list
of frames its API takes (the same image once per readout) and stacks it.

Both simulate the same sensor: spikesim with ``full_scale_rate=0.6`` and
subtract reset (as Spike-Zoo), Spike-Zoo with threshold 2 fed 1.2·I, i.e.
0.6·I thresholds per readout.

Installing the peer (its package needs heavy extras to import, so only its
``spikezoo/utils/spike_utils.py`` is loaded, by path; it imports numpy,
torch, opencv and imageio, which spikesim's environment has)::

    .venv/bin/python -m pip install --no-deps spikezoo

Run::

    .venv/bin/python benchmarks/bench_peers.py            # 1000×1000, 200 readouts, 5 pairs
    .venv/bin/python benchmarks/bench_peers.py --quick    # small smoke run

Writes ``benchmarks/results/peers.json`` and ``peers.md``.  Without the peer
installed it prints how to install it and exits with status 0 (nothing to do).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import statistics
import sys
import time
from pathlib import Path

import machine
import numpy as np

import spikesim as ss

RESULTS = Path(__file__).parent / "results"
INSTALL = "pip install --no-deps spikezoo"


def load_spikezoo_simulator():
    """``video2spike_simulation`` from the installed spikezoo's
    ``utils/spike_utils.py``, or None (with the reason) if it cannot be loaded."""
    spec = importlib.util.find_spec("spikezoo")
    if spec is None or not spec.submodule_search_locations:
        return None, f"spikezoo is not installed (install it with: {INSTALL})"
    path = Path(list(spec.submodule_search_locations)[0]) / "utils" / "spike_utils.py"
    if not path.is_file():
        return None, f"{path} not found (this spikezoo version has no spike_utils.py)"
    mod_spec = importlib.util.spec_from_file_location("spikezoo_spike_utils", path)
    module = importlib.util.module_from_spec(mod_spec)
    try:
        mod_spec.loader.exec_module(module)
    except ImportError as exc:
        return None, f"{path} needs a module this environment lacks ({exc})"
    fn = getattr(module, "video2spike_simulation", None)
    if fn is None:
        return None, f"{path} has no video2spike_simulation"
    return fn, str(path)


def make_image(size: int) -> np.ndarray:
    """A smooth linear-light test image (H, W) in [0, 1] (no download needed)."""
    y, x = np.mgrid[0:size, 0:size] / max(size - 1, 1)
    img = 0.5 + 0.35 * np.sin(7.0 * x + 3.0 * y) * np.cos(5.0 * y - 2.0 * x)
    return np.clip(img, 0.0, 1.0).astype(np.float32)


def run_spikesim(img: np.ndarray, n: int, seed: int) -> np.ndarray:
    sensor = ss.Sensor(height=img.shape[0], width=img.shape[1], cfa=None,
                       full_scale_rate=0.6, reset="subtract")
    return ss.simulate(ss.scenes.Static(img), sensor, n, seed=seed).packed


def run_spikezoo(fn, img: np.ndarray, n: int, seed: int) -> np.ndarray:
    np.random.seed(seed)  # noqa: NPY002 - the peer draws from the legacy global generator
    frame = 1.2 * img  # 0.6·I thresholds per readout at threshold 2
    return fn([frame] * n, threshold=2.0)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, default=1000)
    ap.add_argument("--readouts", type=int, default=200)
    ap.add_argument("--pairs", type=int, default=5, help="alternating run pairs (>= 3)")
    ap.add_argument("--quick", action="store_true", help="128×128, 3 pairs, no files written")
    args = ap.parse_args(argv)
    if args.quick:
        args.size, args.pairs = 128, 3
    fn, where = load_spikezoo_simulator()
    if fn is None:
        print(f"bench_peers: skipped: {where}")
        return 0
    img = make_image(args.size)
    n = args.readouts
    run_spikesim(img, 8, 0)  # compile / warm the kernel
    # sanity: both count the same spikes on average (same charge per readout)
    ours = ss.bits.unpack(run_spikesim(img, n, 1), args.size).mean()
    theirs = run_spikezoo(fn, img, n, 1).mean()
    times = {"spikesim": [], "spikezoo": []}
    for _ in range(args.pairs):
        t0 = time.perf_counter()
        run_spikesim(img, n, 2)
        times["spikesim"].append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        run_spikezoo(fn, img, n, 2)
        times["spikezoo"].append(time.perf_counter() - t0)
    ratios = [z / s for s, z in zip(times["spikesim"], times["spikezoo"], strict=True)]
    px = args.size * args.size * n
    result = {
        "scene": f"{args.size}x{args.size} mono static, {n} readouts, noise-free",
        "peer": where,
        "pairs": args.pairs,
        "times_s": times,
        "median_s": {k: statistics.median(v) for k, v in times.items()},
        "speedup_per_pair": ratios,
        "speedup_median": statistics.median(ratios),
        "speedup_range": [min(ratios), max(ratios)],
        "mean_rate": {"spikesim": float(ours), "spikezoo": float(theirs)},
        "machine": machine.describe(),
    }
    rows = [
        "| simulator | median time (s) | pixel-readouts/s | spikes per readout |",
        "|---|---|---|---|",
    ]
    for k in ("spikesim", "spikezoo"):
        med = result["median_s"][k]
        rows.append(f"| {k} | {med:.3f} | {px / med:.3g} | {result['mean_rate'][k]:.4f} |")
    lo, hi = result["speedup_range"]
    table = "\n".join(rows) + (
        f"\n\nspikesim / Spike-Zoo speed ratio: median {result['speedup_median']:.0f}× "
        f"(range {lo:.0f}–{hi:.0f}× over {args.pairs} alternating pairs), {result['scene']}; "
        f"machine: {result['machine']}.\n")
    print(table)
    if not args.quick:
        RESULTS.mkdir(exist_ok=True)
        (RESULTS / "peers.json").write_text(json.dumps(result, indent=2) + "\n")
        (RESULTS / "peers.md").write_text(
            "# spikesim beside Spike-Zoo's simulator\n\n"
            "`python benchmarks/bench_peers.py` (see its docstring).\n\n" + table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
