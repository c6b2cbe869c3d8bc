"""numba kernels of the integrate-and-fire sensor (no validation, no I/O).

Model (docs/model.md; Dong et al., AAAI 2024, eq. 1):

* Radiance is piecewise linear in time between key frames.  The charge of
  readout ``n`` (the period ``[n, n+1)`` in readout units) is the exact
  integral ``q_n = gain · Ī_n + offset`` where ``Ī_n`` is the mean radiance
  over the period, evaluated in float64:

  - inside one segment ``[t_a, t_b]``: ``Ī_n = I_a + (I_b − I_a) · φ_n`` with
    ``φ_n = (n + ½ − t_a) · inv_span`` (the mean of a linear function is its
    value at the midpoint);
  - a period that contains key times is split into pieces, each contributing
    ``length · (I_a + (I_b − I_a) · φ_mid)``;
  - before the first and after the last key the radiance is held.

* The accumulator, in units of the pixel's own threshold, is exact fixed
  point: a 64-bit fraction (units of 2⁻⁶⁴ θ) and a signed 64-bit whole part.
  The per-readout charge is converted once (truncation to 2⁻⁶⁴ θ) and then
  added exactly, so there is no drift however long the stream.
* Clocked readout: after adding ``q_n`` the pixel emits 1 if the charge reached
  one threshold; at most one spike per readout.  Reset ``modulo`` keeps the
  fraction (A mod θ), ``subtract`` removes one θ (excess accumulates), ``zero``
  clears the accumulator.
* Noise (each optional, all drawn from counter-based hashes of
  (stream, pixel, readout), see ``spikesim.rng``):
  paper mode ``Ĩ = max(Ī + σ(Ī)·z/255, 0)``, ``σ² = σ_g² + σ_p²·255·Ī``;
  Poisson shot noise on ``q·E`` electrons (E electrons per threshold);
  threshold jitter ``θ(1 + σ_t z)`` drawn at every firing for the next cycle.
* Event-driven shot noise (``spikesim._event``, physical mode without charge
  noise): per pixel and firing cycle the readout of the next threshold
  crossing is drawn as an Erlang waiting time in operational time
  ``Λ = Σ E·q_n`` (draws keyed by (stream, pixel, cycle)); on runs of
  linear radiance (the charge on a 2⁻³² e⁻ grid, linear in the readout) each
  pixel goes from firing to firing with no work per readout at all
  (``spikesim._event.event_direct``, exact); elsewhere per readout the block
  only subtracts ``E·q_n`` from each lane's wait and takes the firing lanes'
  next waits from a per-lane cache of draws made ahead, so the work is per
  spike.  Its state is the float64 ``aux`` array, not the fixed point.
* Charge loss at reset: the readout after a firing collects ``(1 − f)·q_n``.

Work is split in blocks of 64 pixels of one row (8 packed bytes) run in
parallel; time is the inner loop of each block so its state stays in
registers/L1.  Fast paths, taken per run and block where every whole part
is 0 and every charge is provably < 1 threshold (there the three reset modes
reduce to the carry, cleared for zero reset), are one 64-lane vector step per
readout (``spikesim._simd``): an integer add for static segments, the exact
linear charge for moving ones, and the noisy charge for paper-mode noise.
Charges too large for the fixed point saturate (:data:`Q_WHOLE_MAX`,
:data:`WHOLE_MAX`), so any finite input fires at every readout.
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import numba
import numpy as np
from numba import njit, prange

from spikesim._event import (
    AFTER_RESET,
    BACKLOG_MAX,
    EV_WORK_F,
    EV_WORK_U,
    GNEXT,
    MOVING_WALK_MIN,
    WMIN,
    event_cache_clear,
    event_direct,
    event_lane_keys,
    event_settle,
    event_step,
    event_sync,
    init_event_block,
    linear_charge,
    walkable,
)
from spikesim._event import WAIT as EV_WAIT
from spikesim._poisson import LAMBDA_MAX, _shot_noise_block
from spikesim._simd import (
    carry_run64,
    carry_run64_zero,
    counting_down_pays,
    event_cached_run64,
    event_cached_run64_static,
    event_cached_run64_zero,
    event_cached_run64_zero_static,
    linear_carry_run64,
    linear_carry_run64_zero,
    paper_carry_add64,
    paper_carry_add64_zero,
    prefer_wide_vectors,
    store_word,
)
from spikesim._zero_period import zero_reset_run
from spikesim.rng import (
    NORMAL_ABS_MAX,
    normals_into,
    pixel_bits,
    pixel_keys_into,
    readout_key,
)

BLOCK = 64  # pixels per block: one uint64 spike mask = 8 packed bytes
#: Work rows per task: 14 float64 and 2 uint64 of the per-readout steps, then
#: the event sampler's (``spikesim._event.EV_WORK_F``, ``EV_WORK_U``).
_EV_F0 = 14
_EV_U0 = 2
SCRATCH_F = _EV_F0 + EV_WORK_F
SCRATCH_U = _EV_U0 + EV_WORK_U
TWO64 = 2.0**64
FAST_Q_LIMIT = 1.0 - 2.0**-20  # fast path only when every charge is safely < 1 θ
#: Largest whole part of one readout's charge (thresholds).  A float64 charge
#: ≥ 2⁵² has no fractional part, so clamping it here changes no spike in modulo
#: or zero reset (every larger charge fires and leaves fraction 0); infinite
#: charges (radiance × rate beyond float64) clamp here too.
Q_WHOLE_MAX = 2.0**53
#: Largest backlog of subtract reset (thresholds): the accumulator saturates
#: here, so ``whole + charge + carry`` never overflows int64 (2⁶² + 2⁵³ + 1 < 2⁶³).
#: A pixel holding it fires at every readout for 2⁶² readouts after the light stops.
WHOLE_MAX = 2**62
_FRAC_MAX = TWO64 - 2048.0  # the largest float64 below 2⁶⁴

#: Shortest static zero-reset run counted down (:mod:`spikesim._zero_period`)
#: rather than added and cleared per readout: its set-up (two exact quotients
#: a lane, about 0.56 µs a block) pays from about 100 readouts on (AMD EPYC
#: host, cache-resident, medians of 5 runs: 8.5 against 8.3 ns a block-readout
#: at 100, 5.5 against 7.9 at 200).
ZERO_PERIOD_MIN = 128

RESET_MODULO = 0
RESET_SUBTRACT = 1
RESET_ZERO = 2

RUN_SEGMENT = 0  # readouts [start, stop) inside one segment (or a hold)
RUN_PIECES = 1  # one readout whose period contains key times


class RunSchedule(NamedTuple):
    """The readouts of one chunk as runs (``spikesim.schedule.build_schedule``).

    Times are in readout units (readout ``n`` is the period ``[n, n+1)``);
    run ``r`` covers readouts ``[start[r], stop[r])``.  A numba-compatible
    named tuple: the kernel takes it as one argument.
    """

    kind: np.ndarray  #: (R,) int8, RUN_SEGMENT or RUN_PIECES
    start: np.ndarray  #: (R,) int64, first readout of the run
    stop: np.ndarray  #: (R,) int64, one past its last readout
    a: np.ndarray  #: (R,) int64, key frame at the segment's start (a hold: a == b)
    b: np.ndarray  #: (R,) int64, key frame at its end
    ta: np.ndarray  #: (R,) float64, time of key ``a``
    inv: np.ndarray  #: (R,) float64, 1 / (t_b − t_a), 0 for a hold
    p0: np.ndarray  #: (R,) int64, a RUN_PIECES run's pieces are [p0, p1)
    p1: np.ndarray  #: (R,) int64
    piece_a: np.ndarray  #: (P,) int64, segment of each piece: key frames a, b
    piece_b: np.ndarray  #: (P,) int64
    piece_len: np.ndarray  #: (P,) float64, length of the piece (readouts)
    piece_phi: np.ndarray  #: (P,) float64, (midpoint − t_a) / (t_b − t_a)


class PixelModel(NamedTuple):
    """The constant inputs of one accumulator set (the noisy stream or its
    clean twin): per-pixel charge constants, reset, fast-path flags, and the
    noise model's parameters and stream keys (``spikesim.rng.stream_key``).
    Built once per run by ``spikesim.simulate``; a numba-compatible named tuple.

    The per-pixel arrays are (H, Wp) float64, or a single row (1, Wp) shared by
    every row (a sensor without fixed pattern); padding lanes (x ≥ W) have zero
    gain and offset, so they never fire.
    """

    gain: np.ndarray  #: thresholds per readout per unit radiance
    offset: np.ndarray  #: thresholds per readout (dark current)
    electrons: np.ndarray  #: electrons per threshold; −1 everywhere: no shot noise
    charge_sd: np.ndarray  #: per-readout charge noise s.d. (thresholds); −1: off
    reset: int  #: RESET_MODULO, RESET_SUBTRACT or RESET_ZERO
    fast_ok: bool  #: no per-readout noise: the vector fast paths may run
    paper_fast_ok: bool  #: paper-mode noise only: its vector fast path may run
    paper_sg2: float  #: paper mode σ_g² (DN²)
    paper_sp2: float  #: paper mode σ_p² (DN)
    jitter: float  #: σ_t, relative threshold s.d. per firing cycle
    loss: float  #: charge loss at reset (fraction of the next readout's charge)
    event: bool  #: shot noise drawn per spike (``spikesim._event``)
    key_paper: np.uint64  #: stream keys of the per-readout draws
    key_shot: np.uint64
    key_jitter: np.uint64
    key_charge: np.uint64
    key_init: np.uint64  #: the initial accumulator's key
    ev_keys: np.ndarray  #: (3,) uint64, the event sampler's wait, residual, refill keys


class PixelState(NamedTuple):
    """The state of one accumulator set, updated in place chunk by chunk."""

    frac: np.ndarray  #: (H, Wp) uint64, fraction of the accumulator (2⁻⁶⁴ θ)
    whole: np.ndarray  #: (H, Wp) int64, whole thresholds (subtract's backlog)
    aux: np.ndarray  #: (4, H, Wp) float64 event state, or a (4, 1, 64) dummy when unused

_U1 = np.uint64(1)

_opts = dict(cache=True, error_model="numpy", boundscheck=False)
#: The functions called per row, block or run: no reference counting.  numba
#: otherwise increments and decrements the count of every array argument (those
#: inside the named tuples too) at each call, atomically; on arrays the threads
#: share that cost about 0.6 µs per call of :func:`_block_runs`, more than a
#: 1-readout block's whole work (measured).  These functions allocate nothing and
#: keep no array beyond the call, so they need no counts.
_inner = dict(_opts, _nrt=False)


@njit(inline="always", **_opts)
def _to_fixed(q):
    """Split a non-negative charge (thresholds) into (whole int64, fraction uint64);
    charges ≥ :data:`Q_WHOLE_MAX` (infinity included) saturate there, fraction 0."""
    qc = min(q, Q_WHOLE_MAX)
    w = np.floor(qc)
    # q − ⌊q⌋ < 1 exactly for q ≥ 0 (so ≤ _FRAC_MAX); a tiny negative charge
    # (charge noise) may round to 1.0 and is kept just below it
    return np.int64(w), np.uint64(min((qc - w) * TWO64, _FRAC_MAX))


@njit(inline="always", **_opts)
def _segment_radiance(frames, a, b, y, x0, ia, di):
    """Per-lane I_a and I_b − I_a of a segment for the block at (y, x0)."""
    for lane in range(BLOCK):
        va = np.float64(frames[y, x0 // BLOCK, a, lane])
        ia[lane] = va
        di[lane] = np.float64(frames[y, x0 // BLOCK, b, lane]) - va


@njit(inline="always", **_opts)
def _pieces_radiance(frames, p0, p1, piece_a, piece_b, piece_len, piece_phi, y, x0, ibuf):
    """Mean radiance of a readout whose period is split at key times."""
    for lane in range(BLOCK):
        ibuf[lane] = 0.0
    for p in range(p0, p1):
        a = piece_a[p]
        b = piece_b[p]
        ln = piece_len[p]
        phi = piece_phi[p]
        for lane in range(BLOCK):
            va = np.float64(frames[y, x0 // BLOCK, a, lane])
            vb = np.float64(frames[y, x0 // BLOCK, b, lane])
            ibuf[lane] += ln * (va + (vb - va) * phi)


@njit(**_inner)
def _fast_static(n0, n1, qconst, frac, out, t_off, y, blk, zero, work):
    """Constant charge < 1 θ, empty whole part: a 64-lane integer add whose
    carry bits are the spikes, the whole run in one call with the accumulator
    in registers (:func:`spikesim._simd.carry_run64`; with ``zero`` reset the
    carrying lanes are cleared).  Modulo and subtract reset are the same step
    here (the whole part stays 0).  ``frac`` is the block's contiguous state;
    the charges ``qconst`` are converted to 2⁻⁶⁴ θ units in the call."""
    first, stride, nbytes = _word_at(out, n0 - t_off, y, blk)
    if zero and n1 - n0 >= ZERO_PERIOD_MIN and counting_down_pays():
        zero_reset_run(frac, qconst, work, out, first, stride, nbytes, n1 - n0)
    elif zero:
        carry_run64_zero(frac, qconst, out, first, stride, nbytes, n1 - n0)
    else:
        carry_run64(frac, qconst, out, first, stride, nbytes, n1 - n0)


@njit(inline="always", **_opts)
def _word_at(out, t, y, blk):
    """Where block ``blk`` of row ``y`` of readout ``t`` goes in ``out`` (the
    packed (T, H, ⌈W/8⌉) uint8 bits, C-contiguous): its first byte (flat
    index), the step in bytes from one readout to the next, and its number of
    bytes in the row (8, or fewer for the row's last block)."""
    row_bytes = out.shape[2]
    stride = out.shape[1] * row_bytes
    return (t * stride + y * row_bytes + 8 * blk, stride,
            min(np.int64(8), row_bytes - 8 * np.int64(blk)))


@njit(inline="always", **_opts)
def _put(out, t, y, blk, word):
    """Write the 64 spike bits ``word`` of block ``blk``, row ``y``, readout
    ``t`` into the packed ``out`` (:func:`_word_at`)."""
    first, _, nbytes = _word_at(out, t, y, blk)
    store_word(out, first, word, nbytes)


@njit(**_inner)
def _fast_linear(n0, n1, t_a, inv_span, ia, di, gain, offset, frac, out, t_off, y, blk, zero):
    """No per-readout noise, charge < 1 θ, empty whole part, linear radiance:
    the whole run in one vector call with the accumulator in registers
    (:func:`spikesim._simd.linear_carry_run64`, or its ``_zero`` twin for zero
    reset).  ``ia``, ``di``, ``gain``, ``offset`` and the state ``frac`` are
    the block's contiguous rows."""
    first, stride, nbytes = _word_at(out, n0 - t_off, y, blk)
    if zero:
        linear_carry_run64_zero(frac, ia, di, gain, offset, n0, t_a, inv_span, out, first,
                                stride, nbytes, n1 - n0)
    else:
        linear_carry_run64(frac, ia, di, gain, offset, n0, t_a, inv_span, out, first, stride,
                           nbytes, n1 - n0)


@njit(inline="always", **_opts)
def _paper_fits(n0, n1, t_a, inv_span, ia, di, gain, offset, paper_sg2, paper_sp2):
    """True when no paper-mode charge of readouts ``[n0, n1)`` can reach one
    threshold: the level is linear in time, so its largest value is at an end
    of the run, and the noisy level is at most ``level + σ(level)·NORMAL_ABS_MAX``
    (σ grows with the level).  Branch-free count, so it vectorises."""
    phi_first = (np.float64(n0) + 0.5 - t_a) * inv_span
    phi_last = (np.float64(n1 - 1) + 0.5 - t_a) * inv_span
    too_big = 0
    for lane in range(BLOCK):
        top = max(ia[lane] + di[lane] * phi_first, ia[lane] + di[lane] * phi_last, 0.0)
        sd = np.sqrt(paper_sg2 + paper_sp2 * 255.0 * top) * (1.0 / 255.0)
        q = gain[lane] * (top + sd * NORMAL_ABS_MAX) + offset[lane]
        too_big += 0 if q < FAST_Q_LIMIT else 1
    return too_big == 0


@njit(**_inner)  # a call per run: inlined, it slowed the noise-free paths (code layout)
def _fast_paper(n0, n1, t_a, inv_span, ia, di, gain, offset, frac, out, t_off, y, blk,
                model, pkeys, level, z, sd, bits, zero):
    """Paper-mode noise only, every noisy charge < 1 θ, empty whole part
    (:func:`_paper_fits`): per readout the block's normal deviates
    (:func:`spikesim.rng.normals_into`) and one vector step
    (:func:`spikesim._simd.paper_carry_add64`), the same values as
    :func:`_general_step`.  ``level, z, sd, bits`` are contiguous scratch
    (``gain``, ``offset`` and the state ``frac`` contiguous already).

    Compiled for the widest vectors: with the x86 default for AVX-512 CPUs
    (256-bit preferred) LLVM left the deviates' loop scalar, and paper-mode
    runs took 1.4–1.5× longer."""
    prefer_wide_vectors()
    paper_sg2 = model.paper_sg2
    paper_sp2 = model.paper_sp2
    key_paper = model.key_paper
    sd_const = np.sqrt(paper_sg2) * (1.0 / 255.0)
    moving = 0
    for lane in range(BLOCK):
        sd[lane] = sd_const
        moving += 0 if di[lane] == 0.0 else 1
    # σ depends on the level only, so a static block computes it once
    sd_per_readout = paper_sp2 > 0.0 and moving > 0
    if paper_sp2 > 0.0 and moving == 0:
        for lane in range(BLOCK):
            sd[lane] = np.sqrt(paper_sg2 + paper_sp2 * 255.0 * (ia[lane] + di[lane] * 0.0)) * (
                1.0 / 255.0)
    for n in range(n0, n1):
        phi = (np.float64(n) + 0.5 - t_a) * inv_span
        for lane in range(BLOCK):
            level[lane] = ia[lane] + di[lane] * phi
        if sd_per_readout:
            for lane in range(BLOCK):
                sd[lane] = np.sqrt(paper_sg2 + paper_sp2 * 255.0 * level[lane]) * (1.0 / 255.0)
        normals_into(readout_key(key_paper, n), pkeys, z, bits)
        if zero:
            word = paper_carry_add64_zero(frac, level, z, sd, gain, offset, 0)
        else:
            word = paper_carry_add64(frac, level, z, sd, gain, offset, 0)
        _put(out, n - t_off, y, blk, word)


@njit(**_inner)
def _general_step(n, ibuf, gain, offset, electrons, charge_sd, frac, whole, y, x0, width,
                  model, zbuf, bbuf, pkeys, shot_work, after, paper, readout):
    """One readout of the general model for a block; returns the spike mask.

    ``ibuf`` holds the mean radiance of each lane on entry and is overwritten
    with the charge; ``zbuf`` (float64) and ``bbuf`` (uint64) are scratch for
    the lanes' normal deviates and their random bits, ``pkeys`` the block's
    pixel keys (:func:`spikesim.rng.pixel_keys_into`).
    Each stage is a separate loop over the 64 lanes so the stages without
    data-dependent control flow vectorise; padding lanes (x ≥ width) have
    zero gain and offset, so they never fire whatever noise is drawn for them.
    ``loss`` > 0: the mean charge of a lane whose ``after`` flag is 1 (it
    fired at the previous readout) is scaled by ``1 − loss`` (charge loss at
    reset, before shot and charge noise); the flags are updated here.
    """
    paper_sg2 = model.paper_sg2
    paper_sp2 = model.paper_sp2
    jitter = model.jitter
    loss = model.loss
    reset = model.reset
    pix0 = np.uint64(y * width + x0)
    if paper is not None and (paper_sg2 > 0.0 or paper_sp2 > 0.0):
        normals_into(readout_key(model.key_paper, n), pkeys, zbuf, bbuf)
        if paper_sp2 > 0.0:
            for lane in range(BLOCK):
                level = ibuf[lane]
                sd = np.sqrt(paper_sg2 + paper_sp2 * 255.0 * level) * (1.0 / 255.0)
                ibuf[lane] = max(level + sd * zbuf[lane], 0.0)
        else:
            sd = np.sqrt(paper_sg2) * (1.0 / 255.0)
            for lane in range(BLOCK):
                ibuf[lane] = max(ibuf[lane] + sd * zbuf[lane], 0.0)
    for lane in range(BLOCK):
        ibuf[lane] = gain[lane] * ibuf[lane] + offset[lane]
    if readout is not None and loss > 0.0:
        for lane in range(BLOCK):
            ibuf[lane] *= 1.0 - loss * after[lane]
    if readout is not None and electrons[0] >= 0.0:
        _shot_noise_block(ibuf, electrons, readout_key(model.key_shot, n), pix0, zbuf, bbuf,
                          shot_work)
    # accumulating charge noise (−1: off; padding lanes 0)
    if readout is not None and charge_sd[0] >= 0.0:
        normals_into(readout_key(model.key_charge, n), pkeys, zbuf, bbuf)
        for lane in range(BLOCK):
            ibuf[lane] += charge_sd[lane] * zbuf[lane]
    m = np.uint64(0)
    for lane in range(BLOCK):
        qw, qf = _to_fixed(ibuf[lane])
        s = frac[lane] + qf
        w = min(whole[lane] + qw + (1 if s < frac[lane] else 0), WHOLE_MAX)
        fire = w >= 1
        if reset == RESET_SUBTRACT:
            w = w - 1 if fire else w
        else:
            w = 0 if fire else w
            if reset == RESET_ZERO:
                s = np.uint64(0) if fire else s
        m |= np.uint64(fire) << np.uint64(lane)
        frac[lane] = s
        whole[lane] = w
    if readout is not None and loss > 0.0:
        for lane in range(BLOCK):
            after[lane] = 1.0 if ((m >> np.uint64(lane)) & _U1) != 0 else 0.0
    if readout is not None and jitter > 0.0 and m != 0:
        # the next cycle's threshold is θ(1 + ε)  ⇔  the charge shifts by −ε;
        # deviates for all lanes (vectorised), applied where the lane fired
        normals_into(readout_key(model.key_jitter, n), pkeys, zbuf, bbuf)
        for lane in range(BLOCK):
            fired = ((m >> np.uint64(lane)) & _U1) != 0
            eps = jitter * zbuf[lane]
            ef = np.uint64(min(abs(eps), 0.5) * TWO64) if fired else np.uint64(0)
            s = frac[lane]
            up = eps > 0.0
            t = s - ef if up else s + ef
            whole[lane] += (-1 if up & (t > s) else 0) + (1 if (not up) & (t < s) else 0)
            frac[lane] = t
    return m


@njit(inline="always", **_opts)
def _charge_rows(model, y, x0, gain, offset):
    """Copy the block's charge constants (row ``y``, lanes from ``x0``) into
    the contiguous rows ``gain``, ``offset``."""
    gy = y if model.gain.shape[0] > 1 else 0
    oy = y if model.offset.shape[0] > 1 else 0
    for lane in range(BLOCK):
        gain[lane] = model.gain[gy, x0 + lane]
        offset[lane] = model.offset[oy, x0 + lane]


@njit(inline="always", **_opts)
def _noise_rows(model, y, x0, electrons, charge_sd):
    """The same for the noise constants, which only the event and general
    steps read (the fast paths never: a block copies them when it first needs
    them)."""
    ey = y * np.int64(model.electrons.shape[0] > 1)
    sy = y if model.charge_sd.shape[0] > 1 else 0
    for lane in range(BLOCK):
        electrons[lane] = model.electrons[ey, x0 + lane]
        charge_sd[lane] = model.charge_sd[sy, x0 + lane]


@njit(**_inner)
def _block_runs(frames, y, x0, width, t_off, runs, model, frac, whole, out,
                scratch_f, scratch_u, ev, words, paper, readout):
    """All runs of one chunk (``runs``, a :class:`RunSchedule`) for one 64-pixel
    block and one accumulator set (``model``, a :class:`PixelModel`; its state
    ``frac``, ``whole`` and ``ev`` are the block's contiguous copies).

    ``scratch_f`` (``SCRATCH_F``, 64) float64 and ``scratch_u`` (``SCRATCH_U``,
    64) uint64 are the caller's work rows (allocated once per task, not per
    block); the event sampler's rows come last, its lane keys already made
    (:func:`spikesim._event.event_lane_keys`); ``words`` (uint64, at least
    the chunk's readouts) takes a run's spike words from
    :func:`spikesim._event.event_direct`.
    ``model.fast_ok``: no per-readout noise; ``model.paper_fast_ok``: paper-mode
    noise only.  Either path is taken for a run only where every lane's whole part
    is 0 and every charge < 1 θ, where the three reset modes reduce to a
    carry (modulo and subtract: keep the fraction; zero: clear it).
    ``model.loss``: the charge loss at reset (its flags in ``ev[AFTER_RESET]``);
    the event sampler's models take :func:`_make_event_block`'s instead.  ``paper``,
    ``readout``: the kernel family (:func:`simulate_chunk`).
    """
    prefer_wide_vectors()  # the per-readout steps' loops of hashes vectorise (1.2–1.3×)
    if x0 < 0 or y < 0:  # never: it proves the indices non-negative, so the lane
        return  # loops index without wrap-around checks and vectorise (1.4× per block)
    gain = scratch_f[10]
    offset = scratch_f[11]
    _charge_rows(model, y, x0, gain, offset)
    ia = scratch_f[0]
    di = scratch_f[1]
    ibuf = scratch_f[2]
    zbuf = scratch_f[3]
    sdbuf = scratch_f[4]
    shot_work = scratch_f[5:10]
    electrons = scratch_f[12]
    charge_sd = scratch_f[13]
    bbuf = scratch_u[0]
    pkeys = scratch_u[1]
    noise_rows = False  # electrons and charge_sd copied
    blk = x0 // BLOCK
    zero = model.reset == RESET_ZERO
    if (model.paper_sg2 > 0.0 or model.paper_sp2 > 0.0 or model.jitter > 0.0
            or model.charge_sd[0, 0] >= 0.0):  # (−1 everywhere when off)
        pixel_keys_into(np.uint64(y * width + x0), pkeys)
    after = ev[AFTER_RESET]
    fast_ok = model.fast_ok
    paper_fast_ok = model.paper_fast_ok
    for r in range(runs.kind.shape[0]):
        n0 = runs.start[r]
        n1 = runs.stop[r]
        if runs.kind[r] == RUN_PIECES:
            _pieces_radiance(frames, runs.p0[r], runs.p1[r], runs.piece_a, runs.piece_b,
                             runs.piece_len, runs.piece_phi, y, x0, ibuf)
            if not noise_rows:
                _noise_rows(model, y, x0, electrons, charge_sd)
                noise_rows = True
            _put(out, n0 - t_off, y, blk, _general_step(
                n0, ibuf, gain, offset, electrons, charge_sd, frac, whole, y, x0, width, model,
                zbuf, bbuf, pkeys, shot_work, after, paper, readout))
            continue
        t_a = runs.ta[r]
        inv = runs.inv[r]
        _segment_radiance(frames, runs.a[r], runs.b[r], y, x0, ia, di)
        if fast_ok or paper_fast_ok:
            empty = 0
            for lane in range(BLOCK):
                empty += 1 if whole[lane] == 0 else 0
            fits = empty == BLOCK
        else:
            fits = False
        use_fast = fast_ok and fits
        static = True
        if use_fast:
            # branch-free counts, so this check vectorises like the step itself
            phi_first = (np.float64(n0) + 0.5 - t_a) * inv
            phi_last = (np.float64(n1 - 1) + 0.5 - t_a) * inv
            moving = 0
            too_big = 0
            for lane in range(BLOCK):
                d = di[lane]
                q1 = gain[lane] * (ia[lane] + d * phi_first) + offset[lane]
                q2 = gain[lane] * (ia[lane] + d * phi_last) + offset[lane]
                moving += 0 if d == 0.0 else 1
                too_big += 0 if (q1 < FAST_Q_LIMIT) & (q2 < FAST_Q_LIMIT) else 1
            static = moving == 0
            use_fast = too_big == 0
        if use_fast and static:
            for lane in range(BLOCK):
                ibuf[lane] = gain[lane] * (ia[lane] + di[lane] * 0.0) + offset[lane]
            _fast_static(n0, n1, ibuf, frac, out, t_off, y, blk, zero, scratch_u)
        elif use_fast:
            _fast_linear(n0, n1, t_a, inv, ia, di, gain, offset, frac, out, t_off, y, blk, zero)
        elif (paper is not None and paper_fast_ok and fits
              and _paper_fits(n0, n1, t_a, inv, ia, di, gain, offset, model.paper_sg2,
                              model.paper_sp2)):
            _fast_paper(n0, n1, t_a, inv, ia, di, gain, offset, frac, out, t_off, y, blk,
                        model, pkeys, ibuf, zbuf, sdbuf, bbuf, zero)
        else:
            if not noise_rows:
                _noise_rows(model, y, x0, electrons, charge_sd)
                noise_rows = True
            for n in range(n0, n1):
                phi = (np.float64(n) + 0.5 - t_a) * inv
                for lane in range(BLOCK):
                    ibuf[lane] = ia[lane] + di[lane] * phi
                _put(out, n - t_off, y, blk, _general_step(
                    n, ibuf, gain, offset, electrons, charge_sd, frac, whole, y, x0, width,
                    model, zbuf, bbuf, pkeys, shot_work, after, paper, readout))


@njit(inline="always", **_opts)
def _event_runs(frames, y, x0, width, t_off, runs, model, out, scratch_f, scratch_u, ev, words,
                reset):
    """:func:`_block_runs` for the event sampler (``model.event``; same
    arguments, the rows set up; ``reset`` the model's reset, a constant).
    Without charge loss, each run's charge is made linear on its grid
    (:func:`spikesim._event.linear_charge`; a ramp too steep for that form
    takes the per-readout step) and the run walked from firing to firing where every sum is exact
    (:func:`spikesim._event.event_direct`; a changing charge from
    :data:`spikesim._event.MOVING_WALK_MIN` readouts on), else it takes the
    readout loop with its cache (:func:`_event_run`).  With charge loss, and
    on readouts split into pieces, the per-readout step
    (:func:`spikesim._event.event_step`)."""
    ia, di, lam, dlam, lam_first = (scratch_f[0], scratch_f[1], scratch_f[2], scratch_f[3],
                                    scratch_f[4])
    gain, offset, electrons = scratch_f[10], scratch_f[11], scratch_f[12]
    ev_f = scratch_f[_EV_F0:]
    ev_u = scratch_u[_EV_U0:]
    blk = x0 // BLOCK
    pix0 = np.uint64(y * width + x0)
    event_cache_clear(ev_f, ev_u, width - x0)
    for r in range(runs.kind.shape[0]):
        n0 = runs.start[r]
        n1 = runs.stop[r]
        if runs.kind[r] == RUN_PIECES:
            _pieces_radiance(frames, runs.p0[r], runs.p1[r], runs.piece_a, runs.piece_b,
                             runs.piece_len, runs.piece_phi, y, x0, lam)
            _put(out, n0 - t_off, y, blk,
                 event_step(lam, gain, offset, electrons, ev, reset, model.jitter, model.loss,
                            model.ev_keys, pix0, ev_f, ev_u))
            continue
        t_a = runs.ta[r]
        inv = runs.inv[r]
        _segment_radiance(frames, runs.a[r], runs.b[r], y, x0, ia, di)
        if model.loss > 0.0 or not linear_charge(t_a, inv, ia, di, gain, offset, electrons,
                                                 lam, dlam):
            for n in range(n0, n1):
                phi = (np.float64(n) + 0.5 - t_a) * inv
                for lane in range(BLOCK):
                    lam[lane] = ia[lane] + di[lane] * phi
                _put(out, n - t_off, y, blk,
                     event_step(lam, gain, offset, electrons, ev, reset, model.jitter,
                                model.loss, model.ev_keys, pix0, ev_f, ev_u))
            continue
        m0 = n0 - np.int64(np.floor(t_a))  # readouts after the segment's reference
        walk, moving = walkable(lam, dlam, m0, n1 - n0, lam_first)
        if walk and (not moving or n1 - n0 >= MOVING_WALK_MIN):  # no work per readout
            event_direct(ev, lam_first, dlam, electrons, reset, model.jitter, model.ev_keys,
                         pix0, ev_f, ev_u, words, n1 - n0)
            for k in range(n1 - n0):
                _put(out, n0 + k - t_off, y, blk, words[k])
            continue
        n = n0
        while n < n1:  # waits in registers, firings from the cache
            k, bad = _event_run(ev, lam_first if not moving else lam, dlam, electrons, ev_f,
                                ev_u, m0 + (n - n0), out, t_off, y, n, blk, n1 - n, reset,
                                not moving)
            n += np.int64(k)
            if bad != 0:
                event_settle(bad, electrons, ev, reset, model.jitter, model.ev_keys, pix0, ev_f,
                             ev_u)


@njit(**_inner)
def _hold_block(frames, y, x0, t_off, runs, model, frac, whole, out, q, work):
    """A chunk that is one hold (one run whose key frames are ``a == b``: a
    static scene, or any chunk after the last key) of a noise-free model
    (``model.fast_ok``), for one block: :func:`_fast_static` at once when
    every lane's whole part is 0 and every charge < 1 θ, with the charges
    :func:`_block_runs` would give it (``di = 0``); returns False, having done
    nothing, otherwise.  The general function's set-up (its checks and work
    rows, a 6 KB stack frame) cost about 260 ns a block, more than the hold's
    whole 1-readout work: a 1-readout call's kernel at 1000 × 1000 took 7.6 ms
    through it and 3.4 ms here (one thread, AMD EPYC host)."""
    a = runs.a[0]
    gy = y if model.gain.shape[0] > 1 else 0
    oy = y if model.offset.shape[0] > 1 else 0
    blk = x0 // BLOCK
    bad = 0
    for lane in range(BLOCK):
        # gain·(I_a + di·0.0) + offset with di = 0, as the general path (−0 → +0)
        ql = model.gain[gy, x0 + lane] * (np.float64(frames[y, blk, a, lane]) + 0.0) \
            + model.offset[oy, x0 + lane]
        q[lane] = ql
        bad += 0 if (ql < FAST_Q_LIMIT) & (whole[lane] == 0) else 1
    if bad != 0:
        return False
    _fast_static(runs.start[0], runs.stop[0], q, frac, out, t_off, y, blk,
                 model.reset == RESET_ZERO, work)
    return True


@njit(inline="always", **_opts)
def _run_block(hold, frames, y, x0, width, t_off, runs, model, frac, whole, out, scratch_f,
               scratch_u, ev, words, paper, event, readout):
    """The chunk's runs for one block and accumulator set: :func:`_hold_block`
    where the chunk is one ``hold`` and the model noise-free, else (or where it
    declines) :func:`_block_runs` (same arguments)."""
    if event is not None and model.event:
        args = (frames, y, x0, width, t_off, runs, model, out, scratch_f, scratch_u, ev, words)
        if event == RESET_MODULO:
            _EVENT_BLOCK_MODULO(*args)
        elif event == RESET_SUBTRACT:
            _EVENT_BLOCK_SUBTRACT(*args)
        else:
            _EVENT_BLOCK_ZERO(*args)
    elif not (hold and model.fast_ok and _hold_block(frames, y, x0, t_off, runs, model, frac,
                                                     whole, out, scratch_f[2], scratch_u)):
        _block_runs(frames, y, x0, width, t_off, runs, model, frac, whole, out, scratch_f,
                    scratch_u, ev, words, paper, readout)


def _make_event_block(reset):
    """:func:`_block_runs` for the event sampler (``model.event``; same
    arguments) compiled for one reset mode (``RESET_*``, a constant here, so
    that only its own walks and refills are compiled): the block's rows set
    up, then :func:`_event_runs`.  A function of its own called from the
    entry point directly: a function numba caches carries the machine code of
    all it calls and optimises it again, so each level of calls between the
    entry point and the event sampler's pieces cost a compilation of them;
    inlined into the entry point instead, the physical family compiled 25 %
    longer."""

    @njit(**_inner)
    def event_block(frames, y, x0, width, t_off, runs, model, out, scratch_f, scratch_u, ev,
                    words):
        prefer_wide_vectors()  # the per-readout steps' loops of hashes vectorise (1.2–1.3×)
        if x0 < 0 or y < 0:  # never: it proves the indices non-negative, so the lane
            return  # loops index without wrap-around checks and vectorise (1.4× per block)
        _charge_rows(model, y, x0, scratch_f[10], scratch_f[11])
        _noise_rows(model, y, x0, scratch_f[12], scratch_f[13])  # (it reads the electrons)
        _event_runs(frames, y, x0, width, t_off, runs, model, out, scratch_f, scratch_u, ev,
                    words, reset)

    return event_block


_EVENT_BLOCK_MODULO, _EVENT_BLOCK_SUBTRACT, _EVENT_BLOCK_ZERO = (
    _make_event_block(reset) for reset in (RESET_MODULO, RESET_SUBTRACT, RESET_ZERO))


@njit(inline="always", **_opts)
def _event_run(ev, lam, dlam, electrons, ev_f, ev_u, m, out, t_off, y, n, blk, count, reset,
               static):
    """Up to ``count`` readouts from ``n`` (``m`` readouts after its segment's
    reference) of a run of linear charge (``lam``, ``dlam``:
    :func:`spikesim._event.linear_charge`; ``static``: ``dlam`` all zero),
    event sampler without charge loss (:func:`spikesim._simd.event_cached_run64`
    and its variants), the firings it took from the cache finished
    (:func:`spikesim._event.event_sync`); returns ``(k, bad)`` as it does."""
    first, stride, nbytes = _word_at(out, n - t_off, y, blk)
    args = (ev[EV_WAIT], lam, dlam, electrons, ev_f[GNEXT], ev_f[WMIN], m, LAMBDA_MAX,
            -BACKLOG_MAX, out, first, stride, nbytes, count)
    if reset == RESET_ZERO:  # (a constant: only one reset mode's loops are compiled)
        if static:
            k, bad, used = event_cached_run64_zero_static(*args)
        else:
            k, bad, used = event_cached_run64_zero(*args)
    elif static:
        k, bad, used = event_cached_run64_static(*args)
    else:
        k, bad, used = event_cached_run64(*args)
    event_sync(used, ev, ev_f, ev_u)
    return k, bad


@njit(inline="always", **_opts)
def _load_state(frac, whole, y, x0, f, w):
    """Copy a block's accumulator into contiguous ``f, w`` (explicit loops: a
    slice assignment costs about a microsecond per block, which a 1-readout call
    of a 1000×1000 sensor pays 32,000 times)."""
    for lane in range(BLOCK):
        f[lane] = frac[y, x0 + lane]
        w[lane] = whole[y, x0 + lane]


@njit(inline="always", **_opts)
def _store_state(frac, whole, y, x0, f, w):
    """The inverse of :func:`_load_state`."""
    for lane in range(BLOCK):
        frac[y, x0 + lane] = f[lane]
        whole[y, x0 + lane] = w[lane]


def _aligned_rows(n, dtype):
    """``n`` uninitialised rows of :data:`BLOCK` 8-byte lanes (C-contiguous),
    the first lane at a multiple of 64 bytes, so that every 8-lane part of a
    row is one cache line: numba aligns a new array to 32 bytes only, and a
    512-bit access that straddles two lines costs two (a refill 2.5–4 %
    slower per lane in a cache-resident microbenchmark with rows 32 bytes
    off; a whole moving physical run 8 %, docs/model.md, Speed)."""
    buf = np.empty(n * BLOCK + 8, dtype)
    skip = (8 - (buf.ctypes.data >> 3) % 8) % 8
    return buf[skip:skip + n * BLOCK].reshape((n, BLOCK))


def simulate_chunk(frames, width, t_off, runs, model, state, out, init, keep,
                   twin, twin_model, twin_state, twin_out, paper, event, readout):
    """Simulate readouts ``[runs.start[0], runs.stop[-1])`` for every pixel,
    on the threads numba may use (``numba.set_num_threads``).

    The rows are cut into groups of up to 8 (at least 64 groups when H ≥ 64)
    and the groups dealt out to ``parts`` calls of :func:`simulate_rows`, call
    ``k`` taking groups ``k, k + parts, …``: a row's cost follows the scene
    (the event-driven shot noise costs per spike), so interleaved groups give
    each call a share of the bright part.  The calls run on a pool of Python
    threads; the kernel releases the GIL.  (numba's own parallel loop compiled
    10 s longer than this kernel, a third of the noise-free family's compile
    time on the reference machine.)

    Parameters
    ----------
    frames : (H, Wp/64, K', 64) float32
        The sensor-channel radiances at the chunk's key frames: key ``k`` of
        pixel ``x`` at ``[y, x // 64, k, x % 64]`` (K' ≥ K, padding lanes zero,
        ``Wp`` a multiple of 64), so a block streams through its key frames.
    width : int
        The sensor's width W (pixels beyond it are padding).
    t_off : int
        The chunk's first readout: readout ``n`` is written to ``out[n − t_off]``.
    runs : RunSchedule
        The chunk's readouts as runs.
    model : PixelModel
        Charge constants, reset and noise of the (noisy) stream.
    state : PixelState
        Its accumulator.  ``init`` = −1 carries it on from the previous chunk
        (read on entry); ``init`` ≥ 0 starts a fresh one, made block by block
        in the kernel (the content on entry is never read): ``init`` = 1 a
        uniform fraction in [0, 1) θ from ``model.key_init`` (:func:`init_state`'s
        bits), 0 zero; the event state is derived from it.
    out : (T, H, ⌈W/8⌉) uint8, C-contiguous
        Receives the spikes in the packed little-bit-order layout: pixel x of
        row y at readout n is bit x % 8 of ``out[n − t_off, y, x // 8]`` (a
        block's 64 bits are written as one little-endian word, its bytes
        beyond the row's end left out).
    init : int
        See ``state``.
    keep : bool
        Write the state back for a next chunk.  A run's last chunk does not,
        and a run of one chunk never touches the state arrays at all: the
        accumulator (16 bytes a pixel) is the largest memory traffic of a short
        call.
    twin : bool
        Advance the noise-free twin (``twin_model``, ``twin_state``, written to
        ``twin_out``) in the same pass, from the same initial accumulator; when
        false those are placeholders of the same types.
    paper, event, readout : None, True or a reset code
        The kernel family (:mod:`spikesim.families`): which noise code is
        compiled, constants of the entry point (:func:`simulate_rows`), so
        numba prunes a branch they rule out before typing it.  ``None`` leaves
        a path out of the machine code altogether; otherwise it is compiled and
        the model's values decide at run time.  ``paper`` (True): paper-mode
        noise (its vector fast path and the per-readout deviates); ``event``
        (the model's ``RESET_*`` code): shot noise drawn per spike
        (``spikesim._event``) for that reset mode only; ``readout`` (True):
        physical noise drawn per readout (shot noise of the reference sampler,
        charge noise, threshold jitter, charge loss).  The noise-free paths
        are always compiled (the clean twin takes them).
    """
    height = frames.shape[0]
    rows = max(1, min(8, height // 64))  # rows per group: at least 64 groups when H ≥ 64
    groups = (height + rows - 1) // rows
    threads = numba.get_num_threads()
    parts = 1 if threads == 1 else min(groups, 4 * threads)
    args = (rows, frames, np.int64(width), np.int64(t_off), runs, model, state, out,
            np.int64(init), bool(keep), bool(twin), twin_model, twin_state, twin_out)
    kernel = simulate_rows(paper, event, readout)
    n_words = max(1, int(runs.stop[-1] - runs.start[0]))
    if parts == 1:
        kernel(np.int64(0), np.int64(1), *args, *_work_rows(n_words))
        return
    list(_thread_pool(threads).map(
        lambda k: kernel(np.int64(k), np.int64(parts), *args, *_work_rows(n_words)),
        range(parts)))


def _work_rows(n_words):
    """A call's work rows (:func:`simulate_rows`' last arguments): the
    per-readout steps' float64 and uint64 rows (:func:`_block_runs`), a
    block's event state ``ev`` (4, 64), accumulator ``f``, ``w`` and initial
    fraction ``f0`` (64), and ``words`` (a run's spike words).  Made here, not
    in the kernel, so that the kernel allocates nothing and needs no
    reference counts: with them, every call of a block function from the
    kernel counted each array argument up and down atomically, about 220 ns a
    64-pixel block, which doubled the time of a 1-readout call."""
    ev = _aligned_rows(4, np.float64)
    ev[:] = 0.0
    return (_aligned_rows(SCRATCH_F, np.float64), _aligned_rows(SCRATCH_U, np.uint64), ev,
            np.empty(BLOCK, np.uint64), np.empty(BLOCK, np.int64), np.empty(BLOCK, np.uint64),
            np.empty(n_words, np.uint64))


_POOL: list = [None, 0, 0]  # the pool, its size and the process that made it
_POOL_LOCK = threading.Lock()


def _thread_pool(threads: int) -> ThreadPoolExecutor:
    """A pool of ``threads`` threads kept between calls (made anew for another
    size, or in a child process after a fork)."""
    with _POOL_LOCK:
        pool, size, pid = _POOL
        if pool is None or size != threads or pid != os.getpid():
            if pool is not None and pid == os.getpid():
                pool.shutdown(wait=False)
            _POOL[:] = [ThreadPoolExecutor(threads, thread_name_prefix="spikesim"), threads,
                        os.getpid()]
        return _POOL[0]


def _make_rows_kernel(paper, event, readout):
    """:func:`simulate_rows` of one kernel family: ``paper``, ``event`` and
    ``readout`` are constants of the compiled function, so numba prunes the
    branches they rule out before typing them."""

    @njit(nogil=True, **_inner)
    def rows_kernel(part, parts, rows, frames, width, t_off, runs, model, state, out, init, keep,
                    twin, twin_model, twin_state, twin_out, scratch_f, scratch_u, ev, f, w, f0,
                    words):
        height = frames.shape[0]
        for group in range(part, (height + rows - 1) // rows, parts):
            for y in range(group * rows, min(height, group * rows + rows)):
                _simulate_row(np.int64(y), frames, width, t_off, runs, model, state, out, init,
                              keep, twin, twin_model, twin_state, twin_out, scratch_f,
                              scratch_u, ev, f, w, f0, words, paper, event, readout)

    return rows_kernel


_ROWS_KERNELS: dict = {}


def simulate_rows(paper, event, readout):
    """The compiled entry point of a kernel family (made once per process):
    it takes the row groups ``part, part + parts, …`` (``rows`` rows each) of
    :func:`simulate_chunk` (its other arguments but the markers), then the
    call's work rows (:func:`_work_rows`), and releases the GIL."""
    key = (paper, event, readout)
    kernel = _ROWS_KERNELS.get(key)
    if kernel is None:
        with _POOL_LOCK:
            kernel = _ROWS_KERNELS.setdefault(key, _make_rows_kernel(*key))
    return kernel


@njit(inline="always", **_opts)
def _simulate_row(y, frames, width, t_off, runs, model, state, out, init, keep,
                  twin, twin_model, twin_state, twin_out, scratch_f, scratch_u, ev, f, w, f0,
                  words, paper, event, readout):
    """Row ``y`` of :func:`simulate_chunk` (same arguments), block by block,
    with the task's contiguous work rows (``scratch_f``, ``scratch_u``, see
    :func:`_block_runs`, and ``words``), the block's event state ``ev`` (4, 64),
    accumulator ``f``, ``w`` and initial fraction ``f0`` (64)); ``paper``,
    ``event``, ``readout``: the kernel family (:func:`simulate_chunk`)."""
    nblk = frames.shape[1]
    use_aux = (event is not None and model.event) or model.loss > 0.0
    frac = state.frac
    whole = state.whole
    aux = state.aux
    init_key = readout_key(model.key_init, 0)
    ey = y * np.int64(model.electrons.shape[0] > 1)
    hold = (runs.kind.shape[0] == 1 and runs.kind[0] == RUN_SEGMENT
            and runs.a[0] == runs.b[0])
    for b in range(nblk):
        x0 = b * BLOCK
        if event is not None and model.event:
            event_lane_keys(model.ev_keys, np.uint64(y * width + x0), scratch_u[_EV_U0:])
        if init >= 0:
            _init_block(f, w, init_key, y, x0, width, init == 1)
            if event is not None and model.event:
                init_event_block(ev, f, model.electrons[ey], x0, scratch_u[_EV_U0:])
            elif use_aux:
                for lane in range(BLOCK):
                    ev[AFTER_RESET, lane] = 0.0  # no charge loss pending
            if twin:
                for lane in range(BLOCK):
                    f0[lane] = f[lane]
        else:
            _load_state(frac, whole, y, x0, f, w)
            if use_aux:
                for k in range(4):
                    for lane in range(BLOCK):
                        ev[k, lane] = aux[k, y, x0 + lane]
        _run_block(hold, frames, y, x0, width, t_off, runs, model, f, w, out, scratch_f,
                   scratch_u, ev, words, paper, event, readout)
        if keep:
            _store_state(frac, whole, y, x0, f, w)
            if use_aux:
                for k in range(4):
                    for lane in range(BLOCK):
                        aux[k, y, x0 + lane] = ev[k, lane]
        if twin:
            if init >= 0:
                for lane in range(BLOCK):
                    f[lane] = f0[lane]
                    w[lane] = 0
            else:
                _load_state(twin_state.frac, twin_state.whole, y, x0, f, w)
            _run_block(hold, frames, y, x0, width, t_off, runs, twin_model, f, w, twin_out,
                       scratch_f, scratch_u, ev, words, paper, None, readout)  # (never event)
            if keep:
                _store_state(twin_state.frac, twin_state.whole, y, x0, f, w)


@njit(inline="always", **_opts)
def _init_block(f, w, init_key, y, x0, width, uniform_init):
    """Initial accumulator of the block at (``y``, ``x0``) into ``f``, ``w``:
    the bits :func:`_init_row` gives these lanes (``init_key`` =
    ``readout_key(model.key_init, 0)``)."""
    base = np.uint64(y * width)
    for lane in range(BLOCK):
        x = x0 + lane
        bits = pixel_bits(init_key, base + np.uint64(x))
        f[lane] = bits if uniform_init and x < width else np.uint64(0)
        w[lane] = 0


@njit(inline="always", **_opts)
def _init_row(frac_row, whole_row, key, y, width, uniform_init):
    """Initial accumulator of row ``y``: fraction ``pixel_bits(readout_key(key,
    0), y·W + x)`` (uniform in [0, 1) θ) or zero, whole part 0; padding lanes 0."""
    rk = readout_key(key, 0)
    base = np.uint64(y * width)
    for x in range(frac_row.shape[0]):
        bits = pixel_bits(rk, base + np.uint64(x))
        frac_row[x] = bits if uniform_init and x < width else np.uint64(0)
        whole_row[x] = 0


@njit(parallel=True, **_opts)
def init_state(key, height, width, padded, uniform_init):
    """Initial accumulator: uniform fraction in [0, 1) θ per pixel, or zero
    (the values :func:`simulate_chunk` writes with ``init`` ≥ 0)."""
    frac = np.empty((height, padded), np.uint64)
    for y in prange(height):
        _init_row(frac[y], np.empty(padded, np.int64), key, y, width, uniform_init)
    return frac
