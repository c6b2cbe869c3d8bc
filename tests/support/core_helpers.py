"""Small shared helpers for the core tests."""

from __future__ import annotations

import numpy as np

import spikesim as ss
from spikesim.scenes.keyframes import Keyframes


def flat_rows(levels, width: int) -> np.ndarray:
    """(len(levels), width, 3) image whose row i has radiance levels[i] everywhere."""
    levels = np.asarray(levels, dtype=np.float32)
    return np.repeat(np.repeat(levels[:, None, None], width, axis=1), 3, axis=2)


def counts(scene, sensor, n_readouts, seed=0, chunk=4096, clean=False) -> np.ndarray:
    """Per-pixel spike counts of a simulation, streamed chunk by chunk."""
    total = np.zeros(sensor.shape, np.int64)
    run = ss.simulate_chunks(scene, sensor, n_readouts, seed=seed, chunk_readouts=chunk,
                             clean_twin=clean)
    for ch in run:
        src = ch.clean_packed if clean else ch.packed
        total += ss.bits.unpack(src, sensor.width).sum(axis=0, dtype=np.int64)
    return total


def initial_fraction(sensor, seed) -> np.ndarray:
    """The exact initial accumulator (units of 2**-64 θ) as Python ints, (H, W) object array."""
    from spikesim import _kernels, rng

    wp = 64 * ((sensor.width + 63) // 64)
    frac = _kernels.init_state(rng.stream_key(seed, rng.STREAM_INIT), sensor.height,
                               sensor.width, wp, sensor.init == "uniform")[:, : sensor.width]
    return frac


__all__ = ["flat_rows", "counts", "initial_fraction", "Keyframes"]
