"""Fit the polynomial coefficients of ``spikesim.rng``'s inverse error function.

Run once; paste the printed tuples into spikesim/rng.py.  They are stored as
literals (not recomputed at import) so that every machine draws the same
normal deviates whatever its SciPy version.

With ``x = 2u - 1`` and ``w = -log(1 - x²)``, ``erfinv(x) = x · g(w)`` where g
is smooth.  g is fitted with a degree-16 Chebyshev least-squares fit on two
ranges (``w < 6.25`` in the variable w, ``w ≥ 6.25`` in sqrt(w), up to w = 38,
i.e. u ≈ 2^-54), converted to a power series in the range-normalised variable.
Reference values come from ``scipy.special.erfcinv`` computed on ``1 - x``
without cancellation.
"""

import numpy as np
from numpy.polynomial import chebyshev, polynomial
from scipy.special import erfcinv

RANGES = ((0.0, 6.25, "w"), (6.25, 38.0, "sqrt_w"))
DEGREE = 16


def fit(lo, hi, var):
    w = np.linspace(lo, hi, 40001)[1:]
    x = np.sqrt(-np.expm1(-w))
    g = erfcinv(np.exp(-w) / (1 + x)) / x
    t = w if var == "w" else np.sqrt(w)
    a, b = (lo, hi) if var == "w" else (np.sqrt(lo), np.sqrt(hi))
    s = (2 * t - (a + b)) / (b - a)
    coeffs = chebyshev.cheb2poly(chebyshev.chebfit(s, g, DEGREE))
    err = np.max(np.abs(polynomial.polyval(s, coeffs) / g - 1))
    return a, b, coeffs, err


if __name__ == "__main__":
    for lo, hi, var in RANGES:
        a, b, coeffs, err = fit(lo, hi, var)
        print(f"# {var} in [{a!r}, {b!r}], max relative error {err:.2e}")
        print("(" + ", ".join(repr(float(c)) for c in coeffs[::-1]) + ")")
