"""The LLVM vector helpers equal the scalar arithmetic they replace, bit for bit."""

from __future__ import annotations

import re

import numpy as np
import pytest
from numba import njit

from spikesim._event import on_grid
from spikesim._simd import (
    carry_run64,
    carry_run64_zero,
    event_cached_run64,
    event_cached_run64_static,
    event_cached_run64_zero,
    event_cached_run64_zero_static,
    expand_lanes64,
    high_bits_at_least64,
    linear_carry_run64,
    linear_carry_run64_zero,
    lowest_bit_index,
    paper_carry_add64,
    paper_carry_add64_zero,
    popcount64,
    prefer_wide_vectors,
    store_word,
)
from spikesim._zero_period import COUNT_CLAMP, _quotient, zero_reset_run

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
    return popcount64(m)



@njit
def _event_run(variant, wait, lam, dlam, e, gn, lo, m0, cap, floor, out, first, stride, nbytes,
               count):
    args = (wait, lam, dlam, e, gn, lo, m0, cap, floor, out, first, stride, nbytes, count)
    if variant == 0:
        return event_cached_run64(*args)
    if variant == 1:
        return event_cached_run64_static(*args)
    if variant == 2:
        return event_cached_run64_zero(*args)
    return event_cached_run64_zero_static(*args)


@njit
def _expand(mask, src, dst):
    expand_lanes64(mask, src, dst)


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
    for first, stride, nbytes in ((3, 13, 8), (0, 8, 8), (5, 11, 5), (2, 10, 4), (1, 9, 1)):
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


def test_carry_run64_converts_float_charges_exactly_as_fptoui():
    """Charges given as float64 are added as ``fptoui(charge·2⁶⁴)``, bit for
    bit: on AVX2 the integer is built from the float's bits (no vector
    conversion exists there), so every exponent is tried, with 0, values
    just below powers of two and the largest charge below 1."""
    rng = np.random.default_rng(11)
    powers = 2.0 ** -rng.integers(0, 80, 64)
    cases = [rng.random(64), rng.random(64) * 2.0**-40, np.zeros(64), np.full(64, 1 - 2**-53),
             powers, powers * (1 + rng.random(64)) / 2, np.nextafter(powers, 0.0)]
    for charge in cases:
        charge = np.minimum(charge, 1 - 2**-53)
        for count in (1, 3):
            acc, out = np.zeros(64, np.uint64), np.zeros(8 * count, np.uint8)
            _runs(acc, charge, out, 0, 8, 8, count, False)
            want = (charge * 2.0**64).astype(np.uint64) * np.uint64(count)
            np.testing.assert_array_equal(acc, want)


@njit
def _quotients(x, inc):
    out = np.empty(x.size, np.uint64)
    for k in range(x.size):
        out[k] = _quotient(x[k], inc[k], 2.0**64 / np.float64(inc[k]))
    return out


