"""Event-driven photon shot noise: work per spike, not per readout (numba; no I/O).

Model (the per-readout sampler of ``spikesim._kernels`` gives the same law).
Readout ``n`` of a pixel collects ``K_n ~ Poisson(λ_n)`` electrons,
``λ_n = E·q_n`` with ``q_n = gain·Ī_n + offset`` its mean charge (thresholds)
and ``E`` the pixel's electrons per threshold; the counts of different readouts
are independent.  A sum of independent Poisson counts is Poisson, so the
electrons collected from the start of a cycle are a unit-rate Poisson process
in the *operational time* ``Λ(n) = Σ_k λ_k``, and the arrival of the ``m``-th
electron is at ``S ~ Gamma(m, 1)`` (Erlang) in that time.

State per pixel (``ev`` rows): ``need`` ``D``, the electrons from a
reference point (the previous crossing electron, or the end of a readout) to
the threshold, ``wait`` the operational time still to go to the ``m``-th
electron after that point, ``m = ⌈D⌉`` (``D`` ≤ 0: ``wait`` ≤ 0), the cycle
index ``c`` and the charge-loss flag (the pixel fired at the previous
readout).  Initially ``D = E·(1 − A₀)`` from the readout start.  Per readout
``wait ← wait − λ_n``; the clocked readout fires at the first readout at whose
end the count reaches ``m``, i.e. ``wait ≤ 0``, and :func:`fire_cycle` draws
the next crossing from the crossing electron (the Poisson process has
independent increments, so what came after it in this readout need not be
drawn), except where a reset depends on the charge at the readout's end:
zero reset (a fresh cycle from the readout's end) and a modulo reset that
drops a whole threshold (the count at the readout's end is drawn exactly,
``Poisson`` of the operational time left).  Comparator jitter: the next
threshold is ``θ(1 + ε)``, ``ε = σ_t·z`` clipped to ±½ (the per-readout model
moves the charge by −ε), ``E·ε`` electrons more.  So the work is one Gamma
variate (Marsaglia–Tsang, or a product of uniforms for small shapes) and
one normal per spike, a second, small Gamma (modulo with ε > 0 where a drop
is possible at all, see :func:`drop_negligible`) or a Poisson count only
where needed.

Every draw is keyed by (seed, source, pixel, cycle): source
``STREAM_WAIT`` for the Gamma variate of cycle ``c``, ``STREAM_RESIDUAL``
for its second Gamma or residual count, ``STREAM_REFILL`` for a wait drawn
from a readout's end after a modulo drop, and ``STREAM_JITTER`` for the jitter
at the end of cycle ``c`` (``pixel_bits(readout_key(key, c), pixel)``), so chunking and thread
count cannot change a bit.  Charge loss at reset (``reset_charge_loss`` f):
the readout after a firing contributes ``(1 − f)·λ_n`` (binomial thinning of
a Poisson count is Poisson).  Work per readout is one multiply-add and a
compare per pixel (vectorised over the 64 lanes); the random draws happen per
spike.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from spikesim._poisson import LAMBDA_MAX, poisson
from spikesim._simd import lowest_bit_index
from spikesim.rng import log_positive, normal, pixel_bits, readout_key, uniform

BLOCK = 64
#: Reset codes, the values of ``spikesim._kernels.RESET_*`` (tested equal).
MODULO = 0
SUBTRACT = 1
ZERO = 2
#: Largest subtract backlog, thresholds (``spikesim._kernels.WHOLE_MAX``).
BACKLOG_MAX = 2.0**62
#: Rows of a block's event state ``ev`` (4, 64).
WAIT, NEED, CYCLE, AFTER_RESET = 0, 1, 2, 3

_U1 = np.uint64(1)
_opts = dict(cache=True, error_model="numpy", boundscheck=False)


#: Shapes up to this use the product of uniforms (cheaper than a rejection).
SMALL_SHAPE = 8


@njit(**_opts)
def gamma_integer(m, bits):
    """Gamma(m, 1) deviate for an integer-valued shape ``m`` ≥ 1 from 64 random bits.

    ``m`` ≤ :data:`SMALL_SHAPE`: ``−log Π_j u_j`` (a sum of ``m`` unit
    exponentials, exact), ``u_j = uniform(pixel_bits(bits, j))``.  Larger:
    Marsaglia & Tsang, "A simple method for generating gamma variables", ACM
    TOMS 26(3), 2000: ``d = m − ⅓``, ``c = 1/√(9d)``, candidate
    ``d·(1 + c·x)³`` for a standard normal ``x``, accepted by the squeeze
    ``u < 1 − 0.0331·x⁴`` or ``log u < ½x² + d·(1 − v + log v)``; attempt
    ``j`` uses ``normal(pixel_bits(bits, 2j))`` and
    ``uniform(pixel_bits(bits, 2j + 1))``.  ``normal`` is the simulator's
    deviate (within 1.4e-4 of Φ⁻¹(u), :func:`spikesim.rng.normal`), which
    moves a variate by at most ``3c·1.4e-4`` relative (1.3e-5 at m = 1000);
    logarithms are :func:`spikesim.rng.log_positive` (absolute error < 1e-13).
    """
    if m <= SMALL_SHAPE:
        prod = 1.0
        for j in range(np.int64(m)):
            prod *= uniform(pixel_bits(bits, np.uint64(j)))
        return -log_positive(prod)
    d = m - 1.0 / 3.0
    c = 1.0 / np.sqrt(9.0 * d)
    j = np.uint64(0)
    while True:
        x = normal(pixel_bits(bits, j))
        u = uniform(pixel_bits(bits, j + _U1))
        j += np.uint64(2)
        t = 1.0 + c * x
        if t <= 0.0:
            continue
        v = t * t * t
        x2 = x * x
        if u < 1.0 - 0.0331 * x2 * x2:
            return d * v
        if log_positive(u) < 0.5 * x2 + d * (1.0 - v + log_positive(v)):
            return d * v


@njit(**_opts)
def cycle_wait(need, key, counter, pix):
    """Operational time (electrons) to the ``⌈need⌉``-th electron:
    ``Gamma(⌈need⌉, 1)`` from ``pixel_bits(readout_key(key, counter), pix)``;
    0 when ``need`` ≤ 0 (the pixel fires at the next readout)."""
    if not need > 0.0:
        return 0.0
    return gamma_integer(np.ceil(need), pixel_bits(readout_key(key, np.uint64(counter)), pix))


#: A modulo drop needs ``h0`` electrons within the operational time ``L`` left in
#: the readout after a crossing.  Chernoff's bound ``P(Poisson(L) ≥ h0) ≤
#: exp(h0·(1 − x + ln x))``, ``x = L/h0``, is below 2⁻⁶⁴ (smaller than any
#: probability a 64-bit draw can resolve) for ``x ≤ ½`` and ``h0 ≥ 230``
#: (``230·(½ − ln 2) = −44.4 < ln 2⁻⁶⁴ = −44.36``).
DROP_FREE_FRACTION = 0.5
DROP_FREE_ELECTRONS = 230.0


@njit(inline="always", **_opts)
def drop_negligible(left, h0):
    """True when a modulo drop (``h0`` electrons within operational time
    ``left``) has probability below 2⁻⁶⁴, so it need not be drawn."""
    return h0 >= DROP_FREE_ELECTRONS and left <= DROP_FREE_FRACTION * h0


@njit(**_opts)
def fire_cycle(wait, need, cycle, e, reset, jitter, key_wait, key_resid, key_refill, key_jitter,
               pix):
    """End cycle ``cycle``, whose crossing (the ``m = ⌈need⌉``-th electron)
    came ``−wait`` ≥ 0 of operational time before the end of this readout;
    returns the next cycle's ``(wait, need, cycle)``.

    ``lead = need − m`` ∈ (−1, 0] places the threshold relative to the
    crossing electron; the comparator jitter ``ε`` (``key_jitter``, counter
    ``cycle``) moves the next threshold by ``E·ε``.  The electrons after the
    crossing are a Poisson process, so (counter ``cycle + 1`` for the draws):

    * zero reset discards them: the next cycle needs ``E(1 + ε)`` electrons
      from the readout's end;
    * subtract: the next threshold is ``d = lead + E + E·ε`` electrons after
      the crossing, whose arrival is ``Gamma(⌈d⌉)`` after it (``key_wait``);
      the wait may stay ≤ 0 (the backlog fires at the next readouts);
    * modulo drops a whole threshold when the charge at the readout's end is
      ≥ 2θ, i.e. ≥ ``h0 = ⌈lead + E⌉`` electrons came after the crossing in
      this readout.  Where that has probability below 2⁻⁶⁴
      (:func:`drop_negligible`: the usual case, a pixel filling less than half
      a threshold per readout with ≥ 230 electrons per threshold), the next
      crossing is drawn at once as for subtract.  Else the arrival of electron
      ``h = min(h0, ⌈d⌉)`` is drawn (``key_wait``); after the readout's end,
      nothing was dropped and the next crossing is that arrival plus
      ``Gamma(⌈d⌉ − h)`` (``key_resid``);
      else the count at the readout's end is ``h + Poisson(rest)``
      (``key_resid``), the charge ``1 + x/E`` with ``x = h + Poisson − lead``
      is reset to ``x mod E`` exactly, and the next wait is drawn from the
      readout's end (``key_refill``).
    """
    c1 = cycle + 1.0
    k1 = np.uint64(c1)
    m = np.ceil(need) if need > 0.0 else 0.0
    eps = 0.0
    if jitter > 0.0:
        z = normal(pixel_bits(readout_key(key_jitter, np.uint64(cycle)), pix))
        eps = min(max(jitter * z, -0.5), 0.5)
    if reset == ZERO:
        d = e + e * eps
        return cycle_wait(d, key_wait, k1, pix), d, c1
    lead = need - m
    d = (lead + e) + e * eps
    hd = np.ceil(d) if d > 0.0 else 0.0
    if reset == SUBTRACT:
        w = wait + cycle_wait(hd, key_wait, k1, pix)
        return max(w, -BACKLOG_MAX * e), d, c1
    h0 = np.ceil(lead + e)
    # drawing the next crossing at once (one variate) is exact when no drop can happen
    h = hd if drop_negligible(-wait, h0) else min(h0, hd)
    g = cycle_wait(h, key_wait, k1, pix)
    if wait + g > 0.0:  # fewer than h electrons after the crossing in this readout
        if hd > h:
            g += cycle_wait(hd - h, key_resid, k1, pix)
        return wait + g, d, c1
    post = h + poisson(min(-(wait + g), LAMBDA_MAX),
                       pixel_bits(readout_key(key_resid, k1), pix))
    x = post - lead  # electrons beyond the threshold at the readout's end
    d2 = (e - np.fmod(x, e)) + e * eps
    return cycle_wait(d2, key_refill, k1, pix), d2, c1


@njit(inline="always", **_opts)
def event_step(level, gain, offset, electrons, ev, reset, jitter, loss, keys, pix0):
    """One readout of the event-driven model for a 64-lane block; returns the
    spike mask.  ``level`` holds each lane's mean radiance of the readout;
    ``ev`` (4, 64) the block's state (rows :data:`WAIT`, :data:`NEED`,
    :data:`CYCLE`, :data:`AFTER_RESET`), updated in place; ``keys`` the
    stream keys (wait, residual, refill, jitter).  The first loop
    (every lane, branch-free) vectorises; only lanes that fire go on to
    :func:`fire_cycle`.  Padding lanes have zero gain and offset, so they
    never fire."""
    wait = ev[WAIT]
    after = ev[AFTER_RESET]
    mask = np.uint64(0)
    for lane in range(BLOCK):
        q = gain[lane] * level[lane] + offset[lane]
        lam = min(q * electrons[lane], LAMBDA_MAX) * (1.0 - loss * after[lane])
        r = wait[lane] - lam
        wait[lane] = r
        mask |= np.uint64(r <= 0.0) << np.uint64(lane)
    if loss > 0.0:
        for lane in range(BLOCK):
            after[lane] = np.float64((mask >> np.uint64(lane)) & _U1)
    m = mask
    while m != 0:  # the lanes that fired, lowest first
        lane = np.int64(lowest_bit_index(m))
        m &= m - _U1
        w, d, c = fire_cycle(wait[lane], ev[NEED, lane], ev[CYCLE, lane], electrons[lane], reset,
                             jitter, keys[0], keys[1], keys[2], keys[3], pix0 + np.uint64(lane))
        wait[lane] = w
        ev[NEED, lane] = d
        ev[CYCLE, lane] = c
    return mask


@njit(inline="always", **_opts)
def init_event_block(ev, frac, electrons_row, x0, key_wait, pix0):
    """Event state ``ev`` (4, 64) of the block whose first lane is pixel
    ``pix0`` (column ``x0`` of ``electrons_row``) from its initial accumulator
    ``frac`` (64 lanes, units of 2⁻⁶⁴ θ): ``D = E·(1 − frac·2⁻⁶⁴)``, cycle 0,
    its wait, no charge loss pending."""
    for lane in range(BLOCK):
        e = electrons_row[x0 + lane]
        d = e * (1.0 - np.float64(frac[lane]) * 2.0**-64)
        ev[NEED, lane] = d
        ev[CYCLE, lane] = 0.0
        ev[AFTER_RESET, lane] = 0.0
        ev[WAIT, lane] = cycle_wait(d, key_wait, np.uint64(0), pix0 + np.uint64(lane))
