"""The LLVM vector helpers equal the scalar arithmetic they replace, bit for bit."""

from __future__ import annotations

import numpy as np
from numba import njit

from spikesim._simd import (
    carry_add64,
    carry_add64_zero,
    high_bits_at_least64,
    linear_carry_add64,
    linear_carry_add64_zero,
    lowest_bit_index,
    paper_carry_add64,
    paper_carry_add64_zero,
)

TWO64 = 2.0**64


@njit
def _carry(acc, inc, start):
    return carry_add64(acc, inc, start)


@njit
def _linear(acc, a, d, g, o, phi, start):
    return linear_carry_add64(acc, a, d, g, o, phi, start)


@njit
def _paper(acc, level, z, sd, g, o, start):
    return paper_carry_add64(acc, level, z, sd, g, o, start)


@njit
def _carry_zero(acc, inc, start):
    return carry_add64_zero(acc, inc, start)


@njit
def _linear_zero(acc, a, d, g, o, phi, start):
    return linear_carry_add64_zero(acc, a, d, g, o, phi, start)


@njit
def _paper_zero(acc, level, z, sd, g, o, start):
    return paper_carry_add64_zero(acc, level, z, sd, g, o, start)


@njit
def _outside(values, shift, low, span):
    return high_bits_at_least64(values, np.uint64(shift), np.uint64(low), np.uint64(span))


@njit
def _ctz(m):
    return lowest_bit_index(m)


def _mask(bits):
    return int(sum(int(b) << k for k, b in enumerate(bits)))


def _check_charge_step(step, acc, charge, start):
    """``step(acc_copy)`` must add ``charge·2⁶⁴`` (truncated) to lanes
    ``start..start+63`` and return their carry bits."""
    sl = slice(start, start + 64)
    with np.errstate(over="ignore"):
        want = acc[sl] + (charge * TWO64).astype(np.uint64)
    got = acc.copy()
    m = step(got)
    np.testing.assert_array_equal(got[sl], want)
    assert int(m) == _mask(want < acc[sl])


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
            charge = g[sl] * (a[sl] + d[sl] * phi) + o[sl]
            _check_charge_step(lambda acc_, phi=phi, start=start:
                               _linear(acc_, a, d, g, o, phi, start), acc, charge, start)


def test_paper_carry_add64_equals_the_scalar_formula_and_clips_negative_light():
    rng = np.random.default_rng(3)
    n = 128
    level, z = rng.random(n) * 0.5, rng.standard_normal(n) * 3
    sd, g, o = rng.random(n) * 0.05, rng.random(n) + 0.3, rng.random(n) * 0.01
    level[:10], z[:10] = 0.0, -1.0  # noisy level below 0: clipped, charge = offset
    acc = rng.integers(0, 2**64, n, dtype=np.uint64)
    for start in (0, 64):
        sl = slice(start, start + 64)
        charge = g[sl] * np.maximum(level[sl] + sd[sl] * z[sl], 0.0) + o[sl]
        _check_charge_step(lambda acc_, start=start: _paper(acc_, level, z, sd, g, o, start),
                           acc, charge, start)


def test_lane_masks_and_lowest_bit():
    k = np.array([0, 15, 16, 17, 4079, 4080, 4095] + [100] * 57, np.uint64)
    values = (k << np.uint64(52)) | np.uint64(12345)
    # lanes outside the central bins [16, 4080): 0, 15, 4080, 4095
    assert int(_outside(values, 52, 16, 4064)) == _mask([1, 1, 0, 0, 0, 1, 1] + [0] * 57)
    for bit in (0, 1, 37, 63):
        assert int(_ctz(np.uint64(1 << bit) | np.uint64(1 << 63))) == bit


def test_zero_reset_steps_clear_exactly_the_lanes_that_carried():
    """The ``_zero`` twins: the same carry bits as the modulo step, and the
    lanes that carried hold 0 afterwards, the others the modulo sum."""
    rng = np.random.default_rng(4)
    n = 128
    acc = rng.integers(0, 2**64, n, dtype=np.uint64)
    inc = rng.integers(0, 2**63, n, dtype=np.uint64)
    a, d = rng.random(n) * 0.4 + 0.1, (rng.random(n) - 0.5) * 0.2
    g, o = rng.random(n) + 0.2, rng.random(n) * 0.01
    level, z, sd = rng.random(n) * 0.5, rng.standard_normal(n) * 3, rng.random(n) * 0.05
    pairs = [(lambda x, s: _carry(x, inc, s), lambda x, s: _carry_zero(x, inc, s)),
             (lambda x, s: _linear(x, a, d, g, o, 0.3, s),
              lambda x, s: _linear_zero(x, a, d, g, o, 0.3, s)),
             (lambda x, s: _paper(x, level, z, sd, g, o, s),
              lambda x, s: _paper_zero(x, level, z, sd, g, o, s))]
    for modulo, zero in pairs:
        for start in (0, 64):
            sl = slice(start, start + 64)
            want, got = acc.copy(), acc.copy()
            m = modulo(want, start)
            assert 0 < int(m) < 2**64 - 1  # some lanes carry, some do not
            assert int(zero(got, start)) == int(m)
            fired = np.array([(int(m) >> k) & 1 for k in range(64)], bool)
            np.testing.assert_array_equal(got[sl][fired], 0)
            np.testing.assert_array_equal(got[sl][~fired], want[sl][~fired])
