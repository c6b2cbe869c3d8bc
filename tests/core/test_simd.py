"""The LLVM vector helpers equal the scalar arithmetic they replace, bit for bit."""

from __future__ import annotations

import numpy as np
from numba import njit

from spikesim._simd import carry_add64, linear_carry_add64

TWO64 = 2.0**64


@njit
def _carry(acc, inc, start):
    return carry_add64(acc, inc, start)


@njit
def _linear(acc, a, d, g, o, phi, start):
    return linear_carry_add64(acc, a, d, g, o, phi, start)


def _mask(bits):
    return int(sum(int(b) << k for k, b in enumerate(bits)))


def test_carry_add64_wraps_and_orders_bits_like_the_packed_layout():
    rng = np.random.default_rng(1)
    acc = rng.integers(0, 2**64, 200, dtype=np.uint64)
    inc = rng.integers(0, 2**64, 200, dtype=np.uint64)
    acc[70], inc[70] = np.uint64(2**64 - 1), np.uint64(1)  # exact wrap to 0: a carry
    acc[71], inc[71] = np.uint64(2**64 - 1), np.uint64(0)  # no carry
    for start in (0, 64, 100):
        a = acc.copy()
        m = _carry(a, inc, start)
        sl = slice(start, start + 64)
        with np.errstate(over="ignore"):
            want = acc[sl] + inc[sl]
        np.testing.assert_array_equal(a[sl], want)
        assert int(m) == _mask(want < acc[sl])
        np.testing.assert_array_equal(np.delete(a, np.arange(start, start + 64)),
                                      np.delete(acc, np.arange(start, start + 64)))


def test_linear_carry_add64_equals_the_scalar_formula():
    rng = np.random.default_rng(2)
    n = 128
    a, d = rng.random(n) * 0.4 + 0.1, (rng.random(n) - 0.5) * 0.2  # charge stays in [0, 1)
    g, o = rng.random(n) + 0.2, rng.random(n) * 0.01
    acc = rng.integers(0, 2**64, n, dtype=np.uint64)
    for phi in (0.0, 0.37, 1.0):
        for start in (0, 64):
            sl = slice(start, start + 64)
            q = ((g[sl] * (a[sl] + d[sl] * phi) + o[sl]) * TWO64).astype(np.uint64)
            with np.errstate(over="ignore"):
                want = acc[sl] + q
            got = acc.copy()
            m = _linear(got, a, d, g, o, phi, start)
            np.testing.assert_array_equal(got[sl], want)
            assert int(m) == _mask(want < acc[sl])
