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
``STREAM_WAIT`` for the Gamma variate of cycle ``c`` and the jitter at its
start (both from one 64-bit draw word, :func:`gamma_integer`),
``STREAM_RESIDUAL`` for its second Gamma or residual count, and
``STREAM_REFILL`` for a wait drawn from a readout's end after a modulo drop:
``readout_key(lane_key(key, pixel), c)``, the pixel's own key for the source
(:func:`lane_key`, made once per block) and one hash per draw word, so
chunking and thread count cannot change a bit.  Charge
loss at reset (``reset_charge_loss`` f): the readout after a firing
contributes ``(1 − f)·λ_n`` (binomial thinning of a Poisson count is
Poisson).

A run's charge is linear in the readout on a grid (:func:`linear_charge`:
``λ_n = lam + m·dlam``, ``m`` readouts after the segment's reference, both
numbers multiples of 2⁻³² e⁻).  Runs of constant charge, and runs of changing
charge from :data:`MOVING_WALK_MIN` readouts on (:func:`event_direct`), are
walked from firing to firing (the block's lanes packed into rows that one
vectorised loop takes a firing further per round): the readout of the next crossing
is found exactly (:func:`crossing`, ``⌈wait/λ⌉``; :func:`crossing_linear`
for a changing charge; :data:`CHARGE_GRID` for why this equals the
per-readout subtraction bit for bit), so there is no work per readout at
all.  Elsewhere the work per readout is one multiply-add, two
compares and a select per pixel (vectorised over the 64 lanes), and the random
draws happen per spike: a draw depends only on the pixel's state and keys, not
on when it fires, so each lane caches its next cycle's draw
(:func:`lane_draw`: one hash, two normals, the first Marsaglia–Tsang
candidate, ahead of the firing), and the readout loop
(:func:`spikesim._simd.event_cached_run64`) takes a firing from the cache in
registers; :func:`event_settle` handles the firings it cannot take, and
:func:`fire_cycle`, the scalar definition, what the cache cannot hold.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from spikesim._poisson import LAMBDA_MAX, poisson
from spikesim._simd import (
    expand_lanes64,
    expands_natively,
    high_bits_at_least64,
    lowest_bit_index,
    popcount64,
    prefer_wide_vectors,
)
from spikesim.rng import (
    _G1,
    _S12,
    _S52,
    _bits_f64,
    _f64_bits,
    counter_input,
    float_of_52,
    log_positive,
    mix64,
    normal,
    normal_field,
    normal_field_body,
    pixel_bits,
    readout_key,
    uint_of_52,
    uniform,
)

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
_U2 = np.uint64(2)
_opts = dict(cache=True, error_model="numpy", boundscheck=False)
_inner = dict(_opts, _nrt=False)  # no reference counting of array arguments per call
# The helpers here are ordinary functions, compiled once per argument types
# (LLVM inlines the small ones where it pays).  ``inline="always"`` is kept only
# on the chain that passes the reset mode down as a constant, so that numba
# prunes the other modes' walks and refills before typing them: numba inlines
# by copying a function's IR into every call site, recursively, and with every
# helper inlined the physical family took 12 minutes to compile
# (docs/performance.md, First-run compilation).


#: Shapes up to this use the product of uniforms (cheaper than a rejection).
SMALL_SHAPE = 8
_THIRD = 1.0 / 3.0
_FIFTH = 1.0 / 5.0
_SIXTH = 1.0 / 6.0


#: One hash per cycle: the cycle's *draw word* ``W`` (64 bits) holds the
#: comparator jitter's normal in its top 26 bits (:func:`jitter_normal`), the
#: first Marsaglia–Tsang normal in the next 26 and the top 12 bits of that
#: attempt's uniform in the last 12 (:func:`gamma_integer`).  Further words
#: ``pixel_bits(W, j)`` are hashed only where a draw needs them: ``j`` = 0 the
#: jitter's tail, 1 the uniform's other bits, 2 the normal's tail, 3 and 4 the
#: second attempt, and so on; a small shape's uniforms are words 1 to ``m``.
#: Three hashes per cycle took about 1 ns per draw more (docs/model.md, Speed).
_S_JITTER = np.uint64(38)
_S_X = np.uint64(12)
_FIELD = np.uint64((1 << 26) - 1)
_U_TOP = np.uint64((1 << 12) - 1)


@njit(**_opts)
def jitter_normal(w):
    """The comparator jitter's standard normal of the cycle whose draw word is
    ``w``: :func:`spikesim.rng.normal_field` of its top 26 bits."""
    return normal_field(w >> _S_JITTER, pixel_bits(w, np.uint64(0)))


@njit(**_opts)
def uniform_above(w):
    """The least upper bound ``(k + 1)/4096`` of the first attempt's uniform,
    ``k`` the draw word's low 12 bits (the uniform itself lies strictly
    between ``k/4096`` and this): a squeeze that accepts it accepts the uniform,
    which then need not be hashed."""
    return (float_of_52(w & _U_TOP) + 1.0) * 2.0**-12


#: Marsaglia–Tsang's squeeze, ``u < 1 − SQUEEZE·c²·x⁴`` where ``t = 1 + c·x ≥ ½``.
#: With ``y = c·x``, ``9dc² = 1`` and Taylor's remainder for ``ln(1 + y)``, the
#: log test's right side is exactly ``−c²x⁴/(12(1 + ξ)⁴)`` for some ξ between 0
#: and y, at least ``−(4/3)c²x⁴`` when ``y ≥ −½``; and ``ln u ≤ u − 1``.  So the
#: squeeze only accepts what the log test accepts.  It leaves ``4c² = 4/(9d)``
#: of the candidates to the log test (0.04 % at 1000 electrons), where the
#: squeeze of the paper, ``u < 1 − 0.0331·x⁴``, leaves 10 %.
SQUEEZE = 4.0 / 3.0


@njit(**_opts)
def squeeze_accepts(u, x2, c, t):
    """The squeeze :data:`SQUEEZE`: ``t ≥ ½`` and ``u < 1 − (4/3)·c²·x⁴``
    (``x2 = x²``, ``t = 1 + c·x``); branch-free."""
    return (t >= 0.5) & (u < 1.0 - SQUEEZE * (c * c) * (x2 * x2))


@njit(**_opts)
def log_test_accepts(u, x2, v, d):
    """Marsaglia–Tsang's acceptance test, ``log u < ½x² + d·(1 − v + log v)``
    (for the candidates :func:`squeeze_accepts` did not accept)."""
    return log_positive(u) < 0.5 * x2 + d * (1.0 - v + log_positive(v))


@njit(**_opts)
def gamma_integer(m, bits):
    """Gamma(m, 1) deviate for an integer-valued shape ``m`` ≥ 1 from the
    64-bit draw word ``bits`` (its top 26 bits are left to the jitter).

    ``m`` ≤ :data:`SMALL_SHAPE`: ``−log Π_j u_j`` (a sum of ``m`` unit
    exponentials, exact), ``u_j = uniform(pixel_bits(bits, j + 1))``.  Larger:
    Marsaglia & Tsang, "A simple method for generating gamma variables", ACM
    TOMS 26(3), 2000: ``d = m − ⅓``, ``c = 1/√(9d)``, candidate
    ``d·(1 + c·x)³`` for a standard normal ``x``, accepted by the squeeze
    (:data:`SQUEEZE`, tighter than the paper's) or ``log u < ½x² + d·(1 − v + log v)``.
    The first attempt's ``x`` is :func:`spikesim.rng.normal_field` of bits
    37–12 (tail: word 2), its ``u`` the uniform of the word whose top 12 bits
    are the draw word's low 12 and whose other bits come from word 1 (hashed
    only where the squeeze does not accept ``u``'s upper bound
    :func:`uniform_above`, which then decides for ``u``); attempt
    ``j`` ≥ 1 uses ``normal(pixel_bits(bits, 2j + 1))`` and
    ``uniform(pixel_bits(bits, 2j + 2))``.  The normals are the simulator's
    (within 1.4e-4 of Φ⁻¹(u), :func:`spikesim.rng.normal`), which moves a
    variate by at most ``3c·1.4e-4`` relative (1.3e-5 at m = 1000);
    logarithms are :func:`spikesim.rng.log_positive` (absolute error < 1e-13).
    """
    if m <= SMALL_SHAPE:
        prod = 1.0
        for j in range(np.int64(m)):
            prod *= uniform(pixel_bits(bits, np.uint64(j + 1)))
        return -log_positive(prod)
    d = m - _THIRD
    # (the table holds this very value: its square root and division off the chain)
    c = _C_OF[np.int64(m)] if m < TABLE_SHAPES else 1.0 / np.sqrt(9.0 * d)
    x = normal_field((bits >> _S_X) & _FIELD, pixel_bits(bits, _U2))
    t = 1.0 + c * x
    if squeeze_accepts(uniform_above(bits), x * x, c, t):  # then u's low bits cannot matter
        return d * (t * t * t)
    u = uniform(((bits & _U_TOP) << _S52) | (pixel_bits(bits, _U1) >> _S12))
    j = np.uint64(1)
    while True:
        t = 1.0 + c * x
        if t > 0.0:
            v = t * t * t
            x2 = x * x
            if squeeze_accepts(u, x2, c, t) or log_test_accepts(u, x2, v, d):
                return d * v
        x = normal(pixel_bits(bits, j + j + _U1))
        u = uniform(pixel_bits(bits, j + j + _U2))
        j += _U1


