"""Zero reset of a constant charge as a periodic count (the kernel's static fast path).

With zero reset, a noise-free pixel whose charge per readout is a constant
``inc`` (fixed point, units of 2⁻⁶⁴ θ, ``0 < inc < 2⁶⁴``) and whose
accumulator holds ``acc`` fires first after ``k₀ = ⌊(2⁶⁴ − 1 − acc) / inc⌋ + 1``
readouts (the first ``k`` with ``acc + k·inc ≥ 2⁶⁴``) and then every
``P = ⌊(2⁶⁴ − 1) / inc⌋ + 1`` readouts, the accumulator starting from 0
after each firing.  So the readout loop needs no accumulator, only a counter
per pixel (:func:`spikesim._simd.countdown_run32`): ``k₀ − 1`` down to −1,
then ``P − 1`` again.  This module converts the accumulator into the counters
before a run and back after it, exactly: the stored state and every spike are
those of the per-readout add and clear.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from spikesim._simd import countdown_run32

_opts = dict(cache=True, error_model="numpy", boundscheck=False)

#: The counters are int32 in the loop; a quotient estimated at or above
#: ``_EXACT_BELOW`` is stored as ``COUNT_CLAMP`` instead (its lane cannot fire
#: again within a piece of ``PIECE`` readouts, which the clamped value
#: preserves).
COUNT_CLAMP = 2**31 - 1
_EXACT_BELOW = 2.0**30
PIECE = 2**29
_M32 = np.uint64(0xFFFFFFFF)
_S32 = np.uint64(32)
_MAX64 = np.uint64(2**64 - 1)
_TWO64 = 2.0**64
_S1 = np.uint64(1)
_SMALL = np.uint64(2**34)
_C, _P, _C0, _INC = 0, 1, 2, 3  # work rows: counter, period, counter at entry, increment


@njit(inline="always", **_opts)
def _product_at_most(m, inc, x):
    """``m·inc ≤ x`` exactly (uint64; ``m < 2³¹``): the 96-bit product as a
    high part ``m·inc_hi + carry`` and a low 32-bit part, against ``x``'s halves."""
    lo = m * (inc & _M32)
    hi = m * (inc >> _S32) + (lo >> _S32)
    xh = x >> _S32
    return (hi < xh) | ((hi == xh) & ((lo & _M32) <= (x & _M32)))


@njit(inline="always", **_opts)
def _quotient(x, inc, inv):
    """``⌊x / inc⌋`` (uint64, ``inc ≥ 2³⁴``, ``inv`` within 2⁻³³ of
    ``2⁶⁴ / inc`` relatively) when the estimate ``x·2⁻⁶⁴·inv`` is below 2³⁰,
    else :data:`COUNT_CLAMP`.  The estimate is then within 2⁻⁴ of the
    quotient, so its floor is the quotient unless it lies within 2⁻³ of a
    whole number; there exact products correct it by one."""
    e = np.float64(np.int64(x >> _S1)) * (2.0**-63) * inv  # (signed conversion: one instruction)
    if e >= _EXACT_BELOW:
        return np.uint64(COUNT_CLAMP)
    m = np.uint64(np.int64(e))
    f = e - np.float64(np.int64(e))
    if 0.125 < f < 0.875:
        return m
    if not _product_at_most(m, inc, x):
        m -= np.uint64(1)
    elif _product_at_most(m + np.uint64(1), inc, x):
        m += np.uint64(1)
    return m


@njit(**_opts)
def zero_reset_run(frac, q, work, out, first, stride, nbytes, count):
    """``count`` zero-reset readouts of constant charges ``q`` (64 lanes,
    float64 thresholds in [0, 1)) for a block whose accumulator fraction is
    ``frac`` (uint64, updated): its spike words stored as
    :func:`spikesim._simd.carry_run64_zero` stores them, with the same bits and
    final state.  ``work`` is (≥ 4, 64) uint64 scratch.

    The increment is ``fptoui(q·2⁶⁴)``, the loop's.  Where it is at least
    2³⁴ the quotients come from ``1 / q`` (within ``2⁻³⁴`` of ``2⁶⁴ / inc``
    relatively) and :func:`_quotient`; a smaller one (below 10⁻⁹ θ a
    readout) has a period of more than 2³⁰ readouts, and its first firing
    is an integer division."""
    done = 0
    while done < count:
        n = min(count - done, PIECE)
        for lane in range(64):
            inc = np.uint64(q[lane] * _TWO64)
            x = ~frac[lane]
            if inc >= _SMALL:
                inv = 1.0 / q[lane]
                c = _quotient(x, inc, inv)
                p = _quotient(_MAX64, inc, inv)
            else:  # never fires (inc = 0), or not again within a piece
                c = min(x // inc, np.uint64(COUNT_CLAMP)) if inc != 0 else np.uint64(COUNT_CLAMP)
                p = np.uint64(COUNT_CLAMP)
            work[_C, lane] = c
            work[_P, lane] = p
            work[_C0, lane] = c
            work[_INC, lane] = inc
        countdown_run32(work[_C], work[_P], out, first + done * stride, stride, nbytes, n)
        for lane in range(64):
            inc = work[_INC, lane]
            if work[_C0, lane] >= n:  # no firing: k₀ > n
                frac[lane] += np.uint64(n) * inc
            else:  # readouts since the last firing: P − 1 − c
                frac[lane] = (work[_P, lane] - work[_C, lane]) * inc
        done += n
