"""spikesim: a physics-faithful simulator of Bayer integrate-and-fire spike cameras.

Public API (README.md, "Using the library"; docs/architecture.md)::

    import spikesim as ss
    sensor = ss.Sensor.preset("color-1000x1000-20k")
    stream = ss.simulate(ss.scenes.Static(image), sensor, n_readouts=1000, seed=0)
"""

# ruff: noqa: E402  (the numba cache is checked before any kernel module is imported)
from pathlib import Path as _Path

from spikesim._numba_cache import sync_cache as _sync_cache

_sync_cache(_Path(__file__).parent)  # before any kernel module loads its cache

from spikesim import bits, cfa, io, noise, scenes, workload
from spikesim._version import __version__
from spikesim.errors import (
    SpikeSimError,
    SpikeSimFileError,
    SpikeSimFormatError,
    SpikeSimTypeError,
    SpikeSimValueError,
)
from spikesim.ideal import ideal_spike_times
from spikesim.sensor import Sensor, list_presets
from spikesim.simulate import SimulationRun, simulate, simulate_chunks
from spikesim.stream import SpikeChunk, SpikeSource, SpikeStream, pixel_counts
from spikesim.workload import RunawayWorkWarning

__all__ = [
    "__version__",
    "Sensor",
    "list_presets",
    "simulate",
    "simulate_chunks",
    "SimulationRun",
    "SpikeStream",
    "SpikeChunk",
    "SpikeSource",
    "pixel_counts",
    "ideal_spike_times",
    "bits",
    "io",
    "cfa",
    "noise",
    "scenes",
    "workload",
    "RunawayWorkWarning",
    "SpikeSimError",
    "SpikeSimValueError",
    "SpikeSimTypeError",
    "SpikeSimFileError",
    "SpikeSimFormatError",
]