@njit(**_opts)
def lane_key(key, pix):
    """A pixel's key for one stream: ``pixel_bits(key, pix)``.  Cycle ``c``'s
    bits are then ``readout_key(lane_key, c)``, one hash per draw (a
    SplitMix64 sequence per pixel, seeded by this key)."""
    return pixel_bits(key, pix)


@njit(**_opts)
def cycle_wait(need, lkey, counter):
    """Operational time (electrons) to the ``⌈need⌉``-th electron:
    ``Gamma(⌈need⌉, 1)`` from ``readout_key(lkey, counter)`` (``lkey`` the
    pixel's :func:`lane_key`); 0 when ``need`` ≤ 0 (the pixel fires at the
    next readout)."""
    return word_wait(need, readout_key(lkey, np.uint64(counter)))


@njit(**_opts)
def word_wait(need, word):
    """:func:`cycle_wait` from the draw word ``word`` itself: ``Gamma(⌈need⌉, 1)``
    (:func:`gamma_integer`), 0 when ``need`` ≤ 0."""
    if not need > 0.0:
        return 0.0
    return gamma_integer(np.ceil(need), word)


#: A modulo drop needs ``h0`` electrons within the operational time ``L`` left in
#: the readout after a crossing.  Chernoff's bound ``P(Poisson(L) ≥ h0) ≤
#: exp(h0·(1 − x + ln x))``, ``x = L/h0`` < 1, with ``s = 1 − x``:
#: ``1 − x + ln x = −Σ_{k≥2} s^k/k ≤ −(s²/2 + s³/3 + s⁴/4 + s⁵/5 + s⁶/6)`` (every
#: term of the series has the same sign, so a truncation bounds it).  Where
#: ``h0`` times that sum is at least ``DROP_FREE_LOG`` (> 64·ln 2 = 44.36, with
#: room for rounding) the drop has probability below 2⁻⁶⁴, smaller than any
#: probability a 64-bit draw resolves.  At 1000 e⁻ per threshold this holds for
#: ``x`` ≤ 0.73: every pixel filling less than 0.73 threshold per readout.
DROP_FREE_LOG = 44.5
#: Above this ``h0`` the rule is not evaluated (its ``h0⁶`` terms would overflow).
DROP_RULE_MAX_H0 = 1e50


@njit(**_opts)
def drop_negligible(left, h0):
    """True when a modulo drop (``h0`` electrons within operational time
    ``left`` ≥ 0) has probability below 2⁻⁶⁴, so it need not be drawn.

    The rule of :data:`DROP_FREE_LOG` times ``h0⁵`` (no division, branch-free:
    it vectorises cheaply): with ``a = h0 − L = s·h0``,
    ``a²·(h0⁴/2 + a·h0³/3 + a²·h0²/4 + a³·h0/5 + a⁴/6) ≥ DROP_FREE_LOG·h0⁵``."""
    a = h0 - left
    h2 = h0 * h0
    h3 = h2 * h0
    h4 = h3 * h0
    p = a * _SIXTH + h0 * _FIFTH
    p = p * a + h2 * 0.25
    p = p * a + h3 * _THIRD
    p = p * a + h4 * 0.5
    return ((h0 >= 1.0) & (h0 <= DROP_RULE_MAX_H0) & (a > 0.0)
            & (a * a * p >= DROP_FREE_LOG * (h4 * h0)))


#: Relative margin of :func:`drop_free_limit` over rounding (the bound it
#: implies holds with a factor ``1 + 2e-6``, rounding moves it by ~1e-15).
_LIMIT_MARGIN = 1.0 + 1e-6
#: Up to here the margin exceeds the rounding of ``h0 − left`` (an ulp of h0).
_LIMIT_MAX_H0 = 2.0**52


@njit(**_opts)
def drop_free_limit(h0):
    """An operational time ``L*`` such that every ``left`` ≤ ``L*`` passes
    :func:`drop_negligible` for this ``h0`` (−∞ outside 1 ≤ ``h0`` ≤ 2⁵², where
    the margin no longer covers the rounding of ``h0 − left``):
    ``L* = h0 − √(2·DROP_FREE_LOG·h0)·(1 + 10⁻⁶)``.  Then ``a = h0 − left`` ≥
    ``√(2·DROP_FREE_LOG·h0)``, so ``a²·h0⁴/2``, the first of the rule's
    positive terms, already reaches ``DROP_FREE_LOG·h0⁵``.  One comparison
    instead of the rule's polynomial, for the per-readout loop; it allows 0.70
    threshold per readout at 1000 e⁻ where the rule allows 0.73, and the few
    lanes between go to the rule itself."""
    limit = h0 - np.sqrt(2.0 * DROP_FREE_LOG * h0) * _LIMIT_MARGIN
    return limit if (h0 >= 1.0) & (h0 <= _LIMIT_MAX_H0) else -np.inf


#: Shapes below this are read from :data:`SHAPE_TABLES` by :func:`lane_draw`
#: (every shape of a pixel with up to 21 800 electrons per threshold, the jitter
#: clipped at +½; larger ones are drawn lane by lane by :func:`prepare_lane`:
#: measured 2.7× slower at 40 000 e⁻).
TABLE_SHAPES = 1 << 15


def shape_tables(n: int = TABLE_SHAPES) -> np.ndarray:
    """(2, n) float64 tables by integer shape ``h`` that :func:`lane_draw`
    reads instead of two square roots and a division per spike: row 0
    Marsaglia–Tsang's ``c = 1/√(9(h − ⅓))`` (0 for ``h`` ≤ :data:`SMALL_SHAPE`;
    the floating-point operations of :func:`gamma_integer`), row 1
    :func:`drop_free_limit` ``(h)``."""
    h = np.arange(n, dtype=np.float64)
    tables = np.zeros((2, n))
    big = h > SMALL_SHAPE
    tables[0, big] = 1.0 / np.sqrt(9.0 * (h[big] - _THIRD))
    tables[1] = -np.inf
    pos = h >= 1.0
    tables[1, pos] = h[pos] - np.sqrt(2.0 * DROP_FREE_LOG * h[pos]) * _LIMIT_MARGIN
    return tables


#: The tables, a compile-time constant of the kernel (so LLVM knows no store
#: aliases them, and :func:`first_waits`' loop vectorises with their gathers).
SHAPE_TABLES = shape_tables()
_C_OF = SHAPE_TABLES[0].copy()
_LIMIT_OF = SHAPE_TABLES[1].copy()


@njit(**_opts)
def _next_threshold(need, word, e, reset, jitter):
    """The threshold of the next cycle (:func:`fire_cycle`; ``word`` its draw
    word): ``(lead, eps, d, hd)``, the threshold's place relative to the
    crossing electron ``lead = need − ⌈need⌉``, the jitter ``ε``
    (:func:`jitter_normal`), the electrons ``d`` to the next threshold (from
    the crossing; zero reset: from the readout's end) and the shape
    ``hd = ⌈d⌉`` of its wait (0 where ``d`` ≤ 0)."""
    eps = 0.0
    if jitter > 0.0:
        z = jitter_normal(word)
        eps = min(max(jitter * z, -0.5), 0.5)
    lead, d, hd = _threshold_at(need, e, eps, reset)
    return lead, eps, d, hd


@njit(**_opts)
def _threshold_at(need, e, eps, reset):
    """``(lead, d, hd)`` of :func:`_next_threshold` for the jitter ``eps``
    (branch-free: the vector draw shares it)."""
    m = np.ceil(need) if need > 0.0 else 0.0
    lead = need - m
    d = e + e * eps if reset == ZERO else (lead + e) + e * eps
    hd = np.ceil(d) if d > 0.0 else 0.0
    return lead, d, hd


@njit(**_opts)
def lowest_wait(g, limit):
    """The lowest wait at a modulo firing for which ``wait + g`` (``g`` > 0) is
    the new wait: ``−wait`` within the drop-free ``limit`` and ``wait + g >
    0``, i.e. ``wait`` at least the next float above ``−g``."""
    return max(-limit, _bits_f64(_f64_bits(-g) - _U1))


