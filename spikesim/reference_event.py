"""Slow NumPy/Python reference of the event-driven shot-noise sampler.

Written independently of ``spikesim._event`` (Python-int hashing, scalar
Python samplers, NumPy over pixels per readout) to check the kernel bit for
bit.  The algorithm (see ``spikesim._event`` for the derivation): per pixel
the electrons ``D = E·(1 − A)`` missing to the threshold and the operational
time ``wait`` to the ``⌈D⌉``-th electron, ``Gamma(⌈D⌉, 1)`` (Marsaglia &
Tsang 2000); per readout ``wait −= λ_n`` with ``λ_n = E·q_n`` (times ``1 − f``
after a firing, charge loss ``f``); the pixel fires where ``wait ≤ 0``, the
residual electrons of that readout are ``Poisson(−wait)`` (inversion below 10,
Hörmann's transformed rejection above), then reset, comparator jitter and the
next wait, every draw keyed by (stream, cycle, pixel).

Floating-point operations are those of the kernel in the same order, except
``exp`` and ``lgamma`` (``math`` here, numba's there, which may differ in the
last bit); like the radiance integral of ``spikesim.reference`` this can only
change a draw when a uniform lands within ~1e-16 of a decision boundary.
"""

from __future__ import annotations

import math

import numpy as np

from spikesim import rng
from spikesim.reference_rng import _f32_pair, _log_positive_np, normal_np

__all__ = ["EventReference"]

_MASK = (1 << 64) - 1
_LAMBDA_MAX = 2.0**62
_BACKLOG_MAX = 2.0**62


def _mix(z: int) -> int:
    """SplitMix64 finaliser on a Python int."""
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _MASK
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _MASK
    return z ^ (z >> 31)


def _bits(key: int, counter: int, pixel: int) -> int:
    """The pixel's key for the stream, ``pixel_bits(key, pixel)``, then
    ``readout_key`` of it for the counter: a SplitMix64 sequence per pixel."""
    lane = _mix(key ^ ((pixel * rng.G2) & _MASK))
    return _mix((lane + counter * rng.G1) & _MASK)


def _sub_bits(bits: int, j: int) -> int:
    """``pixel_bits(bits, j)``: attempt ``j``'s bits of a rejection sampler."""
    return _mix(bits ^ ((j * rng.G2) & _MASK))


def _normal(bits: int) -> float:
    return float(normal_np(np.array([bits], np.uint64))[0])


def _normal_field(f: int, fresh: int) -> float:
    """Standard normal from a 26-bit field: bin ``f >> 14`` of the shipped
    body table, position ``((f mod 2**14) + ½)·2**-14`` in it; in the 16
    outermost bins on each side the full normal of the 64-bit word made of
    that bin (top 12 bits) and the top 52 bits of ``fresh``."""
    k = f >> 14
    if k < rng.ICDF_TAIL_BINS or k >= rng.ICDF_BINS - rng.ICDF_TAIL_BINS:
        return _normal((k << 52) | (fresh >> 12))
    q, d = _f32_pair(rng._ICDF_PAIRS[np.array([k])])
    return float(q[0] + d[0] * (((f & (2**14 - 1)) + 0.5) * 2.0**-14))


def _jitter_z(word: int) -> float:
    """The comparator jitter's normal: the draw word's top 26 bits (tail: word 0)."""
    return _normal_field(word >> 38, _sub_bits(word, 0))


def _drop_negligible(left: float, h0: float) -> bool:
    """Chernoff's bound on P(Poisson(left) ≥ h0) below 2**-64: with s = 1 − left/h0,
    ln of the bound ≤ −h0·(s²/2 + … + s⁶/6) (a truncated series of same-sign terms)."""
    a = h0 - left  # = s·h0; the rule times h0**5, evaluated as the kernel does
    h2 = h0 * h0
    h3 = h2 * h0
    h4 = h3 * h0
    p = a * (1.0 / 6.0) + h0 * (1.0 / 5.0)
    p = p * a + h2 * 0.25
    p = p * a + h3 * (1.0 / 3.0)
    p = p * a + h4 * 0.5
    return 1.0 <= h0 <= 1e50 and a > 0.0 and a * a * p >= 44.5 * (h4 * h0)


