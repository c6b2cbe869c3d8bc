"""Slow, obviously-correct NumPy float64 reference of the clocked sensor.

Written independently of ``spikesim._kernels`` (its own colour filter, radiance
integral, hash, normal deviates with ``np.log`` and fancy indexing into the
shipped quantile table, and a float64 accumulator instead of fixed point) to
check the kernel bit for bit and to serve as the vectorised-NumPy baseline of
``benchmarks/bench_kernel.py``.  Loops over readouts; vectorised over pixels.

Supported: every reset mode, CFA, key-frame layout, fixed patterns, paper
(eq. 5) noise, the temporal threshold noise of physical mode (after each
firing the next threshold is θ(1 + ε), ε = σ_t·z clipped to ±½, i.e. the
charge moves by −ε), its accumulating charge noise (``charge_sd·z`` added
to every readout's charge), its charge loss at reset (the readout after a
firing collects ``1 − f`` of its mean charge) and its event-driven Poisson
shot noise (``spikesim.reference_event``).  Not supported: the per-readout
shot-noise sampler (used with charge noise), checked statistically and lane
by lane against the scalar sampler.

The float64 accumulator differs from the kernel's exact fixed point by
rounding (~1e-16 θ per readout), which can only change a bit when the charge
lands within that distance of the threshold; on random inputs this does not
happen in practice, and the tests state it.
"""

from __future__ import annotations

import numpy as np

from spikesim import rng
from spikesim.reference_rng import _pixel_bits_np, _readout_key_np, mix64_np, normal_np

__all__ = ["reference_simulate", "mix64_np", "normal_np"]

_CH = {"R": 0, "G": 1, "B": 2}
_LUMA = np.array([0.2126, 0.7152, 0.0722])


def _sensor_view(rgb: np.ndarray, cfa: str | None) -> np.ndarray:
    rgb = np.asarray(rgb, dtype=np.float32)
    if cfa is None:
        c = rgb.astype(np.float64)
        return (_LUMA[0] * c[..., 0] + _LUMA[1] * c[..., 1] + _LUMA[2] * c[..., 2]).astype(
            np.float32)
    h, w = rgb.shape[:2]
    out = np.empty((h, w), np.float32)
    for dy in range(2):
        for dx in range(2):
            out[dy::2, dx::2] = rgb[dy::2, dx::2, _CH[cfa[2 * dy + dx]]]
    return out


def _mean_radiance(frames: np.ndarray, tau: np.ndarray, n: int) -> np.ndarray:
    """Exact mean over [n, n+1) of the piecewise-linear radiance (held at the ends)."""
    cuts = [float(n)] + [float(t) for t in tau if n < t < n + 1] + [float(n + 1)]
    total = np.zeros(frames.shape[1:], np.float64)
    for lo, hi in zip(cuts[:-1], cuts[1:], strict=True):
        mid = 0.5 * (lo + hi)
        if len(tau) == 1 or mid < tau[0]:
            value = frames[0].astype(np.float64)
        elif mid >= tau[-1]:
            value = frames[-1].astype(np.float64)
        else:
            j = int(np.searchsorted(tau, mid, side="right")) - 1
            fa = frames[j].astype(np.float64)
            fb = frames[j + 1].astype(np.float64)
            value = fa + (fb - fa) * ((mid - tau[j]) / (tau[j + 1] - tau[j]))
        total += (hi - lo) * value
    return total


def reference_simulate(scene, sensor, n_readouts: int, seed: int = 0) -> np.ndarray:
    """Packed spikes (T, H, ceil(W/8)) of ``sensor`` viewing ``scene``, in float64 NumPy."""
    from spikesim.noise import PaperNoise, PhysicalNoise, fixed_pattern

    h, w = sensor.shape
    clock = sensor.clock_hz
    times = np.asarray(scene.key_times(0.0, n_readouts / clock), np.float64)
    tau = times * clock
    near = np.round(tau)
    tau = np.where(np.abs(tau - near) < 1e-9, near, tau)
    frames = np.stack([_sensor_view(scene.radiance(t), sensor.cfa) for t in times.tolist()])
    noise = sensor.noise
    physical = isinstance(noise, PhysicalNoise)
    if physical and noise.shot_noise and not noise.event_driven:
        raise ValueError("the reference does not support the per-readout shot-noise sampler "
                         "(shot noise with charge noise)")
    jitter = noise.temporal_threshold_noise if physical else 0.0
    loss = noise.reset_charge_loss if physical else 0.0
    key_jitter = rng.stream_key(seed, rng.STREAM_JITTER)
    key_charge = rng.stream_key(seed, rng.STREAM_CHARGE)
    pattern = fixed_pattern(noise, h, w, sensor.full_scale_rate)
    n_pix = h * w
    if sensor.init == "uniform":
        bits = _pixel_bits_np(_readout_key_np(rng.stream_key(seed, rng.STREAM_INIT), 0), n_pix)
        acc = bits.astype(np.float64).reshape(h, w) * 2.0**-64
    else:
        acc = np.zeros((h, w))
    key_paper = rng.stream_key(seed, rng.STREAM_PAPER)
    out = np.zeros((n_readouts, h, w), np.uint8)
    if physical and noise.event_driven:
        from spikesim.reference_event import EventReference

        events = EventReference(pattern.electrons, acc, sensor.reset, jitter, loss, seed)
        for n in range(n_readouts):
            out[n] = events.step(pattern.gain * _mean_radiance(frames, tau, n) + pattern.offset)
        return np.packbits(out, axis=-1, bitorder="little")
    after = np.zeros((h, w))
    for n in range(n_readouts):
        level = _mean_radiance(frames, tau, n)
        if isinstance(noise, PaperNoise) and noise.per_readout:
            z = normal_np(_pixel_bits_np(_readout_key_np(key_paper, n), n_pix)).reshape(h, w)
            sd = np.sqrt(noise.sigma_g**2 + noise.sigma_p**2 * 255.0 * level) / 255.0
            level = np.maximum(level + sd * z, 0.0)
        q = pattern.gain * level + pattern.offset
        if loss > 0.0:  # charge loss in the readout after a firing
            q = q * (1.0 - loss * after)
        if pattern.charge_sd is not None:  # accumulating charge noise, after the mean charge
            z = normal_np(_pixel_bits_np(_readout_key_np(key_charge, n), n_pix)).reshape(h, w)
            q = q + pattern.charge_sd * z
        acc = acc + q
        spike = acc >= 1.0
        out[n] = spike
        after = spike.astype(np.float64)
        if sensor.reset == "modulo":
            acc = np.where(spike, acc - np.floor(acc), acc)
        elif sensor.reset == "subtract":
            acc = np.where(spike, acc - 1.0, acc)
        else:
            acc = np.where(spike, 0.0, acc)
        if jitter > 0.0:
            z = normal_np(_pixel_bits_np(_readout_key_np(key_jitter, n), n_pix)).reshape(h, w)
            eps = jitter * z
            acc = np.where(spike, acc - np.sign(eps) * np.minimum(np.abs(eps), 0.5), acc)
    return np.packbits(out, axis=-1, bitorder="little")