@njit(**_opts)
def fire_cycle(wait, need, cycle, e, reset, jitter, lk_wait, key_resid, key_refill, pix):
    """End cycle ``cycle``, whose crossing (the ``m = ⌈need⌉``-th electron)
    came ``−wait`` ≥ 0 of operational time before the end of this readout;
    returns the next cycle's ``(wait, need, cycle)``.

    ``lead = need − m`` ∈ (−1, 0] places the threshold relative to the
    crossing electron; the comparator jitter ``ε`` (:func:`jitter_normal`
    of the next cycle's draw word) moves the next threshold by ``E·ε``.
    The electrons after the crossing are a Poisson process, so (counter
    ``cycle + 1`` for the draws; ``lk_wait`` the pixel's wait key, and the
    residual and refill keys made per pixel only when those rare draws happen):

    * zero reset discards them: the next cycle needs ``E(1 + ε)`` electrons
      from the readout's end;
    * subtract: the next threshold is ``d = lead + E + E·ε`` electrons after
      the crossing, whose arrival is ``Gamma(⌈d⌉)`` after it;
      the wait may stay ≤ 0 (the backlog fires at the next readouts);
    * modulo drops a whole threshold when the charge at the readout's end is
      ≥ 2θ, i.e. ≥ ``h0 = ⌈lead + E⌉`` electrons came after the crossing in
      this readout.  Where that has probability below 2⁻⁶⁴
      (:func:`drop_negligible`: the usual case), the next crossing is drawn at
      once as for subtract.  Else the arrival of electron
      ``h = min(h0, ⌈d⌉)`` is drawn; after the readout's end,
      nothing was dropped and the next crossing is that arrival plus
      ``Gamma(⌈d⌉ − h)`` (residual key);
      else the count at the readout's end is ``h + Poisson(rest)``
      (residual key), the charge ``1 + x/E`` with ``x = h + Poisson − lead``
      is reset to ``x mod E`` exactly, and the next wait is drawn from the
      readout's end (refill key).

    :func:`lane_draw` and :func:`prepare_lane` draw
    the common cases of this function ahead of the firing, with the same
    arithmetic, and :func:`apply_cached` finishes them at the firing.
    """
    c1 = cycle + 1.0
    k1 = np.uint64(c1)
    word = readout_key(lk_wait, k1)  # the next cycle's draw word, hashed once
    lead, eps, d, hd = _next_threshold(need, word, e, reset, jitter)
    if reset == ZERO:
        return word_wait(hd, word), d, c1
    if reset == SUBTRACT:
        w = wait + word_wait(hd, word)
        return max(w, -BACKLOG_MAX * e), d, c1
    h0 = np.ceil(lead + e)
    # drawing the next crossing at once (one variate) is exact when no drop can happen
    h = hd if drop_negligible(-wait, h0) else min(h0, hd)
    g = word_wait(h, word)
    if wait + g > 0.0:  # fewer than h electrons after the crossing in this readout
        if hd > h:
            g += cycle_wait(hd - h, lane_key(key_resid, pix), k1)
        return wait + g, d, c1
    post = h + poisson(min(-(wait + g), LAMBDA_MAX),
                       readout_key(lane_key(key_resid, pix), k1))
    x = post - lead  # electrons beyond the threshold at the readout's end
    d2 = (e - np.fmod(x, e)) + e * eps
    return cycle_wait(d2, lane_key(key_refill, pix), k1), d2, c1


#: Rows of the event sampler's float64 work array (``EV_WORK_F``, 64): the
#: block's cache by lane (:data:`GNEXT`, :data:`DNEXT`, :data:`WMIN`: wait
#: increment, next need and the lowest wait it applies at; a lane is *ready*,
#: its cache holding its current cycle's draw, where its ``WMIN`` is below +∞),
#: then a packed refill's rows (:func:`_packed_refill`: the stale lanes' need
#: and electrons, then their draws).
GNEXT, DNEXT, WMIN, P_NEED, P_E, P_G, P_D, P_W = range(8)
#: A packed walk's rows (:func:`_packed_walk`): each row's wait, need,
#: electrons, charge at the run's first readout, its change per readout and
#: the reciprocal of a constant one, readouts done, and the
#: bits of its current cycle (jitter, normal, uniform).
W_WAIT, W_NEED, W_E, W_LAM, W_DLAM, W_INV, W_DONE, W_EPS, W_X, W_U = range(8, 18)
EV_WORK_F = 18
#: Rows of its uint64 work array (``EV_WORK_U``, 64): the block's wait lane
#: keys, :func:`first_waits`' scratch, the cache's mask (row
#: :data:`MASKS`, word :data:`FRESH`), then a packed refill's rows (the input
#: of each stale lane's draw-word hash, then the word and whether its draw
#: holds).
LKW, OK, MASKS, P_SEQ, P_OK = range(5)
#: A packed walk's rows: each row's cycle ``c``, the input of its draw word's
#: hash ``counter_input(kw, c + 1)`` (``readout_key`` before the mix: the
#: next cycle's is one addition of ``G1`` away), its normals' tail flag, its
#: lane, its status in the round, and the spike word and bit of its firing in
#: the round (bit 0 where it did not fire).
W_CYCLE, W_SEQ, W_TAIL, W_LANE, W_STATUS, W_WORD, W_BIT = range(5, 12)
EV_WORK_U = 12
#: Word of row :data:`MASKS`: the lanes whose cache was made for their current
#: cycle, ready or not (the others are *stale*).
FRESH = 0


@njit(**_opts)
def lane_draw(need, k, e, kw, reset, jittered, jitter):
    """The common case of :func:`fire_cycle` that does not depend on the wait,
    for one lane in cycle ``k`` (a uint64 counter; ``kw`` its wait lane key):
    ``(g, d, wmin, ok)``, the first Marsaglia–Tsang
    candidate ``g`` of ``Gamma(⌈d⌉)``, the next need ``d`` and the lowest wait
    at the firing for which ``g`` gives the new wait (−∞ for subtract and zero;
    modulo: ``−wait`` within :func:`drop_free_limit` and ``wait + g > 0``,
    i.e. ``wait`` above ``−g``, whose next float up it takes).  ``ok`` says
    that ``g`` is the cycle's draw (shape above :data:`SMALL_SHAPE` and below
    :data:`TABLE_SHAPES`, both normals in the body table, accepted by the
    squeeze: 98.4 % of the spikes at 1000 e⁻ per threshold); else
    :func:`prepare_lane` draws it.  At the firing, ``wait + g`` (modulo and
    subtract, clamped) or ``g`` (zero) is then :func:`fire_cycle`'s new wait
    where ``wait`` ≥ ``wmin``, bit for bit (:func:`apply_cached`).

    Branch-free, so a loop of it over contiguous rows vectorises
    (:func:`_packed_refill`).  It is :func:`lane_finish` of
    :func:`lane_bits`, which the walk (:func:`_walk_lane`) calls one firing
    apart."""
    eps, x, u, tail = lane_bits(k, kw, jittered, jitter)
    return lane_finish(need, e, eps, x, u, tail, reset)


@njit(**_opts)
def lane_bits(k, kw, jittered, jitter):
    """The part of :func:`lane_draw` that depends on the cycle ``k`` and the
    key alone, from one hash (the draw word ``readout_key(kw, k + 1)``):
    ``(eps, x, u, tail)``, the clipped jitter ``ε`` (0 unless ``jittered``),
    the Marsaglia–Tsang normal ``x`` and the uniform's upper bound ``u``
    (:func:`uniform_above`) of :func:`_gamma_candidate`, and whether either
    normal fell in a tail bin.  The walk draws these for a lane's next cycle
    while it finishes the current one, so the two chains of latencies overlap
    (a static walk measured 10 % faster)."""
    return word_bits(readout_key(kw, k + _U1), jittered, jitter)


@njit(**_opts)
def word_bits(w, jittered, jitter):
    """:func:`lane_bits` from the cycle's draw word ``w`` itself."""
    eps = 0.0
    z_tail = False
    if jittered:
        z, z_tail = normal_field_body(w >> _S_JITTER)
        eps = min(max(jitter * z, -0.5), 0.5)
    x, x_tail = normal_field_body((w >> _S_X) & _FIELD)
    return eps, x, uniform_above(w), z_tail | x_tail


@njit(**_opts)
def lane_finish(need, e, eps, x, u, tail, reset):
    """The rest of :func:`lane_draw` from :func:`lane_bits`: ``(g, d, wmin, ok)``.
    (A variant of the walk that skipped the drop-free limit's table read
    where every lane's charge allowed it measured only 1.07–1.09× faster,
    500×500 physical runs, AMD EPYC host: not worth its compile time.)"""
    top = np.float64(TABLE_SHAPES - 1)
    lead, d, hd = _threshold_at(need, e, eps, reset)
    g, accepted = _candidate_of(hd, x, u)
    if reset == MODULO:
        h0 = np.ceil(lead + e)
        limit = _LIMIT_OF[uint_of_52(min(h0, top))]  # (read unconditionally: branch-free)
        wmin = lowest_wait(g, limit if h0 <= top else -np.inf)  # (g > 0 where OK)
    else:
        wmin = -np.inf
    return g, d, wmin, accepted & (not tail)


@njit(**_opts)
def _gamma_candidate(h, bits):
    """:func:`gamma_integer`'s first candidate for the integer shape ``h`` from
    the draw word ``bits``, branch-free for the vector draws: ``(g, accepted)``,
    where ``accepted`` says ``g`` is :func:`gamma_integer`'s result bit for bit
    (shape above :data:`SMALL_SHAPE` and within the tables, the normal in the
    body table, accepted by the squeeze at the uniform's upper bound
    :func:`uniform_above`); elsewhere the scalar draw decides."""
    x, x_tail = normal_field_body((bits >> _S_X) & _FIELD)
    g, accepted = _candidate_of(h, x, uniform_above(bits))
    return g, accepted & (not x_tail)


@njit(**_opts)
def _candidate_of(h, x, u):
    """:func:`_gamma_candidate` from its normal ``x`` (body table) and the
    uniform's upper bound ``u``: ``(g, accepted)``, ``accepted`` before the
    normal's tail flag."""
    top = np.float64(TABLE_SHAPES - 1)
    c = _C_OF[uint_of_52(min(h, top))]  # 1/√(9(h − ⅓)), read
    t = 1.0 + c * x
    g = (h - _THIRD) * (t * t * t)
    return g, (h > SMALL_SHAPE) & (h <= top) & squeeze_accepts(u, x * x, c, t)


