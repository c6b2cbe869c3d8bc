"""The LLVM vector helpers equal the scalar arithmetic they replace, bit for bit."""

from __future__ import annotations

import numpy as np
from numba import njit

from spikesim._simd import (
    carry_run64,
    carry_run64_zero,
    event_wait_run64,
    high_bits_at_least64,
    linear_carry_run64,
    linear_carry_run64_zero,
    lowest_bit_index,
    paper_carry_add64,
    paper_carry_add64_zero,
    popcount,
    prefer_wide_vectors,
    store_word,
)

TWO64 = 2.0**64


@njit
def _paper(acc, level, z, sd, g, o, start):
    return paper_carry_add64(acc, level, z, sd, g, o, start)


@njit
def _runs(acc, inc, out, first, stride, nbytes, count, zero):
    if zero:
        carry_run64_zero(acc, inc, out, first, stride, nbytes, count)
    else:
        carry_run64(acc, inc, out, first, stride, nbytes, count)


@njit
def _linear_runs(acc, a, d, g, o, n0, t_a, inv, out, first, stride, nbytes, count, zero):
    if zero:
        linear_carry_run64_zero(acc, a, d, g, o, n0, t_a, inv, out, first, stride, nbytes, count)
    else:
        linear_carry_run64(acc, a, d, g, o, n0, t_a, inv, out, first, stride, nbytes, count)


@njit
def _store(out, index, word, nbytes):
    store_word(out, index, word, nbytes)


@njit
def _paper_zero(acc, level, z, sd, g, o, start):
    return paper_carry_add64_zero(acc, level, z, sd, g, o, start)


@njit
def _outside(values, shift, low, span):
    return high_bits_at_least64(values, np.uint64(shift), np.uint64(low), np.uint64(span))


@njit
def _ctz(m):
    return lowest_bit_index(m)


@njit
def _popcount(m):
    return popcount(m)


@njit
def _event_run(wait, a, d, g, o, e, n0, t_a, inv, cap, out, first, stride, nbytes, count):
    return event_wait_run64(wait, a, d, g, o, e, n0, t_a, inv, cap, out, first, stride, nbytes,
                            count)


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


def _reference_run(acc, charges, zero):
    """NumPy: per readout ``acc += charge`` (wrapping), the carry mask, and for
    zero reset the carrying lanes cleared; returns the masks and the final acc."""
    acc = acc.copy()
    masks = []
    for inc in charges:
        with np.errstate(over="ignore"):
            new = acc + inc
        carry = new < acc
        masks.append(_mask(carry))
        acc = np.where(carry, np.uint64(0), new) if zero else new
    return masks, acc


def _check_run(run, acc, charges, zero):
    """``run(acc_copy, out, first, stride, nbytes, count)`` must equal
    :func:`_reference_run`, writing readout ``k``'s mask as the low ``nbytes``
    bytes (little-endian) at byte ``first + k·stride`` of ``out`` and nothing
    else, for whole and partial words at unaligned places."""
    count = len(charges)
    masks, want = _reference_run(acc, charges, zero)
    for first, stride, nbytes in ((3, 13, 8), (0, 8, 8), (5, 11, 5), (1, 9, 1)):
        out = np.full(count * stride + first + 8, 7, np.uint8)
        got = acc.copy()
        run(got, out, first, stride, nbytes, count)
        np.testing.assert_array_equal(got, want)
        expect = np.full_like(out, 7)
        for k, m in enumerate(masks):
            at = first + k * stride
            expect[at:at + nbytes] = np.frombuffer(m.to_bytes(8, "little")[:nbytes], np.uint8)
        np.testing.assert_array_equal(out, expect)
    assert not count or any(0 < m < 2**64 - 1 for m in masks)  # some carry, some not


def test_carry_run64_wraps_and_orders_bits_like_the_packed_layout():
    rng = np.random.default_rng(1)
    acc = rng.integers(0, 2**64, 64, dtype=np.uint64)
    inc = rng.integers(0, 2**63, 64, dtype=np.uint64)
    acc[10], inc[10] = np.uint64(2**64 - 1), np.uint64(1)  # exact wrap to 0: a carry
    acc[11], inc[11] = np.uint64(2**64 - 1), np.uint64(0)  # no carry, ever
    for zero in (False, True):
        for count in (0, 1, 37):
            _check_run(lambda a, out, f, s, nb, c, zero=zero:
                       _runs(a, inc, out, f, s, nb, c, zero), acc, [inc] * count, zero)


def test_linear_carry_run64_equals_the_scalar_formula():
    """Readout ``n0 + k`` gets ``(g·(a + d·phi) + o)·2⁶⁴`` truncated, with
    ``phi = (n + ½ − t_a)·inv`` evaluated in this order (float64)."""
    rng = np.random.default_rng(2)
    a, d = rng.random(64) * 0.4 + 0.1, (rng.random(64) - 0.5) * 0.01  # charge stays in [0, 1)
    g, o = rng.random(64) + 0.2, rng.random(64) * 0.01
    acc = rng.integers(0, 2**64, 64, dtype=np.uint64)
    n0, t_a, inv = 1000, 997.25, 1.0 / 48.0
    for zero in (False, True):
        for count in (1, 41):
            phis = [(np.float64(n0 + k) + 0.5 - t_a) * inv for k in range(count)]
            charges = [(g * (a + d * phi) + o) * TWO64 for phi in phis]
            _check_run(lambda x, out, f, s, nb, c, zero=zero:
                       _linear_runs(x, a, d, g, o, n0, t_a, inv, out, f, s, nb, c, zero),
                       acc, [q.astype(np.uint64) for q in charges], zero)


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


