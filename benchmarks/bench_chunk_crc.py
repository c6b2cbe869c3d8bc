"""Cost of the chunk CRC-32s of HDF5 format version 2 (``spikesim.io.h5.sums``).

Writes a stream of random packed spikes (10 % density, 1000x1000 by default)
with the default compression, and reads it whole, with the CRCs computed and
checked and with them stubbed out (the same file layout: zero CRCs, no check),
``--repeat`` times each, alternating.  Synthetic data: only I/O is timed, no
simulation.

Usage::

    python benchmarks/bench_chunk_crc.py                  # 256 readouts of 1000x1000
    python benchmarks/bench_chunk_crc.py --readouts 64 --size 500

Prints median [min-max] milliseconds per variant.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from spikesim.io import open_h5
from spikesim.io.h5 import sums
from spikesim.io.h5.writer import H5Writer


def _stub() -> tuple:
    """Replace the CRC work by zeros (same datasets); returns what to restore."""
    saved = (sums.ChunkSums.feed, sums.ChunkCheck.check)

    def feed(self, arr):
        grid = sums.chunk_grid(self.tail, self.chunks[1:])
        rows = -(-arr.shape[0] // self.chunks[0])
        self._rows.extend([np.zeros(grid, np.uint32)] * rows)

    sums.ChunkSums.feed = feed
    sums.ChunkCheck.check = lambda self, starts, data: None
    return saved


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--readouts", type=int, default=256)
    ap.add_argument("--size", type=int, default=1000)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    n, size = args.readouts, args.size
    bits = np.random.default_rng(0).random((n, size, size)) < 0.1
    packed = np.packbits(bits, axis=-1, bitorder="little")
    meta = {"height": size, "width": size}
    times = {k: {"write": [], "read": []} for k in ("crc32", "stubbed")}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "b.h5"
        for _ in range(args.repeat):
            for variant in ("crc32", "stubbed"):
                saved = _stub() if variant == "stubbed" else None
                try:
                    t = time.perf_counter()
                    with H5Writer(path, meta) as w:
                        w.append(packed)
                    times[variant]["write"].append(time.perf_counter() - t)
                    with open_h5(path) as seq:
                        t = time.perf_counter()
                        seq.read_packed()
                        times[variant]["read"].append(time.perf_counter() - t)
                finally:
                    if saved is not None:
                        sums.ChunkSums.feed, sums.ChunkCheck.check = saved
    mb = packed.nbytes / 2**20
    print(f"{n} readouts of {size}x{size} ({mb:.1f} MiB packed), default compression")
    for variant, t in times.items():
        print(f"{variant:8s} " + ", ".join(
            f"{k} {1e3 * statistics.median(v):.0f} ms [{1e3 * min(v):.0f}-{1e3 * max(v):.0f}]"
            for k, v in t.items()))


if __name__ == "__main__":
    main()