@njit(**_opts)
def prepare_lane(need, cycle, e, reset, jitter, lk_wait):
    """The draw of :func:`lane_draw` for the lanes
    it leaves (normals in the tails, small shapes, the log test, shapes beyond
    the tables): ``(g, d, wmin)`` from :func:`fire_cycle`'s own operations
    (the exact normal, :func:`cycle_wait`), the cycle's draw wherever ``wait``
    ≥ ``wmin`` at the firing (modulo: −∞ limit where
    :func:`drop_free_limit` has none, then ``wmin`` = +∞)."""
    word = readout_key(lk_wait, np.uint64(cycle + 1.0))
    lead, _, d, hd = _next_threshold(need, word, e, reset, jitter)
    g = word_wait(hd, word)
    if reset != MODULO:
        return g, d, -np.inf
    if not g > 0.0:  # (a shape of 0) lowest_wait needs g > 0
        return g, d, np.inf
    return g, d, lowest_wait(g, drop_free_limit(np.ceil(lead + e)))


@njit(**_opts)
def apply_cached(wait, g, wmin, e, reset):
    """``(new wait, valid)`` of a firing whose cycle's draw ``g`` and lowest
    wait ``wmin`` the cache holds (:func:`lane_draw`), ``wait`` ≤ 0 the
    wait at the firing: :func:`fire_cycle`'s result where ``valid`` (modulo:
    no drop can happen and the next crossing lies beyond this readout; else
    :func:`fire_cycle` decides).  :func:`spikesim._simd.event_cached_run64`
    does the same on vectors."""
    valid = wait >= wmin
    if reset == ZERO:
        return g, valid
    return max(wait + g, -BACKLOG_MAX * e), valid


@njit(**_opts)
def event_cache_clear(wf, wu, lanes):
    """Empty the block's cache at the start of its chunk: its first ``lanes``
    lanes stale, the padding lanes beyond the row (which never fire) fresh, so
    that no refill draws for them."""
    wmin = wf[WMIN]
    for lane in range(BLOCK):
        wmin[lane] = np.inf
    wu[MASKS, FRESH] = ~np.uint64(0) if lanes <= 0 else (
        np.uint64(0) if lanes >= BLOCK else ~((_U1 << np.uint64(lanes)) - _U1))


@njit(**_opts)
def event_sync(used, ev, wf, wu):
    """Finish the firings :func:`spikesim._simd.event_cached_run64` took from
    the cache (lanes ``used``; it set their waits and spent their ``WMIN``):
    next need, next cycle, stale, lane by lane (a few lanes a call).  With
    the block's rows 32 bytes off a cache line, whole-row vector merges here
    held 10 % of a moving run's profile samples on one load, waiting for the
    refill's stores; with aligned rows the two forms measured the same."""
    need, cycle, dnext = ev[NEED], ev[CYCLE], wf[DNEXT]
    m = used
    while m != 0:
        lane = lowest_bit_index(m)
        m &= m - _U1
        need[lane] = dnext[lane]
        cycle[lane] += 1.0
    wu[MASKS, FRESH] &= ~used


@njit(inline="always", **_opts)
def event_refill(electrons, ev, reset, jitter, wf, wu):
    """Fill the cache of every stale lane (:func:`lane_draw`, or
    :func:`prepare_lane` where it leaves the draw; packed on vectors from
    :data:`PACKED_REFILL_MIN` lanes on): a lane's draw depends only on its
    state, so drawing it before its firing changes no bit, and drawing every
    stale lane at once spares the readout loop its stops.  Always with the
    jitter's bits, as the walks (with no jitter they give a jitter of ±0, the
    same threshold): one variant to compile per reset mode."""
    _refill_lanes(reset, True, ~wu[MASKS, FRESH], electrons, ev, jitter, wf, wu)
    wu[MASKS, FRESH] = ~np.uint64(0)


@njit(inline="always", **_opts)
def _refill_lanes(reset, jittered, stale, electrons, ev, jitter, wf, wu):
    """:func:`event_refill` for one reset mode and jitter switch: constants at
    each call, so the branches on them fold away (a moving physical run took
    5 % longer with them as run-time values; :func:`event_direct`'s walk did
    not).  From :data:`PACKED_REFILL_MIN` stale lanes on they are drawn on
    vectors (:func:`_packed_refill`), fewer one by one."""
    if popcount64(stale) >= PACKED_REFILL_MIN:
        _packed_refill(reset, stale, electrons, ev, jitter, wf, wu)
        return
    need, cycle = ev[NEED], ev[CYCLE]
    m = stale
    while m != 0:
        lane = lowest_bit_index(m)
        m &= m - _U1
        g, d, wmin, ok = lane_draw(need[lane], np.uint64(cycle[lane]), electrons[lane],
                                   wu[LKW, lane], reset, jittered, jitter)
        if ok:
            wf[GNEXT, lane] = g
            wf[DNEXT, lane] = d
            wf[WMIN, lane] = wmin
        else:  # (1.6 % at 1000 e⁻: a normal's tail) the same draw, exactly
            _prepare_lane_into(lane, electrons, ev, reset, jitter, wf, wu)


#: Stale lanes from which a refill packs them into rows and draws them on
#: vectors.  Per lane (cache-resident, one thread, AMD EPYC host, 256-bit
#: vectors, median [range] of 5): 17.2 [17.2–17.4] ns packed against 21.6
#: [21.3–21.7] one by one at 30 stale lanes, 20.5 [20.5–20.7] against 22.0
#: [22.0–22.0] at 16.  On an Intel Xeon host (AVX-512), with the packed draw
#: in three loops: 19.1–19.4 against 20.5–21.4 ns at 8 lanes, 24.7–26.6
#: against 20.8–24.1 at 6 (medians of 7 in two processes).
PACKED_REFILL_MIN = 8
#: The packed rows are drawn in whole groups of this many (the padding copies
#: the first stale lane), so that no lane falls to the vector loop's scalar
#: remainder: one 512-bit vector of float64 (two 256-bit ones).  With groups
#: of 4, an AVX-512 host's 8-lane loop left up to 4 lanes of a refill to that
#: remainder: 13 % of a moving run's profile samples (500×500, one thread)
#: were its scalar arithmetic.
_PACK_GROUP = 8
#: At least this many rows are drawn: LLVM enters the vector form of the
#: draw's loops from 16 iterations on (it interleaves two vectors), so 8 rows
#: ran scalar (24.8 ns a lane against 18.7 padded to 16, a copy of the
#: refill, AVX-512 host).
_PACK_ROWS_MIN = 16
_TWO52 = 2.0**52