def _uniform(bits: int) -> float:
    return ((bits >> 12) + 0.5) * 2.0**-52


def _log(y: float) -> float:
    return float(_log_positive_np(np.array([y], np.float64))[0])


def gamma_ref(m: float, bits: int) -> float:
    """Gamma(m, 1) from a draw word: ``−log Π u_j`` for m ≤ 8 (``u_j`` from
    ``_sub_bits(bits, j + 1)``), else Marsaglia–Tsang.  Its first attempt takes
    the normal from bits 37–12 (:func:`_normal_field`, tail bits from sub-word
    2) and the uniform's top 12 bits from bits 11–0 (the rest from sub-word 1);
    attempt j ≥ 1 from sub-words ``2j + 1``, ``2j + 2``."""
    if m <= 8:
        prod = 1.0
        for j in range(int(m)):
            prod *= _uniform(_sub_bits(bits, j + 1))
        return -_log(prod)
    d = m - 1.0 / 3.0
    c = 1.0 / math.sqrt(9.0 * d)
    x = _normal_field((bits >> 12) & (2**26 - 1), _sub_bits(bits, 2))
    u = _uniform(((bits & 4095) << 52) | (_sub_bits(bits, 1) >> 12))
    j = 1
    while True:
        t = 1.0 + c * x
        if t > 0.0:
            v = t * t * t
            x2 = x * x
            if t >= 0.5 and u < 1.0 - (4.0 / 3.0) * (c * c) * (x2 * x2):
                return d * v  # ln u ≤ u − 1 < −(4/3)c²x⁴ ≤ the log test's right side
            if _log(u) < 0.5 * x2 + d * (1.0 - v + _log(v)):
                return d * v
        x = _normal(_sub_bits(bits, 2 * j + 1))
        u = _uniform(_sub_bits(bits, 2 * j + 2))
        j += 1


def poisson_ref(lam: float, bits: int) -> float:
    """Poisson(lam): CDF inversion below 10 (at most 200 steps), else the
    transformed rejection with squeeze (Hörmann 1993), attempt j from
    ``_sub_bits(bits, j)`` and ``j + 1``."""
    if lam <= 0.0:
        return 0.0
    if lam < 10.0:
        u = _uniform(bits)
        p = math.exp(-lam)
        cdf = p
        k = 0
        while u > cdf and k < 200:
            k += 1
            p *= lam * (1.0 / k)
            cdf += p
        return float(k)
    b = 0.931 + 2.53 * math.sqrt(lam)
    a = -0.059 + 0.02483 * b
    inv_alpha = 1.1239 + 1.1328 / (b - 3.4)
    v_r = 0.9277 - 3.6224 / (b - 2.0)
    loglam = _log(lam)
    j = 0
    while True:
        u = _uniform(_sub_bits(bits, j)) - 0.5
        v = _uniform(_sub_bits(bits, j + 1))
        j += 2
        us = 0.5 - abs(u)
        k = math.floor((2.0 * a / us + b) * u + lam + 0.43)
        if us >= 0.07 and v <= v_r:
            return float(k)
        if k < 0 or (us < 0.013 and v > us):
            continue
        lhs = _log(v) + _log(inv_alpha) - _log(a / (us * us) + b)
        if lhs <= -lam + k * loglam - math.lgamma(k + 1.0):
            return float(k)


