"""Flat-field simulations shared by the characterisation studies.

A flat field of radiance ``level`` (``spikesim.scenes.procedural("flat")``)
is simulated on a copy of the sensor resized to ``size``; the per-pixel charge
``q_i = gain_i·level + offset_i`` (thresholds per readout, from
:func:`spikesim.noise.fixed_pattern`) is returned with it so that every study
can compare the measured statistics with the model's own prediction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import spikesim as ss
from spikesim._validate import check_size
from spikesim.errors import SpikeSimTypeError, bad_value
from spikesim.noise import fixed_pattern

__all__ = ["FlatRun", "simulate_flat", "check_levels", "check_sensor"]


@dataclass
class FlatRun:
    """One flat-field simulation: spikes (T, H, W) uint8 and per-pixel charge q (H, W)."""

    level: float
    spikes: np.ndarray
    q: np.ndarray
    clean: np.ndarray | None = None


def check_sensor(sensor) -> ss.Sensor:
    if isinstance(sensor, str):
        return ss.Sensor.preset(sensor)
    if not isinstance(sensor, ss.Sensor):
        raise SpikeSimTypeError(f"sensor must be a spikesim.Sensor or a preset name, "
                                f"got {type(sensor).__name__}")
    return sensor


def check_levels(levels, name: str = "levels") -> np.ndarray:
    arr = np.asarray(levels, dtype=np.float64).ravel()
    if arr.size == 0 or not np.all(np.isfinite(arr)) or np.any(arr < 0):
        raise bad_value(name, levels, "one or more finite radiances >= 0 (1 = full scale)")
    return arr


def simulate_flat(sensor: ss.Sensor, level: float, n_readouts: int, seed: int = 0,
                  size: tuple[int, int] = (32, 32), clean_twin: bool = False) -> FlatRun:
    """Simulate a flat field of radiance ``level`` (linear, 1 = full scale)."""
    h, w = check_size(size)
    sen = sensor.replace(height=h, width=w)
    scene = ss.scenes.procedural("flat", size=(h, w), level=float(level))
    stream = ss.simulate(scene, sen, n_readouts, seed=seed, clean_twin=clean_twin)
    pat = fixed_pattern(sen.noise, h, w, sen.full_scale_rate)
    lvl = float(np.float32(level))  # the scene stores float32 radiance
    q = pat.gain * lvl + pat.offset
    clean = stream.unpack(clean=True) if clean_twin else None
    return FlatRun(float(level), stream.unpack(), q, clean)