def _make_packed_refill(reset, jittered):
    """:func:`_packed_refill` compiled for one reset mode and jitter switch."""

    @njit(**_inner)
    def packed_refill(stale, electrons, ev, jitter, wf, wu):
        prefer_wide_vectors()
        need, cycle, kw = ev[NEED], ev[CYCLE], wu[LKW]
        pn, pe, seq = wf[P_NEED], wf[P_E], wu[P_SEQ]
        n = 0
        beyond = False  # a cycle count at or past 2⁵², where uint_of_52 is inexact
        m = stale
        while m != 0:
            lane = lowest_bit_index(m)
            m &= m - _U1
            c = cycle[lane]
            beyond |= c >= _TWO52
            pn[n] = need[lane]
            pe[n] = electrons[lane]
            seq[n] = counter_input(kw[lane], uint_of_52(c) + _U1)
            n += 1
        padded = max((n + _PACK_GROUP - 1) // _PACK_GROUP * _PACK_GROUP, _PACK_ROWS_MIN)
        for i in range(n, padded):
            pn[i] = pn[0]
            pe[i] = pe[0]
            seq[i] = seq[0]
        pg, pd, pw, pok = wf[P_G], wf[P_D], wf[P_W], wu[P_OK]
        # three loops over contiguous rows, each of which vectorises: the
        # draw words, their bits, the draws (split, each loop's chain of
        # latencies is short enough for more of its iterations to overlap)
        for i in range(padded):
            pok[i] = mix64(seq[i])
        for i in range(padded):
            eps, x, u, tail = word_bits(pok[i], jittered, jitter)
            pg[i] = eps
            pd[i] = x
            pw[i] = u
            pok[i] = np.uint64(tail)
        for i in range(padded):
            g, d, wmin, ok = lane_finish(pn[i], pe[i], pg[i], pd[i], pw[i], pok[i] != 0, reset)
            pg[i] = g
            pd[i] = d
            pw[i] = wmin
            pok[i] = np.uint64(ok & (not beyond))
        gnext, dnext, wmin = wf[GNEXT], wf[DNEXT], wf[WMIN]
        native = expands_natively()
        if native:
            expand_lanes64(stale, pg, gnext)  # back by lane, as whole vectors
            expand_lanes64(stale, pd, dnext)
            expand_lanes64(stale, pw, wmin)
        i = 0
        m = stale
        while m != 0:  # (in the packing's order)
            lane = lowest_bit_index(m)
            m &= m - _U1
            if pok[i] == 0:
                _prepare_lane_into(lane, electrons, ev, reset, jitter, wf, wu)
            elif not native:  # back lane by lane
                gnext[lane] = pg[i]
                dnext[lane] = pd[i]
                wmin[lane] = pw[i]
            i += 1

    return packed_refill


_PACKED_M, _PACKED_S, _PACKED_Z = (_make_packed_refill(reset, True)
                                   for reset in (MODULO, SUBTRACT, ZERO))


@njit(inline="always", **_opts)
def _packed_refill(reset, stale, electrons, ev, jitter, wf, wu):
    """:func:`_refill_lanes` on vectors: the stale lanes' need, electrons and
    draw-word hash input (:func:`spikesim.rng.counter_input`) packed into
    contiguous rows (rows ``P_*`` of the work arrays), :func:`lane_draw` over
    them in three loops that LLVM vectorises (the hash, :func:`word_bits`,
    :func:`lane_finish`), the draws put back by lane
    (:func:`spikesim._simd.expand_lanes64` with AVX-512; elsewhere lane by
    lane in the last pass, :func:`spikesim._simd.expands_natively`), and
    :func:`prepare_lane` for the lanes it leaves (all of them where a cycle
    count has reached 2⁵²); the same bits.  Against one loop that packed
    each lane's cycle and key (and its row's lane), drew in one pass and
    put back lane by lane, per lane: 1.25–1.28× faster at 30 stale lanes,
    1.37–1.43× at 64, 1.05–1.10× at 16, 0.83–0.91× at 8 (medians of 7
    alternating repeats in each of three processes,
    ``benchmarks/bench_refill.py``'s set-up on aligned rows, AVX-512
    host).  A function of
    its own, not inlined into the block function: inlined there, a packed
    refill measured at most a few per cent faster than drawing lane by lane
    (docs/model.md, Speed)."""
    if reset == MODULO:
        _PACKED_M(stale, electrons, ev, jitter, wf, wu)
    elif reset == SUBTRACT:
        _PACKED_S(stale, electrons, ev, jitter, wf, wu)
    else:
        _PACKED_Z(stale, electrons, ev, jitter, wf, wu)


@njit(**_opts)
def _prepare_lane_into(lane, electrons, ev, reset, jitter, wf, wu):
    """:func:`prepare_lane` for one lane of the block, into its cache."""
    g, d, wmin = prepare_lane(ev[NEED, lane], ev[CYCLE, lane], electrons[lane], reset, jitter,
                              wu[LKW, lane])
    wf[GNEXT, lane] = g
    wf[DNEXT, lane] = d
    wf[WMIN, lane] = wmin


@njit(inline="always", **_opts)
def event_settle(mask, electrons, ev, reset, jitter, keys, pix0, wf, wu):
    """End the cycle of every lane of ``mask`` (non-zero) after a readout, the
    waits at the firing in ``ev``: stale lanes get their cache filled
    (:func:`event_refill`), a ready lane takes its draw where
    :func:`apply_cached` allows, :func:`fire_cycle` does the rest; their cache
    is spent.  ``reset`` must be a constant: each reset mode's is a function
    of its own (compiled once, however many places call it)."""
    if reset == MODULO:
        _SETTLE_MODULO(mask, electrons, ev, jitter, keys, pix0, wf, wu)
    elif reset == SUBTRACT:
        _SETTLE_SUBTRACT(mask, electrons, ev, jitter, keys, pix0, wf, wu)
    else:
        _SETTLE_ZERO(mask, electrons, ev, jitter, keys, pix0, wf, wu)


def _make_settle(reset):
    """:func:`event_settle` compiled for one reset mode."""

    @njit(**_inner)
    def settle(mask, electrons, ev, jitter, keys, pix0, wf, wu):
        _settle_lanes(mask, electrons, ev, reset, jitter, keys, pix0, wf, wu)

    return settle


@njit(inline="always", **_opts)
def _settle_lanes(mask, electrons, ev, reset, jitter, keys, pix0, wf, wu):
    """:func:`event_settle`'s work (``reset`` a constant)."""
    if mask & ~wu[MASKS, FRESH] != 0:
        event_refill(electrons, ev, reset, jitter, wf, wu)
    wait = ev[WAIT]
    m = mask
    while m != 0:
        lane = lowest_bit_index(m)
        m &= m - _U1
        nw, valid = apply_cached(wait[lane], wf[GNEXT, lane], wf[WMIN, lane],
                                 electrons[lane], reset)  # (never valid unless ready)
        if valid:
            wait[lane] = nw
            ev[NEED, lane] = wf[DNEXT, lane]
            ev[CYCLE, lane] += 1.0
        else:
            _fire_lane(np.int64(lane), electrons, ev, reset, jitter, keys, pix0, wu)
        wf[WMIN, lane] = np.inf
    wu[MASKS, FRESH] &= ~mask


_SETTLE_MODULO, _SETTLE_SUBTRACT, _SETTLE_ZERO = (_make_settle(r) for r in (MODULO, SUBTRACT,
                                                                               ZERO))


@njit(inline="always", **_opts)
def event_step(level, gain, offset, electrons, ev, reset, jitter, loss, keys, pix0, wf, wu):
    """One readout of the event-driven model for a 64-lane block; returns the
    spike mask.  ``level`` holds each lane's mean radiance of the readout;
    ``ev`` (4, 64) the block's state (rows :data:`WAIT`, :data:`NEED`,
    :data:`CYCLE`, :data:`AFTER_RESET`), updated in place; ``keys`` the
    stream keys (wait, residual, refill, jitter); ``wf``, ``wu`` the work
    arrays and cache (:func:`event_settle`).  The loop over every lane is
    branch-free, so it vectorises.  Padding lanes have zero gain and offset,
    so they never fire.  (Runs without charge loss take
    :func:`spikesim._simd.event_cached_run64` instead, the same arithmetic.)"""
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
    if mask != 0:
        event_settle(mask, electrons, ev, reset, jitter, keys, pix0, wf, wu)
    return mask


@njit(**_opts)
def _fire_lane(lane, electrons, ev, reset, jitter, keys, pix0, wu):
    """:func:`fire_cycle` for lane ``lane`` (int64) of the block, its state
    updated in place.  (Every call passes the same argument types, so it is
    compiled once.)"""
    wait = ev[WAIT]
    w, d, c = fire_cycle(wait[lane], ev[NEED, lane], ev[CYCLE, lane], electrons[lane], reset,
                         jitter, wu[LKW, lane], keys[1], keys[2], pix0 + np.uint64(lane))
    wait[lane] = w
    ev[NEED, lane] = d
    ev[CYCLE, lane] = c


@njit(**_opts)
def event_lane_keys(keys, pix0, wu):
    """The block's wait lane keys (:func:`lane_key` of ``keys[0]``) for pixels
    ``pix0 + lane``, into row :data:`LKW`."""
    for lane in range(BLOCK):
        wu[LKW, lane] = lane_key(keys[0], pix0 + np.uint64(lane))


@njit(**_opts)
def init_event_block(ev, frac, electrons_row, x0, wu):
    """Event state ``ev`` (4, 64) of the block whose first lane is column
    ``x0`` of ``electrons_row``, from its initial accumulator ``frac`` (64
    lanes, units of 2⁻⁶⁴ θ) and its wait lane keys (row :data:`LKW` of ``wu``):
    ``D = E·(1 − frac·2⁻⁶⁴)``, cycle 0, its wait (:func:`first_waits`), no
    charge loss pending."""
    for lane in range(BLOCK):
        e = electrons_row[x0 + lane]
        ev[NEED, lane] = e * (1.0 - np.float64(frac[lane]) * 2.0**-64)
        ev[CYCLE, lane] = 0.0
        ev[AFTER_RESET, lane] = 0.0
    first_waits(ev, wu)


@njit(**_inner)
def first_waits(ev, wu):
    """The first wait of every lane, ``cycle_wait(need, lane key, 0)``, into row
    :data:`WAIT` of ``ev``: the first Marsaglia–Tsang candidate on 512-bit
    vectors with :func:`lane_draw`'s operations (the same bits as
    :func:`gamma_integer`), then :func:`cycle_wait` itself, in scalar code, for
    the lanes the vectors leave (the normal's tail, small shapes, shapes beyond
    the table, the log test).  Row :data:`OK` of ``wu`` is scratch.  A fresh
    run draws these for every pixel; in scalar code they took a third of a
    1-readout physical-mode call (13.5 ms → 8.9 ms at 1000 × 1000)."""
    prefer_wide_vectors()
    need, wait, key, ok = ev[NEED], ev[WAIT], wu[LKW], wu[OK]
    for lane in range(BLOCK):
        m = np.ceil(need[lane]) if need[lane] > 0.0 else 0.0
        g, accepted = _gamma_candidate(m, readout_key(key[lane], np.uint64(0)))
        wait[lane] = g
        ok[lane] = np.uint64(accepted)
    left = high_bits_at_least64(ok, 0, 1, 1)  # (OK = 0)
    while left != 0:
        lane = lowest_bit_index(left)
        left &= left - _U1
        wait[lane] = cycle_wait(need[lane], key[lane], np.uint64(0))


#: The grid of a run's charge ``λ`` (electrons per readout):
#: :func:`linear_charge` rounds ``λ`` at the segment's reference readout and its
#: change per readout to multiples of 2⁻³² e⁻ (at most 1.2e-10 e⁻ each; after
#: ``m`` readouts the charge is within ``(1 + m)·1.2e-10`` e⁻ of the exact
#: line), so every charge of a run is a multiple of 2⁻³², and so is every sum
#: ``S_j`` of ``j`` of them, exactly, below 2²¹ e⁻.  A wait ``w`` below
#: :data:`EXACT_WAIT` (2²⁰ e⁻) is a multiple of its own ulp ≤ 2⁻³², so every
#: ``w − S_j`` between ``w`` and the first one ≤ 0 is a multiple of that ulp no
#: larger than ``w`` in magnitude: representable, so each subtraction of the
#: per-readout loop is exact, and the last one is the single rounding of
#: ``w − S_j``.  Hence ``w − S_j``, computed at once (``S_j = j·λ`` on a
#: constant run, :func:`charge_sum` on a changing one), is bit for bit what
#: ``j`` subtractions give, whatever the chunks.
CHARGE_GRID = 2.0**-32
_GRID_INV = 2.0**32
EXACT_WAIT = 2.0**20
EXACT_CHARGE = 2.0**18


@njit(**_opts)
def on_grid(lam):
    """``lam`` rounded to a multiple of :data:`CHARGE_GRID` (half up); values
    beyond 2²¹ already are (their ulp is coarser) and come back unchanged."""
    return np.floor(lam * _GRID_INV + 0.5) * CHARGE_GRID


#: Largest change of charge per readout (e⁻) :func:`linear_charge` holds; a
#: steeper one (a ramp of more than 2⁶² e⁻ a readout, or an overflow) leaves the
#: run to the per-readout step, which evaluates the radiance at each readout.
DLAM_MAX = 2.0**62


@njit(**_opts)
def linear_charge(t_a, inv, level, slope, gain, offset, electrons, lam, dlam):
    """Each lane's electrons per readout on a run of linear radiance (mean
    radiance ``level + slope·phi`` at readout ``n``, ``phi = (n + ½ − t_a)·inv``),
    on :data:`CHARGE_GRID`: ``lam[l]`` at the segment's reference readout
    ``⌊t_a⌋``, ``(gain·(level + slope·phi) + offset)·E`` rounded (not capped:
    :func:`charge_at` caps each readout's charge, so a ramp from beyond the cap
    comes down where the exact line does), and ``dlam[l]`` its change per
    readout, ``gain·slope·inv·E`` rounded (0 where ``slope`` is).  Readout ``n``
    then collects :func:`charge_at` ``(lam, dlam, n − ⌊t_a⌋)``: both numbers
    depend on the segment only, never on the chunk, and on a run where that
    stays within :data:`EXACT_CHARGE` every sum of them is exact
    (:func:`crossing_linear`).  Returns False where some ``|dlam|`` exceeds
    :data:`DLAM_MAX` (or is not a number): then the form does not hold."""
    phi = (np.floor(t_a) + 0.5 - t_a) * inv
    bad = 0
    for lane in range(BLOCK):
        g = gain[lane]
        e = electrons[lane]
        lam[lane] = on_grid((g * (level[lane] + slope[lane] * phi) + offset[lane]) * e)
        d = on_grid(((g * slope[lane]) * inv) * e)
        dlam[lane] = d
        bad += 0 if (d <= DLAM_MAX) & (d >= -DLAM_MAX) else 1
    return bad == 0


#: Shortest run of changing charge that :func:`event_direct` walks: shorter ones
#: take the readout loop (:func:`spikesim._simd.event_cached_run64`), whose
#: work per readout costs less there than each pixel's set-up and last
#: crossing per run.  On the benchmark's moving scene (500×500 RGGB, physical
#: defaults, one thread, AMD EPYC host) the loop was 3 % faster with a key
#: frame every 64 readouts, the walk 3 % faster every 128 and 4 % every 256.
MOVING_WALK_MIN = 128
#: Longest run of changing charge walked: ``k(k − 1)/2`` of :func:`charge_sum`
#: is exact in float64 below it.
WALK_MAX = 2**26


@njit(**_opts)
def walkable(lam, dlam, m0, count, lam_first):
    """Whether :func:`event_direct` can walk a run of ``count`` ≥ 1 readouts from
    the one ``m0`` readouts after its segment's reference (``lam``, ``dlam``:
    :func:`linear_charge`): ``(walk, moving)``, ``walk`` where every lane's
    charge at both ends of the run is within [0, :data:`EXACT_CHARGE`] and
    ``lam`` within :data:`EXACT_WAIT`, and a changing charge's run shorter
    than :data:`WALK_MAX` (so, the charge being linear, every
    charge of the run and every product ``m·dlam`` is exact on the grid and
    :func:`charge_at` adds nothing to it: its cap lies far above), ``moving``
    where some ``dlam`` is non-zero.  ``lam_first`` takes each lane's charge
    at the run's first readout, capped at ``LAMBDA_MAX`` (what a run of
    constant charge subtracts).  Branch-free counts: the loop vectorises."""
    m_last = np.float64(m0 + count - 1)
    m_first = np.float64(m0)
    ok = 0
    moving = 0
    for lane in range(BLOCK):
        ref = lam[lane]
        d = dlam[lane]
        first = ref + m_first * d
        last = ref + m_last * d
        lam_first[lane] = first if first < LAMBDA_MAX else LAMBDA_MAX
        moving += 0 if d == 0.0 else 1
        ok += 1 if ((ref <= EXACT_WAIT) & (first >= 0.0) & (first <= EXACT_CHARGE)
                    & (last >= 0.0) & (last <= EXACT_CHARGE)
                    & ((d == 0.0) | (count < WALK_MAX))) else 0
    return ok == BLOCK, moving != 0


@njit(**_opts)
def charge_at(lam, dlam, m, lam_max):
    """Electrons of readout ``m`` readouts after the segment's reference
    (:func:`linear_charge`): ``min(lam + m·dlam, lam_max)``, float64, in this
    order (:func:`spikesim._simd.event_cached_run64`'s operations)."""
    x = lam + m * dlam
    return lam_max if lam_max < x else x


@njit(**_opts)
def crossing(w, lam, inv_lam, left):
    """The readouts to the next firing of a lane with wait ``w`` (0 < ``w`` <
    :data:`EXACT_WAIT`) on a constant charge ``lam`` (on :data:`CHARGE_GRID`,
    at most :data:`EXACT_CHARGE`; ``inv_lam`` = 1/lam, +∞ for 0): the least
    ``k`` ≥ 1 with ``k·lam ≥ w``, i.e. the first readout at whose end the
    per-readout loop's wait ``w − k·lam`` is ≤ 0, or ``left + 1`` when that
    is beyond the ``left`` readouts still to go.  The estimate ``⌈w/lam⌉``
    is off by at most one where it matters (``k`` ≤ ``left + 2`` < 2⁵⁰);
    the exact products (:data:`CHARGE_GRID`) correct it.  Float64 ``k``."""
    k = np.ceil(w * inv_lam)
    if not k <= left + 2.0:
        return left + 1.0
    if k > 1.0 and (k - 1.0) * lam >= w:
        k -= 1.0
    elif k * lam < w:
        k += 1.0
    return k if k <= left else left + 1.0


#: A moving lane (``dlam`` ≠ 0) is walked from firing to firing while its wait
#: is below this: every partial sum :func:`crossing_linear` needs is then below
#: 2²¹ e⁻ (``k·lam`` is at most twice the sum of a run whose charge stays ≥ 0),
#: so exact on :data:`CHARGE_GRID`; a larger wait is stepped readout by readout.
LINEAR_WAIT = 2.0**19


@njit(**_opts)
def charge_sum(k, lam, dlam):
    """Electrons of the ``k`` readouts from one collecting ``lam`` on, the
    charge growing by ``dlam`` a readout: ``k·lam + dlam·k(k−1)/2`` (``k`` a
    whole float64 below 2²⁶, so ``k(k − 1)/2`` is exact; the sum is exact on
    :data:`CHARGE_GRID` below 2²¹ e⁻)."""
    return k * lam + dlam * (k * (k - 1.0) * 0.5)


@njit(**_opts)
def crossing_linear(w, lam, dlam, inv_lam, left):
    """:func:`crossing` for a charge that changes by ``dlam`` a readout (``lam``
    that of the next readout, ``inv_lam`` = 1/lam, +∞ for 0; every charge of
    the ``left`` readouts still to go within [0, :data:`EXACT_CHARGE`],
    ``0 < w <`` :data:`LINEAR_WAIT`): the least ``k`` ≥ 1 with
    ``charge_sum(k) ≥ w``, or ``left + 1``.  The estimate is the constant
    charge's ``k₀ = w/lam`` less the first-order change,
    ``k₀ − dlam·k₀(k₀ − 1)/(2·lam)``; from there exact sums
    (:func:`charge_sum`, then one readout's charge at a time) walk to the
    crossing, no step or one where the charge changes slowly.  Where a sum is
    rounded it is far above ``w``, so each comparison is right.  The reciprocal
    is made apart from the wait, off the wait's chain of latencies: a
    quadratic's root (a square root and a division after the wait) made the
    walk slower than the readout loop."""
    k0 = w * inv_lam
    k = np.ceil(k0 - (0.5 * dlam * inv_lam) * (k0 * (k0 - 1.0)))
    if not k >= 1.0:
        k = 1.0
    if not k <= left:
        k = left
    s = charge_sum(k, lam, dlam)
    if s < w:
        step = lam + k * dlam  # the charge of the run's readout k (from 0)
        while k < left:
            s += step
            k += 1.0
            if s >= w:
                return k
            step += dlam
        return left + 1.0
    while k > 1.0:
        s -= lam + (k - 1.0) * dlam
        if s < w:
            break
        k -= 1.0
    return k


@njit(inline="always", **_opts)
def event_direct(ev, lam, dlam, electrons, reset, jitter, keys, pix0, wf, wu, words, count):
    """``count`` readouts of a run of linear charge for a block without charge
    loss (64 lanes: ``lam`` the electrons of the run's first readout, ``dlam``
    their change per readout, both on :data:`CHARGE_GRID`, every charge of the
    run within [0, :data:`EXACT_CHARGE`]), each lane from firing to firing
    (the lanes together on vectors, :func:`_packed_walk`):
    its spike words into ``words[:count]`` (bit ``l`` of ``words[k]``: lane
    ``l`` fired at the run's readout ``k``), its state ``ev`` advanced; the
    same bits as the per-readout loop (:data:`CHARGE_GRID`), with no work per
    readout.

    Per lane: a wait above the rest of the run's charge is lowered by it;
    else :func:`crossing` (constant charge) or :func:`crossing_linear` finds
    the next firing, the wait at it is ``w −`` :func:`charge_sum` (exact),
    :func:`lane_draw` the next cycle's draw and :func:`apply_cached` its
    validity; :func:`fire_cycle` what that leaves.  A wait at or above
    :data:`EXACT_WAIT` (:data:`LINEAR_WAIT` where the charge changes; only at
    an enormous threshold) is stepped readout by readout, the per-readout
    loop's own arithmetic.  The cache of the lanes that fired is spent (their
    cycles moved on)."""
    if count <= 0:
        return
    for k in range(count):
        words[k] = np.uint64(0)
    _direct_lanes(ev, lam, dlam, electrons, reset, jitter, keys, pix0, wf, wu, words, count)
    fired = np.uint64(0)
    for k in range(count):
        fired |= words[k]
    wmin = wf[WMIN]
    for lane in range(BLOCK):
        if (fired >> np.uint64(lane)) & _U1:
            wmin[lane] = np.inf
    wu[MASKS, FRESH] &= ~fired


@njit(inline="always", **_opts)
def _direct_lanes(ev, lam, dlam, electrons, reset, jitter, keys, pix0, wf, wu, words, count):
    """:func:`event_direct`'s walk (:func:`_packed_walk`)."""
    _packed_walk(ev, lam, dlam, electrons, reset, jitter, keys, pix0, wf, wu, words, count)


@njit(**_opts)
def _walk_lane(lane, ev, l0, dl, electrons, reset, jitter, keys, pix0, wu, words, fcount,
               p0=0.0):
    """One lane of :func:`_direct_lanes`,
    from the run's readout ``p0`` on (a whole float64; the lane's state in
    ``ev`` is the one at that readout).  Its wait, need and cycle stay in
    registers between its firings; the cycle as an integer (a float64 →
    uint64 conversion per draw measured 1.3 ns)."""
    wait, need, cyc = ev[WAIT], ev[NEED], ev[CYCLE]
    jittered = jitter > 0.0
    e = electrons[lane]
    w = wait[lane]
    moving = dl != 0.0
    bit = _U1 << np.uint64(lane)
    limit = LINEAR_WAIT if moving else EXACT_WAIT
    kw = wu[LKW, lane]
    nd = need[lane]
    c = np.uint64(cyc[lane])
    p = p0  # readouts of the run done
    lm = l0 + p * dl if moving else l0  # the charge of readout p
    inv_lam = 1.0 / lm if lm > 0.0 else np.inf
    eps, x, u, tail = lane_bits(c, kw, jittered, jitter)  # cycle c's bits
    while True:
        left = fcount - p
        if w <= 0.0:
            k = 1.0  # the same single subtraction as the loop's
            wfire = w - lm
        elif w < limit:
            rest = charge_sum(left, lm, dl) if moving else left * lm
            if w > rest:  # no firing in the rest of the run
                w = w - rest
                break
            if moving:
                k = crossing_linear(w, lm, dl, inv_lam, left)
                wfire = w - charge_sum(k, lm, dl)
            else:
                k = crossing(w, lm, inv_lam, left)
                wfire = w - k * lm
        else:  # the loop's own subtractions
            k = 0.0
            while k < left and w > 0.0:
                w = w - (l0 + (p + k) * dl)
                k += 1.0
            if w > 0.0:
                break
            wfire = w
        words[np.int64(p + k) - 1] |= bit
        g, d, wmin, ok = lane_finish(nd, e, eps, x, u, tail, reset)
        eps, x, u, tail = lane_bits(c + _U1, kw, jittered, jitter)  # the next cycle's
        nw, valid = apply_cached(wfire, g, wmin if ok else np.inf, e, reset)
        if valid:
            w = nw
            nd = d
            c += _U1
        else:
            wait[lane] = wfire
            need[lane] = nd
            cyc[lane] = np.float64(c)
            _fire_lane(lane, electrons, ev, reset, jitter, keys, pix0, wu)
            w = wait[lane]
            nd = need[lane]
            c1 = np.uint64(cyc[lane])
            if c1 != c + _U1:  # (a float64 cycle count beyond 2⁵³)
                eps, x, u, tail = lane_bits(c1, kw, jittered, jitter)
            c = c1
        p += k
        if p >= fcount:
            break
        if moving:
            lm = l0 + p * dl
            inv_lam = 1.0 / lm if lm > 0.0 else np.inf
    wait[lane] = w
    need[lane] = nd
    cyc[lane] = np.float64(c)


#: A packed walk's status of a row after a round: no firing in it, a firing
#: whose cached draw held, a firing that :func:`fire_cycle` finishes, or a row
#: left to the lane-by-lane walk (a wait of :data:`EXACT_WAIT` or more).
_QUIET, _FIRED, _REDRAW, _BY_LANE = 0, 1, 2, 3
#: Rows a packed walk's round takes in whole groups of (a multiple of the
#: vector width), and the finished rows it gathers before it compacts them.
_WALK_GROUP = 8
#: Fewest rows a round takes: below 16 rows LLVM runs the constant-charge
#: round on scalars (its checks that the rows do not overlap cost more than
#: they save, it judges), so the last few rows of a block, padded to 8, took
#: 8 rows of scalar work a round instead of two vector steps.  (The
#: changing-charge round, vectorised from 8 rows on, then takes one vector
#: step more on a block's last rows, on runs of 128 readouts or more only.)
_WALK_ROWS_MIN = 16


@njit(**_opts)
def _copy_row(wf, wu, src, dst):
    """Copy packed-walk row ``src`` onto ``dst`` (every ``W_*`` row)."""
    for r in range(W_WAIT, W_U + 1):
        wf[r, dst] = wf[r, src]
    for r in range(W_CYCLE, W_BIT + 1):
        wu[r, dst] = wu[r, src]


@njit(**_opts)
def _put_row(wf, wu, ev, i):
    """Write packed-walk row ``i``'s wait, need and cycle back to its lane of ``ev``."""
    lane = wu[W_LANE, i]
    ev[WAIT, lane] = wf[W_WAIT, i]
    ev[NEED, lane] = wf[W_NEED, i]
    ev[CYCLE, lane] = np.float64(wu[W_CYCLE, i])


@njit(**_opts)
def _round_rows(n, group):
    """Rows a packed walk's round takes for ``n`` active ones: whole
    ``group`` rows, at least :data:`_WALK_ROWS_MIN`."""
    return max((n + group - 1) // group * group, _WALK_ROWS_MIN)


@njit(**_opts)
def _pad_rows(wf, wu, n, group):
    """Fill rows ``n`` up to :func:`_round_rows` with copies of row 0 (valid
    numbers the round computes and drops)."""
    for i in range(n, _round_rows(n, group)):
        _copy_row(wf, wu, 0, i)


@njit(**_opts)
def _crossing_constant(w, lam, inv_lam, left):
    """:func:`crossing` without branches, for a vector of lanes: ``(k, found)``,
    ``k`` the same readouts to the next firing wherever ``found`` (not where
    it would have returned ``left + 1``)."""
    k0 = np.ceil(w * inv_lam)
    dec = (k0 > 1.0) & ((k0 - 1.0) * lam >= w)
    inc = (not dec) & (k0 * lam < w)
    k = k0 - 1.0 if dec else (k0 + 1.0 if inc else k0)
    return k, (k0 <= left + 2.0) & (k <= left)


@njit(**_opts)
def _crossing_steps(w, lam, dlam, inv_lam, left):
    """:func:`crossing_linear` (and :func:`crossing`, ``dlam`` = 0) without
    branches, for a vector of lanes: ``(k, found)``, ``k`` the same readouts to
    the next firing wherever ``found``; the estimate followed by at most two
    steps either way (its exact sums, :func:`charge_sum`, compared with ``w``
    at each), not ``found`` where those do not reach the crossing or it lies
    beyond ``left``."""
    k0 = w * inv_lam
    ke = np.ceil(k0 - (0.5 * dlam * inv_lam) * (k0 * (k0 - 1.0)))
    ke = ke if ke >= 1.0 else 1.0
    ke = ke if ke <= left else left
    up = charge_sum(ke, lam, dlam) < w
    up1 = charge_sum(ke + 1.0, lam, dlam) >= w
    up2 = charge_sum(ke + 2.0, lam, dlam) >= w
    k_up = ke + 1.0 if up1 else ke + 2.0
    found_up = (up1 | up2) & (k_up <= left)
    down1 = (ke <= 1.0) | (charge_sum(ke - 1.0, lam, dlam) < w)
    down2 = (ke <= 2.0) | (charge_sum(ke - 2.0, lam, dlam) < w)
    k_down = ke if down1 else ke - 1.0
    return (k_up if up else k_down), (found_up if up else (down1 | down2))


def _make_packed_walk(reset, jittered, moving, group=_WALK_GROUP):
    """:func:`_packed_walk` compiled for one reset mode, jitter switch and
    whether the charge may change (``moving``; else every ``dlam`` is 0), in
    whole ``group`` rows."""

    @njit(**_inner)
    def packed_walk(ev, lam, dlam, electrons, jitter, keys, pix0, wf, wu, words, count):
        prefer_wide_vectors()
        wait, need, cyc = ev[WAIT], ev[NEED], ev[CYCLE]
        rw, rn, re, rl, rdl, ri, rp = (wf[W_WAIT], wf[W_NEED], wf[W_E], wf[W_LAM], wf[W_DLAM],
                                       wf[W_INV], wf[W_DONE])
        reps, rx, ru = wf[W_EPS], wf[W_X], wf[W_U]
        rc, rseq, rtail, rlane, rstat = (wu[W_CYCLE], wu[W_SEQ], wu[W_TAIL], wu[W_LANE],
                                         wu[W_STATUS])
        rword, rbit = wu[W_WORD], wu[W_BIT]
        fcount = np.float64(count)
        odd = 0
        for lane in range(BLOCK):  # (vectorises)
            limit = EXACT_WAIT if dlam[lane] == 0.0 else LINEAR_WAIT
            odd += 0 if (wait[lane] < limit) & (cyc[lane] < _TWO52 - fcount) else 1
        n = 0
        if odd == 0:  # every lane a row, in lane order
            for lane in range(BLOCK):
                rlane[lane] = np.uint64(lane)
                rw[lane] = wait[lane]
                rn[lane] = need[lane]
                re[lane] = electrons[lane]
                rl[lane] = lam[lane]
                rdl[lane] = dlam[lane]
                ri[lane] = 1.0 / lam[lane] if lam[lane] > 0.0 else np.inf
                rp[lane] = 0.0
                rc[lane] = uint_of_52(cyc[lane])
                rseq[lane] = counter_input(wu[LKW, lane], rc[lane] + _U1)
            n = BLOCK
        else:  # (an enormous threshold, or 2⁵² cycles) those lanes walked one by one
            for lane in range(BLOCK):
                w = wait[lane]
                l0 = lam[lane]
                dl = dlam[lane]
                limit = EXACT_WAIT if dl == 0.0 else LINEAR_WAIT
                if dl == 0.0 and not l0 > 0.0 and w > 0.0:  # never fires in this run
                    continue
                if not ((w < limit) & (cyc[lane] < _TWO52 - fcount)):
                    _walk_lane(lane, ev, l0, dl, electrons, reset, jitter, keys, pix0, wu, words,
                               fcount, 0.0)
                    continue
                rlane[n] = np.uint64(lane)
                rw[n] = w
                rn[n] = need[lane]
                re[n] = electrons[lane]
                rl[n] = l0
                rdl[n] = dl
                ri[n] = 1.0 / l0 if l0 > 0.0 else np.inf
                rp[n] = 0.0
                rc[n] = uint_of_52(cyc[lane])
                rseq[n] = counter_input(wu[LKW, lane], rc[n] + _U1)
                n += 1
            if n == 0:
                return
            _pad_rows(wf, wu, n, group)
        for i in range(_round_rows(n, group)):  # vectorises
            eps, x, u, tail = word_bits(mix64(rseq[i]), jittered, jitter)
            reps[i] = eps
            rx[i] = x
            ru[i] = u
            rtail[i] = np.uint64(tail)
        active = n
        while active > 0:
            rows = _round_rows(active, group)
            done = 0
            special = 0
            for i in range(rows):  # one firing per row, branch-free: vectorises
                w = rw[i]
                l0 = rl[i]
                dl = rdl[i]
                p = rp[i]
                c = rc[i]
                nd = rn[i]
                e = re[i]
                left = fcount - p
                if moving:
                    limit = EXACT_WAIT if dl == 0.0 else LINEAR_WAIT
                    lm = l0 + p * dl  # the charge of readout p (l0 itself where dl = 0)
                    inv = 1.0 / lm if lm > 0.0 else np.inf
                    rest = charge_sum(left, lm, dl)
                    k, found = _crossing_steps(w, lm, dl, inv, left)
                else:
                    limit = EXACT_WAIT
                    lm = l0
                    rest = left * lm
                    k, found = _crossing_constant(w, lm, ri[i], left)
                pos = w > 0.0
                big = pos & (w >= limit)  # the lane-by-lane walk steps it
                quiet = pos & (not big) & (w > rest)  # no firing in the rest of the run
                k = k if pos else 1.0
                go = (not quiet) & (left > 0.0)
                by_lane = go & (big | (pos & (not found)))
                fire = go & (not by_lane)
                wfire = w - (charge_sum(k, lm, dl) if moving else k * lm)
                g, d, wmin, ok = lane_finish(nd, e, reps[i], rx[i], ru[i], rtail[i] != 0,
                                             reset)
                seq = rseq[i] + _G1  # the next cycle's (lane_bits(c + 1, …))
                eps, x, u, tail = word_bits(mix64(seq), jittered, jitter)
                nw, valid = apply_cached(wfire, g, wmin if ok else np.inf, e, reset)
                take = fire & valid
                p1 = p + k
                # a firing whose next crossing lies beyond the run ends the row at once
                # (a changing charge's runs are short: it spares them a round)
                left1 = fcount - p1
                rest1 = charge_sum(left1, l0 + p1 * dl, dl) if moving else left1 * l0
                last = moving & take & (left1 > 0.0) & (nw > 0.0) & (nw < limit) & (nw > rest1)
                rw[i] = (nw - rest1 if last else nw) if take else (
                    wfire if fire else (w - rest if quiet else w))
                rn[i] = d if take else nd
                rc[i] = c + _U1 if fire else c
                rseq[i] = seq if fire else rseq[i]
                reps[i] = eps if fire else reps[i]
                rx[i] = x if fire else rx[i]
                ru[i] = u if fire else ru[i]
                rtail[i] = np.uint64(tail) if fire else rtail[i]
                p_new = (fcount if last else p1) if fire else (fcount if quiet else p)
                rp[i] = p_new
                rword[i] = uint_of_52(p1 if fire else 1.0) - _U1  # (p1 < 2⁵²)
                rbit[i] = np.uint64(fire)
                rstat[i] = (_FIRED if take else (_REDRAW if fire else
                                                 (_BY_LANE if by_lane else _QUIET)))
                # (counted here, not in the scalar pass: 12 % of a static run's time
                # went to that pass; pad rows count for nothing)
                row = i < active
                done += 1 if row & (by_lane | (p_new >= fcount)) else 0
                special += 1 if row & (by_lane | (fire & (not take))) else 0
            for i in range(active):
                words[rword[i]] |= rbit[i] << rlane[i]
            for i in range(active if special else 0):
                s = rstat[i]
                if s == _REDRAW:  # what the cached draw cannot finish, exactly
                    lane = rlane[i]
                    w, d, c1 = fire_cycle(rw[i], rn[i], np.float64(rc[i] - _U1), re[i], reset,
                                          jitter, wu[LKW, lane], keys[1], keys[2], pix0 + lane)
                    rw[i] = w
                    rn[i] = d
                elif s == _BY_LANE:
                    lane = rlane[i]
                    _put_row(wf, wu, ev, i)
                    _walk_lane(np.int64(lane), ev, rl[i], rdl[i], electrons, reset, jitter, keys,
                               pix0, wu, words, fcount, rp[i])
                    rw[i] = wait[lane]
                    rn[i] = need[lane]
                    rc[i] = np.uint64(cyc[lane])
                    rp[i] = fcount
            if done == active or _round_rows(active - done, group) < rows:
                kept = 0
                for i in range(active):
                    if rp[i] >= fcount:
                        _put_row(wf, wu, ev, i)
                    else:
                        if kept != i:
                            _copy_row(wf, wu, i, kept)
                        kept += 1
                active = kept
                if active > 0:
                    _pad_rows(wf, wu, active, group)

    return packed_walk


#: The walks compiled for each reset mode, for a constant and a changing
#: charge (the constant charge's own walk measured 1.30× faster on a static
#: 500×500 physical run than the changing charge's walk taking it, AMD EPYC
#: host).  Always with the jitter's bits (with no jitter they give a jitter
#: of ±0, the same threshold; its normal's tail sends 0.8 % of the draws to
#: :func:`fire_cycle`): half the variants to compile.
_WALK_M, _WALK_M_MOVING, _WALK_S, _WALK_S_MOVING, _WALK_Z, _WALK_Z_MOVING = (
    _make_packed_walk(reset, True, moving) for reset in (MODULO, SUBTRACT, ZERO)
    for moving in (False, True))


@njit(inline="always", **_opts)
def _packed_walk(ev, lam, dlam, electrons, reset, jitter, keys, pix0, wf, wu, words, count):
    """:func:`_direct_lanes` on vectors: the lanes are packed into contiguous
    rows (rows ``W_*`` of the work arrays; every lane in lane order, unless
    one needs the lane-by-lane walk from the start), and each round takes
    every row to its next firing in one branch-free loop that LLVM vectorises
    (:func:`_crossing_constant` or :func:`_crossing_steps`, :func:`lane_finish`
    with the bits :func:`lane_bits` made a round ahead, :func:`apply_cached`;
    a row whose next crossing lies beyond the run ends there); a scalar pass
    sets the spike bits and finishes what the cached draw cannot
    (:func:`fire_cycle`, or :func:`_walk_lane` for the rest of the run), and
    finished rows are gathered out whenever that saves a vector step.  The
    same operations as :func:`_walk_lane`, so the same bits.  ``reset`` must be
    a constant (only its own walks are compiled)."""
    moving = 0
    for lane in range(BLOCK):
        moving += 0 if dlam[lane] == 0.0 else 1
    args = (ev, lam, dlam, electrons, jitter, keys, pix0, wf, wu, words, count)
    if reset == MODULO:
        if moving:
            _WALK_M_MOVING(*args)
        else:
            _WALK_M(*args)
    elif reset == SUBTRACT:
        if moving:
            _WALK_S_MOVING(*args)
        else:
            _WALK_S(*args)
    elif moving:
        _WALK_Z_MOVING(*args)
    else:
        _WALK_Z(*args)
