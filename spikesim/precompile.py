"""Compile kernel families into numba's cache ahead of use (``spikesim compile``)."""

from __future__ import annotations

import time
from collections.abc import Iterable

import numpy as np

from spikesim import noise as noise_models
from spikesim.families import FAMILIES, RESETS, family_markers, kernel_name
from spikesim.scenes import Static, procedural
from spikesim.sensor import Sensor
from spikesim.simulate import simulate

__all__ = ["precompile"]


def precompile(names: Iterable[str] | None = None, progress=None,
               resets: Iterable[str] = RESETS) -> dict[str, float]:
    """Compile the kernels of families ``names`` (all when None) into numba's
    cache by simulating a tiny sensor of each, moving and static, mono and
    RGGB (the same argument types as any run, so later runs load them); the
    physical family for each reset mode of ``resets`` (its kernels are
    compiled per reset mode, :func:`spikesim.families.kernel_name`).
    Returns seconds per kernel name; ``progress(name, seconds)`` is called
    after each."""
    chosen = list(FAMILIES) if names is None else [n for n in names]
    for name in chosen:
        family_markers(name)  # validates
    resets = list(resets)
    for reset in resets:
        kernel_name("physical", reset)  # validates
    models = {"noise-free": None, "paper": noise_models.PaperNoise(sigma_g=5.0, sigma_p=1.0),
              "physical": noise_models.PhysicalNoise(),
              "charge": noise_models.PhysicalNoise(charge_noise_electrons=1.0)}
    times = {}
    for family in chosen:
        for reset in (resets if family == "physical" else RESETS[:1]):  # (no matter which)
            name = kernel_name(family, reset)
            t0 = time.perf_counter()
            for cfa in ("RGGB", None):
                sensor = Sensor(height=16, width=16, cfa=cfa, noise=models[family], reset=reset)
                moving = procedural("astronaut", motion="pan", size=(16, 16))
                static = Static(np.full((16, 16, 3), 0.5, np.float32))
                for scene in (moving, static):
                    simulate(scene, sensor, n_readouts=8, seed=0, clean_twin=True)
            times[name] = time.perf_counter() - t0
            if progress is not None:
                progress(name, times[name])
    return times
