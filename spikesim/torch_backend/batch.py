"""Many small sensors at once on one device: :func:`simulate_batch`.

A training batch is ``B`` short streams of small sensors, each with its own
seed, Bayer phase and noise level.  :func:`simulate_batch` simulates them in
one set of tensor operations (the sample is a leading batch dimension of
:mod:`spikesim.torch_backend._core`), from key frames the caller rendered on
the same device, so a batch never leaves the device that trains on it.
Sample ``b`` has the bits of ``spikesim.simulate`` of the scene whose key
frames are ``frames[b]`` at ``key_readouts`` (a
:class:`spikesim.scenes.Keyframes` scene), on the sensor with pattern
``cfa[b]``, noise ``PaperNoise(sigma_g[b], sigma_p[b])`` (none when both are
0) and seed ``seeds[b]`` — with either backend.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import torch

from spikesim import rng as _keys
from spikesim._validate import check_int
from spikesim.cfa import normalize_cfa
from spikesim.errors import SpikeSimTypeError, bad_value
from spikesim.schedule import build_schedule, key_readout_times
from spikesim.torch_backend import _core, _rng
from spikesim.torch_backend._driver import TILE_ELEMENTS, _channel_map, mosaic

__all__ = ["simulate_batch"]


def _per_sample(name: str, value, b: int) -> list:
    if isinstance(value, str | bytes) or value is None or not isinstance(value, Sequence):
        return [value] * b
    values = list(value)
    if len(values) != b:
        raise bad_value(name, f"{len(values)} values", f"one value, or one per sample ({b})")
    return values


def _sigmas(name: str, value, b: int) -> list[float]:
    out = []
    for v in _per_sample(name, value, b):
        try:
            f = float(v)
        except (TypeError, ValueError):
            raise bad_value(name, v, "noise levels in 8-bit DN, finite and >= 0") from None
        if not (math.isfinite(f) and f >= 0):
            raise bad_value(name, v, "noise levels in 8-bit DN, finite and >= 0")
        out.append(f)
    return out


def simulate_batch(frames: torch.Tensor, key_readouts, n_readouts: int, seeds, cfa="RGGB",
                   sigma_g=0.0, sigma_p=0.0, *, full_scale_rate: float = 0.6,
                   reset: str = "modulo", init: str = "uniform") -> torch.Tensor:
    """Simulate ``B`` sensors viewing ``B`` key-frame scenes; spikes on ``frames``' device.

    Parameters
    ----------
    frames : (B, K, 3, H, W) float tensor
        Linear RGB radiance (relative, 1 = full scale; finite, ≥ 0) of each
        sample at the ``K`` key times; linear in time between them, held
        outside (docs/model.md).
    key_readouts : sequence of K floats
        Key times in readout units (readout ``n`` integrates ``[n, n+1)``),
        strictly increasing, shared by the samples.
    n_readouts : int
        Readouts ``0 … n_readouts − 1`` to simulate.
    seeds : sequence of B ints
        Seed of each sample (initial accumulator and noise), in [0, 2⁶⁴).
    cfa : str or None, or a sequence of B of them
        Bayer pattern per sample (``"RGGB"``, ``"BGGR"``, ``"GRBG"``, ``"GBRG"``;
        None for a monochrome sensor).
    sigma_g, sigma_p : float or sequence of B floats
        Paper-mode noise (eq. 5 of Dong et al., AAAI 2024) per sample, 8-bit DN.
    full_scale_rate : float
        Spikes per readout at radiance 1.
    reset : {"modulo", "subtract", "zero"}
    init : {"uniform", "zero"}
        Initial accumulator.

    Returns
    -------
    (B, n_readouts, H, W) bool tensor
    """
    if not isinstance(frames, torch.Tensor) or not frames.is_floating_point():
        raise SpikeSimTypeError("frames must be a floating-point torch tensor (B, K, 3, H, W)")
    if frames.ndim != 5 or frames.shape[2] != 3 or min(frames.shape) < 1:
        raise bad_value("frames.shape", tuple(frames.shape), "(B, K, 3, H, W) with every size >= 1")
    b, k, _, h, w = frames.shape
    t_total = check_int("n_readouts", n_readouts, 1)
    kr = np.asarray(key_readouts, dtype=np.float64).ravel()
    if kr.size != k or not np.all(np.isfinite(kr)) or (k > 1 and not np.all(np.diff(kr) > 0)):
        raise bad_value("key_readouts", kr.tolist()[:8],
                        f"{k} finite, strictly increasing times in readouts (one per key frame)")
    tau = key_readout_times(kr, 1.0)  # near-integer times snapped, as the simulator does
    if not bool(torch.isfinite(frames).all()) or float(frames.min()) < 0:
        raise bad_value("frames", "values out of range", "finite, non-negative linear radiance")
    seeds = [check_int("seeds[i]", s, 0, 2**64 - 1) for s in _per_sample("seeds", seeds, b)]
    cfas = [normalize_cfa(c) for c in _per_sample("cfa", cfa, b)]
    sg, sp = _sigmas("sigma_g", sigma_g, b), _sigmas("sigma_p", sigma_p, b)
    if reset not in ("modulo", "subtract", "zero"):
        raise bad_value("reset", reset, "'modulo', 'subtract' or 'zero'")
    if init not in ("uniform", "zero"):
        raise bad_value("init", init, "'uniform' or 'zero'")
    rate = float(full_scale_rate)
    if not (math.isfinite(rate) and rate > 0):
        raise bad_value("full_scale_rate", full_scale_rate, "spikes per readout > 0")

    dev = frames.device
    chan = torch.stack([_channel_map(c, h, w, dev) for c in cfas])  # (B, H, W)
    sensor_frames = mosaic(frames, chan[:, None])  # (B, K, H, W) float32
    pkeys = _rng.pixel_keys(h, w, dev)
    model = _core.AccumulatorModel(gain=rate, offset=0.0, reset=reset)
    if any(sg) or any(sp):
        model.noisy = True
        model.sg2 = torch.tensor([s**2 for s in sg], dtype=torch.float64,
                                 device=dev).view(b, 1, 1, 1)
        model.sp2 = torch.tensor([s**2 for s in sp], dtype=torch.float64,
                                 device=dev).view(b, 1, 1, 1)
        model.key_paper = _core.stream_keys(seeds, _keys.STREAM_PAPER, dev)
    state = _core.initial_state(_core.stream_keys(seeds, _keys.STREAM_INIT, dev), pkeys,
                                init == "uniform")
    sched = build_schedule(tau, 0, t_total)
    tile = max(1, TILE_ELEMENTS.get(dev.type, TILE_ELEMENTS["cpu"]) // (b * h * w))
    out = torch.empty((b, t_total, h, w), dtype=torch.bool, device=dev)
    for t0 in range(0, t_total, tile):
        t1 = min(t_total, t0 + tile)
        level = _core.mean_radiance(sensor_frames, sched, t0, t1)
        readouts = torch.arange(t0, t1, dtype=torch.int64, device=dev)
        state, out[:, t0:t1] = _core.advance(state, level, model, readouts, pkeys)
    return out
