"""Spike streams: the in-memory stream and chunk types, the ``SpikeSource`` protocol every
reader satisfies, and the one routine that counts spikes per pixel.

A *spike source* is anything that hands out windows of unpacked readouts:
the in-memory :class:`SpikeStream`, a spikesim HDF5 sequence
(:class:`spikesim.io.Sequence`), a PKU ``.dat`` capture
(:class:`spikesim.io.DatFile`) and the analysis view of a capture
(:class:`spikesim.analysis.capture.Capture`).  Code that only reads spikes
takes a :class:`SpikeSource` and works on all of them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from spikesim._validate import check_window
from spikesim.bits import unpack
from spikesim.errors import bad_value
from spikesim.sensor import Sensor

__all__ = ["SpikeSource", "SpikeStream", "SpikeChunk", "pixel_counts", "BLOCK_READOUTS"]

#: Readouts read at a time when a source is scanned (bounded memory).
BLOCK_READOUTS = 256


@runtime_checkable
class SpikeSource(Protocol):
    """What every spike reader offers (shape, colour filter, clock, metadata, windows).

    Attributes
    ----------
    n_readouts, height, width : int
    cfa : str or None
        Bayer pattern (``None``: monochrome or unknown).
    clock_hz : float or None
        Readouts per second, when known.
    meta : dict
        What the source records about itself (sensor, scene, seed, file, ...).
    """

    n_readouts: int
    height: int
    width: int
    cfa: str | None
    clock_hz: float | None
    meta: dict

    def read_window(self, start: int = 0, length: int | None = None) -> np.ndarray:
        """(length, H, W) uint8 0/1 readouts ``[start, start + length)``."""
        ...


def pixel_counts(source: SpikeSource, start: int = 0, stop: int | None = None,
                 block: int = BLOCK_READOUTS,
                 read: Callable[[int, int], np.ndarray] | None = None,
                 progress: bool = False) -> np.ndarray:
    """(H, W) int64 spikes of each pixel over readouts ``[start, stop)`` of ``source``.

    Reads ``block`` readouts at a time, so memory stays bounded for streams of
    any length.  ``read(start, length)`` replaces ``source.read_window`` (e.g.
    to count a clean twin).

    Examples
    --------
    >>> import numpy as np
    >>> from spikesim.stream import pixel_counts
    >>> class Flat:  # any object with the SpikeSource attributes
    ...     n_readouts, height, width, cfa, clock_hz, meta = 10, 1, 2, None, None, {}
    ...     def read_window(self, start=0, length=None):
    ...         return np.ones((length, 1, 2), np.uint8)
    >>> pixel_counts(Flat(), block=3).tolist()
    [[10, 10]]
    """
    read = read or source.read_window
    stop = source.n_readouts if stop is None else min(int(stop), source.n_readouts)
    counts = np.zeros((source.height, source.width), np.int64)
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=max(stop - start, 0), desc="count", unit="readout", leave=False)
    for t0 in range(int(start), stop, block):
        n = min(block, stop - t0)
        counts += np.asarray(read(t0, n)).sum(axis=0, dtype=np.int64)
        if bar is not None:
            bar.update(n)
    if bar is not None:
        bar.close()
    return counts


@dataclass
class SpikeChunk:
    """Consecutive readouts ``[start, start + len(packed))`` of a simulation."""

    start: int
    packed: np.ndarray
    clean_packed: np.ndarray | None
    gt: np.ndarray
    gt_index: np.ndarray


@dataclass
class SpikeStream:
    """A simulated (or loaded) spike stream with its ground truth and metadata.

    Attributes
    ----------
    packed : (T, H, ceil(W/8)) uint8
        Spike bits, packed along W, little bit order (docs/architecture.md, Conventions).
    meta : dict
        JSON-able description: sensor, scene, seed, clock_hz, cfa, height,
        width, n_readouts, start_readout, clean_twin, spikesim_version, bitorder.
    clean_packed : same shape as ``packed`` or None
        The noise-free twin (same seed and initial state, every noise source off).
    gt : (K, H, W, 3) float32
        Linear RGB radiance at the middle of readouts ``gt_index``.
    gt_index : (K,) int64
        Readout index of each ground-truth frame.
    """

    packed: np.ndarray
    meta: dict
    clean_packed: np.ndarray | None = None
    gt: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0, 3), np.float32))
    gt_index: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    @property
    def n_readouts(self) -> int:
        return int(self.packed.shape[0])

    @property
    def height(self) -> int:
        return int(self.meta["height"])

    @property
    def width(self) -> int:
        return int(self.meta["width"])

    @property
    def cfa(self) -> str | None:
        return self.meta.get("cfa")

    @property
    def clock_hz(self) -> float:
        return float(self.meta["clock_hz"])

    @property
    def seed(self) -> int:
        return int(self.meta["seed"])

    @property
    def sensor(self) -> Sensor:
        return Sensor.from_dict(self.meta["sensor"])

    def unpack(self, clean: bool = False, start: int = 0, stop: int | None = None) -> np.ndarray:
        """(T, H, W) uint8 0/1 spikes of readouts ``[start, stop)``."""
        src = self.clean_packed if clean else self.packed
        if src is None:
            raise bad_value("clean", clean, "False: this stream has no clean twin")
        return unpack(src[start:stop], self.width)

    def read_window(self, start: int = 0, length: int | None = None,
                    clean: bool = False) -> np.ndarray:
        """(length, H, W) uint8 0/1 spikes of readouts ``[start, start + length)`` (default:
        to the end): the :class:`SpikeSource` protocol."""
        start, length = check_window(start, length, self.n_readouts)
        return self.unpack(clean, start, start + length)

    def firing_rate(self, clean: bool = False) -> np.ndarray:
        """(H, W) mean spikes per readout of each pixel."""
        read = (lambda s, n: self.read_window(s, n, clean=True)) if clean else None
        return pixel_counts(self, read=read) / max(self.n_readouts, 1)
