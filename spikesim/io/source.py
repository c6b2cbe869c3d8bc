"""Open any spike file the commands accept: a spikesim HDF5 file or folder, or a ``.dat``."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from spikesim.io.dat import DatFile
from spikesim.io.h5 import Sequence
from spikesim.io.index import open_dataset

__all__ = ["is_dat", "open_source", "firing_rate_stats"]


def is_dat(path: str | os.PathLike) -> bool:
    """True for a path named ``*.dat`` (PKU format), whatever its content."""
    return Path(path).suffix.lower() == ".dat"


def open_source(
    path: str | os.PathLike,
    sequence: str | int | None = None,
    height: int | None = None,
    width: int | None = None,
    flip: bool = True,
    head_columns: int = 0,
    cfa: str | None = None,
    clock_hz: float | None = None,
    partial: str = "error",
) -> DatFile | Sequence:
    """A :class:`DatFile` for ``*.dat``, else one :class:`Sequence` of a spikesim dataset.

    ``sequence`` picks a sequence of a multi-sequence dataset by name or
    position (default: the first).  The ``.dat`` options are ignored for HDF5.
    """
    if is_dat(path):
        return DatFile(path, height, width, flip=flip, head_columns=head_columns,
                       partial=partial, cfa=cfa, clock_hz=clock_hz)
    ds = open_dataset(path)
    return ds.sequence(0 if sequence is None else sequence)


def firing_rate_stats(src, max_readouts: int = 4096, block: int = 256) -> dict:
    """Spikes per readout of each pixel over the first ``max_readouts`` readouts, summarised.

    Reads ``block`` readouts at a time (bounded memory).  Returns the mean,
    min, 1st/99th percentile and max rate over pixels, and the fraction of
    pixels that never fired.
    """
    from spikesim.stream import pixel_counts

    n = max(1, min(src.n_readouts, int(max_readouts)))
    counts = pixel_counts(src, 0, n, block)
    rate = counts / n
    return {"readouts": n, "mean": float(rate.mean()), "min": float(rate.min()),
            "p01": float(np.percentile(rate, 1)), "p99": float(np.percentile(rate, 99)),
            "max": float(rate.max()), "silent_fraction": float((counts == 0).mean())}
