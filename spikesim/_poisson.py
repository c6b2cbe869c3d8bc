"""Exact Poisson samplers of the shot noise (numba; no validation, no I/O).

:func:`poisson` is the scalar sampler (inversion below λ = 10, Hörmann's
transformed rejection above), :func:`_shot_noise_block` the same draws for the
64 lanes of a kernel block, bit for bit.  Moved out of ``spikesim._kernels``
so that the event-driven sampler (``spikesim._event``) can use them too.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from spikesim.rng import exp_nonpositive, log_positive, pixel_bits, uniform

BLOCK = 64  # lanes of a kernel block
#: Largest mean electron count given to the shot-noise sampler; a pixel there
#: holds ≥ 2⁶²/E thresholds per readout and fires at every readout anyway.
LAMBDA_MAX = 2.0**62
_U1 = np.uint64(1)
_POISSON_INVERSION_MAX = 10.0
_POISSON_INVERSION_CAP = 200  # the inversion search stops here (P(k > 200 | λ < 10) ≈ 0)
_INV_INT = np.array([0.0] + [1.0 / k for k in range(1, _POISSON_INVERSION_CAP + 1)])  # 1/k
_UNDECIDED = -1.0  # an attempt the vector pass cannot judge (k beyond the log k! table)

_opts = dict(cache=True, error_model="numpy", boundscheck=False)


@njit(**_opts)
def _log_factorial_table(n):
    """``log k!`` for k = 0..n−1, by the same ``math.lgamma`` the samplers use."""
    out = np.empty(n, np.float64)
    for k in range(n):
        out[k] = math.lgamma(k + 1.0)
    return out


_LOG_FACTORIAL = _log_factorial_table(4096)  # k ≤ λ + a few √λ for λ up to ~4000


@njit(inline="always", **_opts)
def _log_factorial(k):
    """``log k!`` of an integer-valued float k ≥ 0: the table's value (identical
    to ``math.lgamma(k + 1)``, which it stores) or ``math.lgamma`` beyond it."""
    if k < _LOG_FACTORIAL.shape[0]:
        return _LOG_FACTORIAL[np.int64(k)]
    return math.lgamma(k + 1.0)


@njit(**_opts)
def poisson(lam, bits):
    """Poisson deviate with mean ``lam`` from 64 random bits (exact samplers).

    ``lam < 10``: inversion of the CDF with one uniform (sequential search,
    ``p_k = p_{k−1}·(λ·(1/k))`` from ``p_0 = e**−λ``).  Otherwise the
    transformed rejection with squeeze of W. Hörmann, "The transformed
    rejection method for generating Poisson random variables", Insurance:
    Mathematics and Economics 12 (1993); attempt j uses two uniforms hashed
    from ``bits`` and j.  Logarithms are :func:`spikesim.rng.log_positive`
    (absolute error < 1e-13, vectorisable, so the block sampler can run the
    whole first attempt branch-free) and ``log k!`` a table of ``lgamma``.
    """
    if lam <= 0.0:
        return 0.0
    if lam < _POISSON_INVERSION_MAX:
        u = uniform(bits)
        p = exp_nonpositive(-lam)
        cdf = p
        k = 0
        while u > cdf and k < _POISSON_INVERSION_CAP:
            k += 1
            p *= lam * _INV_INT[k]
            cdf += p
        return np.float64(k)
    return _ptrs_from(lam, bits, np.uint64(0))


@njit(**_opts)
def _ptrs_from(lam, bits, j):
    """The transformed rejection for ``lam`` ≥ 10 from attempt ``j`` (even) on:
    :func:`poisson` starts at 0, the block sampler at 2 for the lanes whose
    first attempt it ran and rejected (the same bits either way)."""
    loglam, b, a, inv_alpha, v_r = _ptrs_constants(lam)
    while True:
        k, v, us = _ptrs_draw(bits, j, lam, a, b)
        j += np.uint64(2)
        if _ptrs_squeeze(us, v, v_r):
            return k
        if not _ptrs_not_rejected(k, us, v):
            continue
        if _ptrs_lhs(v, us, a, b, inv_alpha) <= -lam + k * loglam - _log_factorial(k):
            return k


@njit(inline="always", **_opts)
def _ptrs_constants(lam):
    """Constants of the transformed rejection for mean ``lam`` ≥ 10 (Hörmann
    1993): ``(log λ, b, a, 1/α, v_r)``."""
    b = 0.931 + 2.53 * np.sqrt(lam)
    a = -0.059 + 0.02483 * b
    inv_alpha = 1.1239 + 1.1328 / (b - 3.4)
    v_r = 0.9277 - 3.6224 / (b - 2.0)
    return log_positive(lam), b, a, inv_alpha, v_r


@njit(inline="always", **_opts)
def _ptrs_draw(bits, j, lam, a, b):
    """Attempt ``j`` (even): the candidate ``k``, the uniform ``v`` and ``us = ½ − |u|``."""
    u = uniform(pixel_bits(bits, j)) - 0.5
    v = uniform(pixel_bits(bits, j + _U1))
    us = 0.5 - abs(u)
    return np.floor((2.0 * a / us + b) * u + lam + 0.43), v, us


@njit(inline="always", **_opts)
def _ptrs_squeeze(us, v, v_r):
    """The squeeze: accept without the full test."""
    return (us >= 0.07) & (v <= v_r)


@njit(inline="always", **_opts)
def _ptrs_not_rejected(k, us, v):
    """False where the attempt is rejected before the full test."""
    return (k >= 0.0) & ((us >= 0.013) | (v <= us))


@njit(inline="always", **_opts)
def _ptrs_lhs(v, us, a, b, inv_alpha):
    """Left side of the full acceptance test ``lhs ≤ −λ + k log λ − log k!``."""
    return log_positive(v) + log_positive(inv_alpha) - log_positive(a / (us * us) + b)


@njit(inline="always", **_opts)
def _shot_noise_block(ibuf, electrons, rkey, pix0, zbuf, bbuf, work):
    """``ibuf[i] ← poisson(ibuf[i]·e_i, bits_i)/e_i`` for the 64 lanes of a block.

    Bit for bit :func:`poisson`, in up to three passes, the first two
    branch-free over the lanes:

    * λ ≥ 10: the first attempt of the transformed rejection
      (:func:`_ptrs_first_attempt`); it settles 75 % of draws at λ = 10 and
      87 % at λ = 480;
    * λ < 10: the inversion search run in lock-step for all lanes, for as
      many steps as the block's largest such λ needs (λ + 4√λ + 6; beyond
      that, P < 1e-5, the search is left to the last pass);
    * the lanes left go on one by one: the rejection from its second attempt,
      the search from the start.

    ``zbuf``/``bbuf`` are scratch (float64/uint64), ``work`` (5, 64) float64.
    """
    lam_v = work[0]
    n_small = 0
    small_max = 0.0
    for lane in range(BLOCK):
        lam = min(ibuf[lane] * electrons[lane], LAMBDA_MAX)
        lam_v[lane] = lam
        bbuf[lane] = pixel_bits(rkey, pix0 + np.uint64(lane))
        small = lam < _POISSON_INVERSION_MAX
        n_small += 1 if small else 0
        small_max = max(small_max, lam if small else 0.0)
    if n_small < BLOCK:
        _ptrs_first_attempt(lam_v, bbuf, zbuf)
    else:
        for lane in range(BLOCK):
            zbuf[lane] = np.nan
    if n_small:
        _inversion_lockstep(lam_v, bbuf, zbuf, work, small_max)
    slow = 0
    for lane in range(BLOCK):
        slow += 0 if zbuf[lane] >= 0.0 else 1  # NaN or undecided
    if slow:
        for lane in range(BLOCK):
            z = zbuf[lane]
            if not z >= 0.0:  # not settled by the passes above
                lam = lam_v[lane]
                if lam < _POISSON_INVERSION_MAX:
                    zbuf[lane] = poisson(lam, bbuf[lane])
                else:  # attempt 0 rejected: go on from attempt 2; undecided: redo it
                    first = np.uint64(0) if z == _UNDECIDED else np.uint64(2)
                    zbuf[lane] = _ptrs_from(lam, bbuf[lane], first)
    for lane in range(BLOCK):
        ibuf[lane] = zbuf[lane] / electrons[lane]


@njit(inline="always", **_opts)
def _ptrs_attempt(lam, bits, j):
    """Attempt ``j`` of :func:`_ptrs_from` for ``lam`` ≥ 10 without branches:
    the draw if accepted (squeeze, or the full test with ``log k!`` from the
    table), NaN if rejected, :data:`_UNDECIDED` where the full test needs
    ``log k!`` beyond the table (the caller then runs :func:`_ptrs_from` from
    this attempt).  The same helpers, so the same bits as the scalar loop."""
    table_top = np.float64(_LOG_FACTORIAL.shape[0] - 1)
    loglam, b, a, inv_alpha, v_r = _ptrs_constants(lam)
    k, v, us = _ptrs_draw(bits, j, lam, a, b)
    log_fact = _LOG_FACTORIAL[np.int64(min(max(k, 0.0), table_top))]
    tested = _ptrs_not_rejected(k, us, v)
    full = (tested & (k <= table_top)
            & (_ptrs_lhs(v, us, a, b, inv_alpha) <= -lam + k * loglam - log_fact))
    undecided = tested & (k > table_top)
    return k if _ptrs_squeeze(us, v, v_r) | full else (_UNDECIDED if undecided else np.nan)


@njit(inline="always", **_opts)
def _ptrs_first_attempt(lam_v, bbuf, zbuf):
    """Attempt 0 for every lane with λ ≥ 10: ``zbuf`` gets the accepted draws,
    :data:`_UNDECIDED` or NaN elsewhere (lanes with λ < 10 compute it at
    λ = 10, not kept)."""
    for lane in range(BLOCK):
        lam = lam_v[lane]
        k = _ptrs_attempt(max(lam, _POISSON_INVERSION_MAX), bbuf[lane], np.uint64(0))
        zbuf[lane] = k if lam >= _POISSON_INVERSION_MAX else np.nan


@njit(inline="always", **_opts)
def _inversion_lockstep(lam_v, bbuf, zbuf, work, small_max):
    """The inversion search of :func:`poisson` for every lane with λ < 10 at
    once: step ``j`` updates ``p_j``, ``F_j`` and counts the lanes still above
    their CDF, so after ``J`` steps the count is the draw wherever ``u ≤ F_J``.
    Writes those draws to ``zbuf``; other λ < 10 lanes keep NaN."""
    u_v = work[1]
    p_v = work[2]
    cdf_v = work[3]
    k_v = work[4]
    for lane in range(BLOCK):
        lam = lam_v[lane]
        small = lam < _POISSON_INVERSION_MAX
        p = exp_nonpositive(-(lam if small else 0.0))
        u_v[lane] = uniform(bbuf[lane])
        p_v[lane] = p if small else 0.0  # other lanes: inert
        cdf_v[lane] = p if small else 0.0
        k_v[lane] = 0.0
    steps = min(np.int64(small_max + 4.0 * np.sqrt(small_max) + 6.0), _POISSON_INVERSION_CAP)
    for j in range(1, steps + 1):
        inv_j = _INV_INT[j]
        for lane in range(BLOCK):
            go = u_v[lane] > cdf_v[lane]  # the scalar loop's condition; stopped lanes freeze
            p = p_v[lane] * (lam_v[lane] * inv_j)
            p_v[lane] = p if go else p_v[lane]
            cdf_v[lane] = cdf_v[lane] + p if go else cdf_v[lane]
            k_v[lane] += 1.0 if go else 0.0
    for lane in range(BLOCK):
        done = (lam_v[lane] < _POISSON_INVERSION_MAX) & (u_v[lane] <= cdf_v[lane])
        zbuf[lane] = k_v[lane] if done else zbuf[lane]
