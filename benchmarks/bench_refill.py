"""Cost per lane of the event sampler's packed refill against the number of stale lanes.

The refill (``spikesim._event._packed_refill``, modulo reset with comparator
jitter, the physical defaults) draws the next cycle of every stale lane of a
block when the moving scene's readout loop stops.  This times it
cache-resident, one thread, on rows aligned as the kernel's: a block of
1000 e⁻ per threshold with needs
between 500 and 1500 e⁻, 1024 random stale masks of each size, 20 passes
over them per repeat; the median and range of ``--repeats`` repeats, in ns
per stale lane, the sizes alternating within each repeat.  Writes nothing;
prints a Markdown table.

Usage::

    python benchmarks/bench_refill.py [--lanes 16,30,48,64] [--repeats 7]
"""

from __future__ import annotations

import argparse
import time

import machine
import numba
import numpy as np

from spikesim import _event as E


@numba.njit(_nrt=False)
def _passes(masks, electrons, ev, wf, wu, jitter, passes):
    for _ in range(passes):
        for i in range(masks.shape[0]):
            ev[E.CYCLE, i & 63] += 1.0  # a new cycle, so new draws
            E._PACKED_M(masks[i], electrons, ev, jitter, wf, wu)


def _aligned_zeros(rows, dtype=np.float64):
    """Zeroed ``(rows, 64)`` lanes starting at a multiple of 64 bytes, as the
    kernel's work rows (``spikesim._kernels._aligned_rows``)."""
    buf = np.zeros(rows * E.BLOCK + 8, dtype)
    skip = (-buf.ctypes.data % 64) // 8
    return buf[skip:skip + rows * E.BLOCK].reshape(rows, E.BLOCK)


def _block(rng):
    ev = _aligned_zeros(4)
    ev[E.NEED] = rng.uniform(500.0, 1500.0, E.BLOCK)
    ev[E.CYCLE] = rng.integers(0, 1000, E.BLOCK).astype(np.float64)
    wf = _aligned_zeros(E.EV_WORK_F)
    wu = _aligned_zeros(E.EV_WORK_U, np.uint64)
    wu[E.LKW] = rng.integers(0, 2**63, E.BLOCK, dtype=np.uint64)
    electrons = _aligned_zeros(1)[0]
    electrons[:] = 1000.0
    return ev, electrons, wf, wu


def _masks(rng, lanes, count=1024):
    return np.array([sum(1 << int(k) for k in rng.choice(E.BLOCK, lanes, replace=False))
                     for _ in range(count)], dtype=np.uint64)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--lanes", default="16,30,48,64", help="stale lanes per refill")
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args(argv)
    if args.repeats < 1:
        ap.error("--repeats: at least 1")
    sizes = [int(s) for s in args.lanes.split(",")]
    if not all(E.PACKED_REFILL_MIN <= s <= E.BLOCK for s in sizes):
        ap.error(f"--lanes: each between {E.PACKED_REFILL_MIN} and {E.BLOCK} "
                 "(fewer stale lanes are drawn one by one)")
    numba.set_num_threads(1)
    rng = np.random.default_rng(0)
    ev, electrons, wf, wu = _block(rng)
    masks = {s: _masks(rng, s) for s in sizes}
    passes = 20
    _passes(masks[sizes[0]], electrons, ev, wf, wu, 0.006, 1)  # compile
    times = {s: [] for s in sizes}
    for _ in range(args.repeats):
        for s in sizes:
            t0 = time.perf_counter()
            _passes(masks[s], electrons, ev, wf, wu, 0.006, passes)
            times[s].append((time.perf_counter() - t0) / (passes * len(masks[s]) * s) * 1e9)
    machine.print_medians(__file__, argv, "stale lanes", "ns per lane", times)


if __name__ == "__main__":
    main()
