"""Write the inverse-normal-CDF tables of ``spikesim.rng.normal``.

* ``spikesim/tables/normal_icdf_4096.npy``: Φ⁻¹(k/4096), k = 0..4096 (the body:
  4096 equal-probability bins; the two end entries are ±inf and never read);
* ``spikesim/tables/normal_icdf_tail_4096.npy``: Φ⁻¹(m/2**20), m = 0..4096 (the
  lower tail u < 2**-8 on bins 256× finer; the upper tail is its mirror image;
  entry 0 is −inf and never read).

Both are computed once with SciPy's ``ndtri`` (double precision, error ~1e-16)
and shipped as data, so that every machine and every SciPy version uses the
very same bits (the simulator's reproducibility contract).

Run::

    python tools/make_icdf_table.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.special import ndtri

BINS = 4096
TAIL_BITS = 20  # tail bins are 2**-20 wide
TABLES = Path(__file__).resolve().parents[1] / "spikesim" / "tables"


def main() -> None:
    q = ndtri(np.arange(BINS + 1, dtype=np.float64) / BINS)
    assert np.isneginf(q[0]) and np.isposinf(q[-1]) and np.all(np.diff(q) > 0)
    assert np.array_equal(q[1:-1], -q[-2:0:-1])  # symmetric to the bit
    tail = ndtri(np.arange(BINS + 1, dtype=np.float64) / 2.0**TAIL_BITS)
    assert np.isneginf(tail[0]) and np.all(np.diff(tail) > 0) and tail[-1] == q[16]
    for name, table in ((f"normal_icdf_{BINS}.npy", q), (f"normal_icdf_tail_{BINS}.npy", tail)):
        np.save(TABLES / name, table)
        print(f"wrote {TABLES / name} ({table.nbytes} bytes)")


if __name__ == "__main__":
    main()
