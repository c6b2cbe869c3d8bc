"""Write ``spikesim/tables/normal_icdf_4096.npy``: Φ⁻¹(k/4096) for k = 0..4096.

The table drives the fast path of ``spikesim.rng.normal`` (piecewise-linear
inverse normal CDF on 4096 equal-probability bins).  It is computed once with
SciPy's ``ndtri`` (double precision, error ~1e-16) and shipped as data, so that
every machine and every SciPy version uses the very same bits (the simulator's
reproducibility contract).  The two end entries are ±inf; the kernel never
reads them (the outermost bins use exact inversion).

Run::

    python tools/make_icdf_table.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.special import ndtri

BINS = 4096
OUT = Path(__file__).resolve().parents[1] / "spikesim" / "tables" / f"normal_icdf_{BINS}.npy"


def main() -> None:
    q = ndtri(np.arange(BINS + 1, dtype=np.float64) / BINS)
    assert np.isneginf(q[0]) and np.isposinf(q[-1]) and np.all(np.diff(q) > 0)
    assert np.array_equal(q[1:-1], -q[-2:0:-1])  # symmetric to the bit
    np.save(OUT, q)
    print(f"wrote {OUT} ({q.nbytes} bytes)")


if __name__ == "__main__":
    main()