def test_period_quotients_are_exact_or_clamped():
    """``⌊x / inc⌋`` from a float estimate and one exact correction: at
    quotients just at, above and below whole numbers (``x = m·inc + r``,
    ``r`` ∈ {0, 1, inc − 1}), for divisors from 2³⁴ (smaller ones are divided
    in integers) to 2⁶⁴ − 1; the quotient 2³⁰ − 1 may clamp to COUNT_CLAMP
    (its estimate can round up to 2³⁰)."""
    rng = np.random.default_rng(5)
    cases = []
    for _ in range(4000):
        inc = max(int(rng.integers(1, 2**64, dtype=np.uint64)) >> int(rng.integers(0, 30)),
                  2**34)
        m = min(int(rng.integers(0, 2**31)) >> int(rng.integers(0, 31)), (2**64 - 1) // inc)
        for r in (0, 1, inc - 1):
            if r < inc and m * inc + r < 2**64:
                cases.append((m * inc + r, inc))
    cases += [(2**64 - 1, 2**64 - 1), (0, 2**34 + 7), (2**64 - 1, 2**34), (2**64 - 1, 2**34 + 3),
              (2**64 - 2**34, 2**34), (2**64 - 2**34 - 1, 2**34)]
    x = np.array([c[0] for c in cases], np.uint64)
    inc = np.array([c[1] for c in cases], np.uint64)
    got = _quotients(x, inc)
    want = np.array([a // b for a, b in cases], dtype=object)
    exact, edge = want < 2**30 - 1, want == 2**30 - 1  # the estimate may round up to 2³⁰
    np.testing.assert_array_equal(got[exact].astype(object), want[exact])
    assert np.all((got[edge] == COUNT_CLAMP) | (got[edge] == 2**30 - 1)) and edge.sum() >= 2


def test_zero_reset_counted_down_equals_add_and_clear():
    """A static zero-reset run as a periodic count (``spikesim._zero_period``)
    gives the add-and-clear loop's spike words and final accumulator, bit for
    bit: charges from 0 and 2⁻⁶⁰ (a lane that fires at most once) to just
    below 1 θ, powers of two (periods that divide 2⁶⁴), accumulators at 0,
    2⁶⁴ − 1 and one charge below the top (a firing at the first readout)."""
    rng = np.random.default_rng(8)
    q = rng.random(64)
    q[:6] = [0.0, 2.0**-60, 2.0**-33, 0.5, 0.25, 1 - 2.0**-20]
    q[6:12] = 2.0 ** -rng.integers(1, 12, 6) * (1 + rng.random(6) * 1e-12)
    inc = (q * TWO64).astype(np.uint64)
    acc = rng.integers(0, 2**64, 64, dtype=np.uint64)
    acc[1], acc[12], acc[13], acc[14] = np.uint64(2**64 - 1), 0, 0, np.uint64(2**64 - 1)
    acc[15] = np.uint64(2**64 - int(inc[15]))  # acc + inc = 2⁶⁴ exactly
    acc[2] = np.uint64(2**64 - 10 * int(inc[2]))  # 2⁻³³ θ (integer division): fires at 10
    work = np.zeros((4, 64), np.uint64)
    for count in (0, 1, 16, 37, 300):
        _check_run(lambda a, out, f, s, nb, c: zero_reset_run(a, q, work, out, f, s, nb, c),
                   acc, [inc] * count, True)
        masks, _ = _reference_run(acc, [inc] * count, True)
        if count >= 16:  # lane 1 (2⁻⁶⁰ θ from 2⁶⁴ − 1) fires once, at the first readout
            assert [m >> 1 & 1 for m in masks] == [1] + [0] * (count - 1)
            assert [k for k, m in enumerate(masks) if m >> 2 & 1] == [9]


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
    for m in (0, 1, 2**63, 2**64 - 1, 0x0F0F_0000_8000_0001):
        assert int(_popcount(np.uint64(m))) == bin(m).count("1")


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


@pytest.mark.parametrize("variant", [0, 1, 2, 3])
def test_event_cached_run64_equals_the_scalar_steps_and_stops_where_a_lane_cannot_take(variant):
    """Waits in registers: each readout subtracts ``min(lam + m·dlam, cap)``,
    ``m`` the readouts after the segment's reference (static variants: ``lam``
    itself, ``dlam`` unread); a firing lane whose wait is ≥ its ``wmin``
    takes ``max(wait + gnext, floor·E)`` (zero reset: ``gnext``) and its
    ``wmin`` becomes +∞; every readout's firing word is stored; the call ends
    after the first readout where a firing lane could not take, returning the
    readouts done, those lanes and the lanes that took."""
    zero, static = variant >= 2, variant % 2 == 1
    rng = np.random.default_rng(8 + variant)
    lam = np.array([on_grid(x) for x in 900.0 * rng.random(64)])
    dlam = np.array([on_grid(x) for x in 3.0 * rng.standard_normal(64)])
    if static:  # its dlam is never read: garbage must not matter
        dlam = np.full(64, np.nan)
    e = 900.0 + 200.0 * rng.random(64)
    m0, cap, floor = 5, 2.0**62, -(2.0**62)
    lam[7] = 2.0**63  # capped (the static variants subtract it as it is)
    for base, ready, count in ((3000.0, 1.0, 60), (3000.0, 0.9, 60), (50.0, 0.0, 40),
                               (1e9, 1.0, 7), (50.0, 1.0, 0), (0.0, 1.0, 5)):
        wait = base + 100.0 * rng.random(64)
        wait[7] = 1e30
        gn = 900.0 + 300.0 * rng.random(64)
        # ready lanes' lowest wait: within one readout's electrons (some firings
        # fall below it), or below any (only a spent draw stops a lane)
        top = -1200.0 if ready == 1.0 else -400.0
        lo = np.where(rng.random(64) < ready, top - 600.0 * rng.random(64), np.inf)
        out = np.full(9 * count + 20, 0xAA, np.uint8)
        got_w, got_lo = wait.copy(), lo.copy()
        k, bad, used = _event_run(variant, got_w, lam, dlam, e, gn, got_lo, m0, cap, floor, out,
                                  3, 9, 8, count)
        w, lw, took = wait.copy(), lo.copy(), np.zeros(64, bool)
        want_bad, words = 0, []
        for j in range(count):  # the scalar steps
            w = w - (lam if static else np.minimum(lam + np.float64(m0 + j) * dlam, cap))
            fired = w <= 0.0
            take = fired & (w >= lw)
            new = gn if zero else np.maximum(w + gn, floor * e)
            w = np.where(take, new, w)
            lw = np.where(take, np.inf, lw)
            took |= take
            words.append(_mask(fired))
            if (fired & ~take).any():
                want_bad = _mask(fired & ~take)
                break
        assert (int(k), int(bad), int(used)) == (len(words), want_bad, _mask(took))
        np.testing.assert_array_equal(got_w.view(np.uint64), w.view(np.uint64))
        np.testing.assert_array_equal(got_lo, lw)
        for j, word in enumerate(words):
            assert int.from_bytes(out[3 + 9 * j: 11 + 9 * j].tobytes(), "little") == word
        assert (out[3 + 9 * len(words):] == 0xAA).all()
        if base == 3000.0:  # firings inside the run, some taken
            assert took.any() and want_bad != 0 and 2 < len(words) < count
            if ready == 1.0:  # only a second firing (its draw spent) stops the run
                assert want_bad & ~_mask(took) == 0


def test_expand_lanes64_puts_packed_values_back_by_lane_and_keeps_the_rest():
    """Lane ``k`` of the mask takes ``src[j]``, ``j`` its rank among the mask's
    lanes; the others keep their value; no value of ``src`` beyond the mask's
    count is read (``src`` exactly that long), and the stores are whole
    vectors (no AVX-512 masked store)."""
    rng = np.random.default_rng(3)
    masks = [0, 2**64 - 1, 1, 2**63, 0xFF00, 0x00FF00FF00FF00FF] + [
        int(rng.integers(0, 2**63)) * 2 + int(rng.integers(0, 2)) for _ in range(40)]
    for m in masks:
        lanes = [k for k in range(64) if m >> k & 1]
        src = rng.random(len(lanes))
        dst = rng.random(64)
        want = dst.copy()
        want[lanes] = src
        _expand(np.uint64(m), src, dst)
        np.testing.assert_array_equal(dst, want)
    asm = "".join(_expand.inspect_asm().values())
    assert not re.search(r"vmov[au]p[sd]\s+%zmm\d+,\s*[^,\s]*\(%\w+[^)]*\)\{%k", asm)


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


@njit(cache=False)
def _static_event_run(zero, *args):
    if zero:
        return event_cached_run64_zero_static(*args)
    return event_cached_run64_static(*args)