class EventReference:
    """Event-driven state of every pixel: ``need``, ``wait``, ``cycle``,
    ``after`` (fired at the previous readout), for an (H, W) sensor.

    ``electrons`` (H, W) e⁻ per threshold, ``a0`` (H, W) the initial charge
    (thresholds, in [0, 1)), ``reset`` ``"modulo" | "subtract" | "zero"``,
    ``jitter`` σ_t, ``loss`` the charge loss at reset, ``seed`` the simulation
    seed.
    """

    def __init__(self, electrons, a0, reset: str, jitter: float, loss: float, seed: int):
        self.e = np.asarray(electrons, np.float64).ravel()
        self.reset = reset
        self.jitter = float(jitter)
        self.loss = float(loss)
        self.key_wait = int(rng.stream_key(seed, rng.STREAM_WAIT))
        self.key_resid = int(rng.stream_key(seed, rng.STREAM_RESIDUAL))
        self.key_refill = int(rng.stream_key(seed, rng.STREAM_REFILL))
        self.need = self.e * (1.0 - np.asarray(a0, np.float64).ravel())
        self.cycle = np.zeros(self.e.size, np.int64)
        self.after = np.zeros(self.e.size)
        self.wait = np.array([self._gamma(d, self.key_wait, 0, p)
                              for p, d in enumerate(self.need.tolist())])

    def _gamma(self, shape: float, key: int, counter: int, p: int) -> float:
        """Operational time to the ``⌈shape⌉``-th electron (0 for shape ≤ 0)."""
        if not shape > 0.0:
            return 0.0
        return gamma_ref(float(math.ceil(shape)), _bits(key, counter, p))

    def _fire(self, p: int) -> None:
        c = int(self.cycle[p])
        wait, need, e = float(self.wait[p]), float(self.need[p]), float(self.e[p])
        m = float(math.ceil(need)) if need > 0.0 else 0.0
        eps = 0.0
        if self.jitter > 0.0:  # the jitter shares the next cycle's draw word
            z = _jitter_z(_bits(self.key_wait, c + 1, p))
            eps = min(max(self.jitter * z, -0.5), 0.5)
        self.cycle[p] = c + 1
        if self.reset == "zero":  # a fresh cycle from the end of this readout
            d = e + e * eps
            self.need[p], self.wait[p] = d, self._gamma(d, self.key_wait, c + 1, p)
            return
        lead = need - m  # the threshold relative to the crossing electron
        d = (lead + e) + e * eps  # the next threshold, electrons after the crossing
        hd = float(math.ceil(d)) if d > 0.0 else 0.0
        if self.reset == "subtract":
            w = wait + self._gamma(hd, self.key_wait, c + 1, p)
            self.need[p], self.wait[p] = d, max(w, -_BACKLOG_MAX * e)
            return
        h0 = float(math.ceil(lead + e))  # this many after the crossing: charge ≥ 2θ at the end
        # a drop below 2**-64 is not drawn, only the next crossing
        no_drop = _drop_negligible(-wait, h0)
        h = hd if no_drop else min(h0, hd)
        g = self._gamma(h, self.key_wait, c + 1, p)
        if wait + g > 0.0:
            if hd > h:
                g += self._gamma(hd - h, self.key_resid, c + 1, p)
            self.need[p], self.wait[p] = d, wait + g
            return
        post = h + poisson_ref(min(-(wait + g), _LAMBDA_MAX), _bits(self.key_resid, c + 1, p))
        x = post - lead
        d2 = (e - math.fmod(x, e)) + e * eps
        self.need[p], self.wait[p] = d2, self._gamma(d2, self.key_refill, c + 1, p)

    def step(self, q) -> np.ndarray:
        """One readout with mean charges ``q`` (H, W) thresholds; returns the (H, W) spikes."""
        shape = np.shape(q)
        lam = np.minimum(np.asarray(q, np.float64).ravel() * self.e, _LAMBDA_MAX)
        self.wait = self.wait - lam * (1.0 - self.loss * self.after)
        fired = self.wait <= 0.0
        for p in np.flatnonzero(fired).tolist():
            self._fire(p)
        self.after = fired.astype(np.float64)
        return fired.reshape(shape)
