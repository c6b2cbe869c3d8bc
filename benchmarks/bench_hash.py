"""Cost of the counter-based hash on vectors: 1, 2 or 3 chained SplitMix64 finalisers per element.

Each element of a 512-lane array takes ``readout_key(key_i, r)`` (one
``mix64``) and then 0, 1 or 2 further ``mix64`` of it, in one loop that numba
vectorises (512-bit vectors where the CPU has AVX-512), 4000 passes per
repeat; prints the median and range over ``--repeats`` repeats in ns per
element, the variants alternating within each repeat.  It shows what a hash
costs where a 64-bit vector multiply (two per ``mix64``) is dear, which is
why the event sampler draws a spike from one hash (docs/model.md, Speed).
Writes nothing; prints a Markdown table.

Usage::

    python benchmarks/bench_hash.py [--repeats 7]
"""

from __future__ import annotations

import argparse
import time

import machine
import numba
import numpy as np

from spikesim._simd import prefer_wide_vectors
from spikesim.rng import _S12, float_of_52, mix64, readout_key


def _make(extra):
    @numba.njit(error_model="numpy", boundscheck=False, _nrt=False)
    def passes(keys, out, count):
        prefer_wide_vectors()
        for r in range(count):
            for i in range(keys.shape[0]):
                b = readout_key(keys[i], np.uint64(r))
                for _ in range(extra):  # (a compile-time count: unrolled)
                    b = mix64(b)
                out[i] += float_of_52(b >> _S12)

    return passes


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args(argv)
    if args.repeats < 1:
        ap.error("--repeats: at least 1")
    numba.set_num_threads(1)
    keys = np.arange(512, dtype=np.uint64) * np.uint64(0x9E3779B97F4A7C15)
    out = np.zeros(keys.size)
    variants = {hashes: _make(hashes - 1) for hashes in (1, 2, 3)}
    for f in variants.values():
        f(keys, out, 1)  # compile
    count = 4000
    times = {h: [] for h in variants}
    for _ in range(args.repeats):
        for h, f in variants.items():
            t0 = time.perf_counter()
            f(keys, out, count)
            times[h].append((time.perf_counter() - t0) / (count * keys.size) * 1e9)
    machine.print_medians(__file__, argv, "hashes per element", "ns per element", times, 3)


if __name__ == "__main__":
    main()
