"""CRC-32 of every chunk of a spikesim HDF5 file's datasets (format version 2).

HDF5's Fletcher-32 filter sums 16-bit words modulo 65535, so it cannot tell
the word 0x0000 from 0xFFFF: a run of saturated spikes (0xFF bytes) read back
as zeros, or the reverse, passes it.  Format version 2 therefore stores, for
each dataset of :data:`CHECKED`, a companion ``<name>_crc32`` dataset: one
CRC-32 (ISO-HDLC, ``zlib.crc32``) per chunk of the dataset's *uncompressed*
data, the chunk's bytes in C order, an edge chunk only over its part inside
the dataset (no padding).  CRC-32 detects every error burst of up to 32 bits
(so every changed 16-bit word, whatever its value) and all but about 2⁻³² of
the rest.  The companion's shape is the chunk grid (chunks along each axis).

:class:`ChunkSums` computes them while a writer appends (the data as given,
before compression: an end-to-end check), :class:`ChunkCheck` compares them
while a reader reads, each chunk once per open file.
"""

from __future__ import annotations

import zlib

import h5py
import numpy as np

from spikesim.errors import SpikeSimFormatError

__all__ = ["CHECKED", "SUMS_SUFFIX", "ChunkSums", "ChunkCheck", "chunk_grid", "chunk_crc",
           "sums_name"]

#: Datasets that carry chunk CRCs in format version 2 (``clean_spikes`` when present).
CHECKED = ("spikes", "clean_spikes", "gt", "gt_index")
SUMS_SUFFIX = "_crc32"


def sums_name(name: str) -> str:
    """The companion dataset of ``name``'s chunk CRCs."""
    return name + SUMS_SUFFIX


def chunk_grid(shape: tuple, chunks: tuple) -> tuple:
    """Chunks along each axis of a dataset of ``shape`` in chunks of ``chunks``."""
    return tuple(int(n) for n in -(-np.asarray(shape, np.int64) // np.asarray(chunks, np.int64)))


def chunk_crc(block: np.ndarray) -> int:
    """CRC-32 of one chunk's data (C order; copied only when not contiguous)."""
    return zlib.crc32(np.ascontiguousarray(block).data)


def _box(index, chunks: np.ndarray, shape: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """First and one-past-last element, along each axis, of the chunk at grid ``index``."""
    lo = np.asarray(index, np.int64) * chunks
    return lo, np.minimum(lo + chunks, shape)


def _slices(lo, hi) -> tuple:
    return tuple(slice(int(a), int(b)) for a, b in zip(lo, hi, strict=True))


class ChunkSums:
    """The CRCs of a dataset written by appending along axis 0.

    ``feed`` the appended rows in order (any number at a time); rows of a chunk
    not yet complete are kept (copied: the caller may reuse its buffer) until
    it is; :meth:`result` adds the last, partial chunk and returns the grid
    (uint32)."""

    def __init__(self, shape_tail: tuple, chunks: tuple):
        self.tail = tuple(int(s) for s in shape_tail)
        self.chunks = tuple(int(c) for c in chunks)
        self._pending: list[np.ndarray] = []
        self._pending_rows = 0
        self._rows: list[np.ndarray] = []

    def feed(self, arr: np.ndarray) -> None:
        c0 = self.chunks[0]
        n = arr.shape[0]
        i = 0
        if self._pending_rows:
            take = min(c0 - self._pending_rows, n)
            self._pending.append(np.array(arr[:take]))
            self._pending_rows += take
            i = take
            if self._pending_rows == c0:
                self._sum(np.concatenate(self._pending))
                self._pending, self._pending_rows = [], 0
        while n - i >= c0:
            self._sum(arr[i:i + c0])
            i += c0
        if i < n:
            self._pending.append(np.array(arr[i:]))
            self._pending_rows += n - i

    def _sum(self, block: np.ndarray) -> None:
        chunks, shape = np.asarray(self.chunks[1:]), np.asarray(self.tail)
        grid = np.empty(chunk_grid(self.tail, self.chunks[1:]), np.uint32)
        for index in np.ndindex(*grid.shape):
            lo, hi = _box(index, chunks, shape)
            grid[index] = chunk_crc(block[(slice(None), *_slices(lo, hi))])
        self._rows.append(grid)

    def result(self) -> np.ndarray:
        if self._pending_rows:
            self._sum(np.concatenate(self._pending))
            self._pending, self._pending_rows = [], 0
        shape = (len(self._rows), *chunk_grid(self.tail, self.chunks[1:]))
        return np.stack(self._rows) if self._rows else np.zeros(shape, np.uint32)


class ChunkCheck:
    """Compares the chunks a reader reads of one dataset with their stored CRCs.

    :meth:`check` takes a region just read (its start along each axis and the
    data): every chunk inside it is checked from that data, every chunk it
    only touches is read whole once and checked; a chunk checked once is not
    checked again.  A mismatch raises :class:`SpikeSimFormatError` naming the
    file, the dataset and the chunk."""

    def __init__(self, ds: h5py.Dataset, sums: np.ndarray, path):
        self.ds = ds
        self.name = ds.name.lstrip("/")
        self.shape = np.asarray(ds.shape, np.int64)
        self.chunks = np.asarray(ds.chunks, np.int64)
        self.sums = sums
        self.path = path
        self.done = np.zeros(sums.shape, bool)

    def check(self, starts: tuple, data: np.ndarray) -> None:
        starts = np.asarray(starts, np.int64)
        stops = starts + np.asarray(data.shape, np.int64)
        first, last = starts // self.chunks, -(-stops // self.chunks)
        if self.done[_slices(first, last)].all():
            return
        for offset in np.ndindex(*(last - first)):
            index = tuple(int(i) for i in first + offset)
            if self.done[index]:
                continue
            lo, hi = _box(index, self.chunks, self.shape)
            if (lo >= starts).all() and (hi <= stops).all():  # inside the data read
                block = data[_slices(lo - starts, hi - starts)]
            else:  # only touched: read it whole (from HDF5's chunk cache, usually)
                block = self.ds[_slices(lo, hi)]
            if chunk_crc(block) != int(self.sums[index]):
                raise self.damage(index, lo, hi)
            self.done[index] = True

    def damage(self, index: tuple, lo, hi) -> SpikeSimFormatError:
        names = _AXES.get(self.name, tuple(f"axis {k}" for k in range(len(lo))))
        where = ", ".join(f"{n} {int(a)}–{int(b) - 1}" for n, a, b in zip(names, lo, hi,
                                                                           strict=True))
        return SpikeSimFormatError(
            f"{str(self.path)!r}: damaged data in its {self.name} (chunk "
            f"{', '.join(map(str, index))}: {where}) fails its CRC-32: restore or regenerate "
            "the file")


#: What the axes of the checked datasets count (for the damage message).
_AXES = {"spikes": ("readouts", "rows", "bytes"), "clean_spikes": ("readouts", "rows", "bytes"),
         "gt": ("frames", "rows", "columns", "channels"), "gt_index": ("entries",)}
