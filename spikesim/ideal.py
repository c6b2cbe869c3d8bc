"""Ideal asynchronous reference: exact firing times without a readout clock.

An unclocked integrate-and-fire pixel fires at every instant its charge
``A(t) = A0 + ∫ (gain·I(τ) + offset) dτ`` crosses a multiple of θ (eq. 1 of
Dong et al., AAAI 2024); without a clock, modulo, subtract and zero reset are
the same thing (the reset happens exactly at the crossing).  With radiance
piecewise linear between key frames the charge is piecewise quadratic, and
each crossing time is a root of ``c1/2·s² + c0·s − d = 0``, taken in the
cancellation-free form ``s = 2d / (c0 + sqrt(c0² + 2·c1·d))``.

The clocked sensor reports readout ``n`` as 1 when at least one crossing lies
in ``(n, n+1]``, so ``ceil(t) − 1`` maps an ideal time ``t`` to its readout:
comparing the two isolates **quantization noise** (clocking and the
one-spike-per-readout limit).  Only noise-free sensors (fixed patterns
allowed, no per-readout noise) have an ideal reference.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from spikesim import _kernels, rng
from spikesim.cfa import mosaic
from spikesim.errors import bad_value
from spikesim.noise import fixed_pattern
from spikesim.scenes.static import validate_radiance
from spikesim.schedule import key_readout_times

__all__ = ["ideal_spike_times", "IdealSpikes"]


class IdealSpikes:
    """Firing times per pixel, stored compressed (CSR).

    ``times`` (float64, readout units) of pixel ``(y, x)`` are
    ``times[start[y, x] : start[y, x] + count[y, x]]``, increasing.
    """

    def __init__(self, count: np.ndarray, start: np.ndarray, times: np.ndarray):
        self.count, self.start, self.times = count, start, times

    def pixel(self, y: int, x: int) -> np.ndarray:
        s = self.start[y, x]
        return self.times[s : s + self.count[y, x]]

    def clocked(self, n_readouts: int) -> np.ndarray:
        """(T, H, W) uint8: 1 where a readout period holds at least one firing."""
        h, w = self.count.shape
        out = np.zeros((n_readouts, h, w), np.uint8)
        _fill_clocked(self.count, self.start, self.times, out)
        return out


@njit(cache=True)
def _fill_clocked(count, start, times, out):
    h, w = count.shape
    for y in range(h):
        for x in range(w):
            s = start[y, x]
            for i in range(s, s + count[y, x]):
                n = math.ceil(times[i]) - 1
                if 0 <= n < out.shape[0]:
                    out[n, y, x] = 1


@njit(cache=True)
def _crossings(frames, tau, gain, offset, a0, n_readouts, count, buf):
    """Crossing times of every pixel over [0, n_readouts]; returns the total."""
    k = frames.shape[0]
    h, w = a0.shape
    total = 0
    # breakpoints: 0, key times inside (0, N), N
    bps = [0.0]
    for t in tau:
        if 0.0 < t < n_readouts:
            bps.append(t)
    bps.append(float(n_readouts))
    for y in range(h):
        for x in range(w):
            acc = a0[y, x]
            c = 0
            for i in range(len(bps) - 1):
                lo = bps[i]
                hi = bps[i + 1]
                # radiance at lo and slope on [lo, hi] (held outside the keys)
                if k == 1 or lo >= tau[k - 1]:
                    i_lo = frames[k - 1 if k > 1 else 0, y, x]
                    slope = 0.0
                elif lo < tau[0]:
                    i_lo = frames[0, y, x]
                    slope = 0.0
                else:
                    j = 0
                    while j + 1 < k and tau[j + 1] <= lo:
                        j += 1
                    ia = frames[j, y, x]
                    ib = frames[j + 1, y, x]
                    slope = (ib - ia) / (tau[j + 1] - tau[j])
                    i_lo = ia + slope * (lo - tau[j])
                c0 = gain[y, x] * i_lo + offset[y, x]
                c1 = gain[y, x] * slope
                pos = lo
                while True:
                    rem = hi - pos
                    d = 1.0 - acc
                    disc = c0 * c0 + 2.0 * c1 * d
                    s = -1.0
                    if disc >= 0.0 and c0 + math.sqrt(disc) > 0.0:
                        s = 2.0 * d / (c0 + math.sqrt(disc))
                    if s < 0.0 or s > rem:
                        acc += c0 * rem + 0.5 * c1 * rem * rem
                        break
                    pos += s
                    c0 += c1 * s
                    acc = 0.0
                    if total + c < buf.shape[0]:
                        buf[total + c] = pos
                    c += 1
            count[y, x] = c
            total += c
    return total


def ideal_spike_times(scene, sensor, n_readouts: int, seed: int = 0) -> IdealSpikes:
    """Exact asynchronous firing times of a noise-free sensor (readout units).

    Uses the same key frames, colour filter, fixed patterns and initial
    accumulator (same ``seed``) as :func:`spikesim.simulate`.
    """
    if sensor.noise is not None and sensor.noise.per_readout:
        raise bad_value("sensor.noise", sensor.noise,
                        "no per-readout noise and no reset_charge_loss (the ideal reference is "
                        "deterministic and unclocked)")
    if not isinstance(n_readouts, int) or n_readouts < 1:
        raise bad_value("n_readouts", n_readouts, "an integer >= 1")
    h, w = sensor.shape
    clock = sensor.clock_hz
    times = np.asarray(scene.key_times(0.0, n_readouts / clock), np.float64)
    tau = key_readout_times(times, clock)
    frames = np.stack([
        mosaic(validate_radiance(scene.radiance(t), "scene.radiance"), sensor.cfa)
        for t in times.tolist()
    ]).astype(np.float32).astype(np.float64)
    pattern = fixed_pattern(sensor.noise, h, w, sensor.full_scale_rate)
    wp = _kernels.BLOCK * math.ceil(w / _kernels.BLOCK)
    frac = _kernels.init_state(rng.stream_key(seed, rng.STREAM_INIT), h, w, wp,
                               sensor.init == "uniform")[:, :w]
    a0 = frac.astype(np.float64) * 2.0**-64
    count = np.zeros((h, w), np.int64)
    expected = float(np.sum(np.max(frames, axis=0) * pattern.gain + pattern.offset)) * n_readouts
    buf = np.empty(int(expected) + h * w + 16, np.float64)
    total = _crossings(frames, tau, pattern.gain, pattern.offset, a0, n_readouts, count, buf)
    if total > buf.shape[0]:  # pragma: no cover - the bound above is an upper bound
        buf = np.empty(total, np.float64)
        _crossings(frames, tau, pattern.gain, pattern.offset, a0, n_readouts, count, buf)
    start = np.zeros((h, w), np.int64)
    start.ravel()[1:] = np.cumsum(count.ravel())[:-1]
    return IdealSpikes(count, start, buf[:total].copy())