def test_paper_zero_reset_step_clears_exactly_the_lanes_that_carried():
    """The ``_zero`` twin: the same carry bits as the modulo step, and the
    lanes that carried hold 0 afterwards, the others the modulo sum."""
    rng = np.random.default_rng(4)
    n = 128
    acc = rng.integers(0, 2**64, n, dtype=np.uint64)
    g, o = rng.random(n) + 0.2, rng.random(n) * 0.01
    level, z, sd = rng.random(n) * 0.5, rng.standard_normal(n) * 3, rng.random(n) * 0.05
    for start in (0, 64):
        sl = slice(start, start + 64)
        want, got = acc.copy(), acc.copy()
        m = _paper(want, level, z, sd, g, o, start)
        assert 0 < int(m) < 2**64 - 1  # some lanes carry, some do not
        assert int(_paper_zero(got, level, z, sd, g, o, start)) == int(m)
        fired = np.array([(int(m) >> k) & 1 for k in range(64)], bool)
        np.testing.assert_array_equal(got[sl][fired], 0)
        np.testing.assert_array_equal(got[sl][~fired], want[sl][~fired])


def test_store_word_writes_the_low_bytes_little_endian_and_nothing_else():
    word = 0x0807060504030201
    for index in (0, 3, 8):
        for nbytes in range(1, 9):
            out = np.zeros(20, np.uint8)
            _store(out, index, np.uint64(word), nbytes)
            expect = np.zeros(20, np.uint8)
            expect[index:index + nbytes] = np.arange(1, nbytes + 1)
            np.testing.assert_array_equal(out, expect)


def test_popcount_counts_the_set_bits():
    rng = np.random.default_rng(3)
    for m in [0, 1, 2**63, 2**64 - 1, *rng.integers(0, 2**63, 50, dtype=np.uint64).tolist()]:
        assert int(_popcount(np.uint64(m))) == bin(int(m)).count("1")


def test_event_wait_run64_stops_at_the_first_firing_readout_like_the_scalar_step():
    """Waits held in registers: each readout subtracts ``min((g·(a + d·phi) + o)·E,
    cap)``; readouts with no firing store a zero word, the first firing readout
    returns its index and mask (its word left to the caller), waits stored."""
    rng = np.random.default_rng(8)
    a, d = rng.random(64), 0.01 * rng.standard_normal(64)
    g, o, e = 1.0 + 0.1 * rng.random(64), np.full(64, 0.002), 900.0 + 200.0 * rng.random(64)
    n0, t_a, inv, cap = 5, 3.25, 0.125, 2.0**62
    for base, spread, count in ((3000.0, 100.0, 40), (50.0, 30.0, 40), (1e9, 1e9, 7),
                                (50.0, 30.0, 0), (0.0, 0.0, 5)):
        wait = base + spread * rng.random(64)
        out = np.full(200, 0xAA, np.uint8)
        got = wait.copy()
        k, mask = _event_run(got, a, d, g, o, e, n0, t_a, inv, cap, out, 3, 9, 8, count)
        w = wait.copy()
        want_k, want_mask = count, 0
        for j in range(count):  # the scalar step of spikesim._event.event_step, no charge loss
            phi = (np.float64(n0 + j) + 0.5 - t_a) * inv
            lam = np.minimum((g * (a + d * phi) + o) * e, cap)
            w = w - lam
            if (w <= 0.0).any():
                want_k, want_mask = j, _mask(w <= 0.0)
                break
        assert (int(k), int(mask)) == (want_k, want_mask)
        assert base != 3000.0 or 2 <= want_k < count  # a firing inside the run
        np.testing.assert_array_equal(got.view(np.uint64), w.view(np.uint64))
        words = [out[3 + 9 * j: 11 + 9 * j] for j in range(int(k))]
        assert all((word == 0).all() for word in words)
        assert (out[3 + 9 * int(k): 11 + 9 * int(k)] == 0xAA).all() or int(k) == count == 0


def test_prefer_wide_vectors_marks_the_calling_function():
    """The attribute reaches the compiled function's definition (LLVM reads it
    there), with ``noinline`` so that no caller's attributes replace it."""

    @njit(cache=False)
    def scaled(x):
        prefer_wide_vectors()
        out = np.empty_like(x)
        for i in range(x.size):
            out[i] = 2.0 * x[i]
        return out

    np.testing.assert_array_equal(scaled(np.arange(5.0)), 2.0 * np.arange(5.0))
    lines = "\n".join(scaled.inspect_llvm().values()).splitlines()
    definition = next(line for line in lines if line.startswith("define") and "6scaled" in line)
    group = definition.rsplit("#", 1)[1].split()[0]  # its attribute group
    attributes = next(line for line in lines if line.startswith(f"attributes #{group} "))
    assert '"prefer-vector-width"="512"' in attributes and "noinline" in attributes
