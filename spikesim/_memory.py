"""Memory the simulator reuses instead of allocating afresh.

A fresh array costs page faults on first touch: about 1.6 ms per 8 MB on the
2-core VM (filling a new 8 MB array took 2.3 ms, a reused one 0.7 ms), which
is a sizeable share of a short ``simulate`` call (the accumulator of a
1000×1000 sensor alone is 16 MB).  Two recyclers:

* :class:`RecycledOutput`, within one run: output arrays of successive chunks,
  handed out again once the consumer has let go of them;
* :class:`ArrayPool`, across runs: arrays private to a run (the accumulator
  state, the key-frame buffer), taken at its start and given back at its end,
  so repeated calls of one size (a training loader, a dataset worker) skip
  the page faults.  Concurrent runs each take their own arrays.
"""

from __future__ import annotations

import sys
import threading

import numpy as np

__all__ = ["ArrayPool", "RecycledOutput"]


class ArrayPool:
    """Arrays kept between runs, by shape and dtype, at most ``max_bytes`` in
    all (the oldest given back are dropped first); arrays under ``min_bytes``
    are not worth keeping.  Thread-safe."""

    def __init__(self, max_bytes: int, min_bytes: int = 1 << 16):
        self.max_bytes = int(max_bytes)
        self.min_bytes = int(min_bytes)
        self._free: list[np.ndarray] = []
        self._lock = threading.Lock()

    def take(self, shape: tuple[int, ...], dtype, zeros: bool = False) -> np.ndarray:
        """An array of ``shape`` and ``dtype``: one given back earlier (its content
        is whatever its last user left, so take it only where that content is
        overwritten, or was zero where it is read and never written), else a fresh
        one (``np.zeros`` when ``zeros``, else ``np.empty``)."""
        shape = tuple(int(n) for n in shape)
        dtype = np.dtype(dtype)
        with self._lock:
            for i, a in enumerate(self._free):
                if a.shape == shape and a.dtype == dtype:
                    return self._free.pop(i)
        return np.zeros(shape, dtype) if zeros else np.empty(shape, dtype)

    def give(self, *arrays: np.ndarray) -> None:
        """Keep ``arrays`` for later runs (the caller must not use them again)."""
        with self._lock:
            for a in arrays:
                if self.min_bytes <= a.nbytes <= self.max_bytes and a.flags.owndata:
                    self._free.append(a)
            while sum(a.nbytes for a in self._free) > self.max_bytes:
                self._free.pop(0)

    def clear(self) -> None:
        """Drop every kept array."""
        with self._lock:
            self._free.clear()


class RecycledOutput:
    """Output arrays for successive chunks, reused once the consumer lets go.

    A fresh array of tens of MB costs about 10 ms of page faults on first
    touch (measured on the 2-core VM), a sizeable share of a chunk's kernel
    time.  A consumer that drops each chunk before asking for the next (the
    streaming case: writing to a file, reducing) gets the same memory back;
    an array still referenced anywhere else (a kept chunk, or any view of
    it) is never handed out again.  At most ``keep`` arrays are remembered
    (four: a stream and its clean twin, for the chunk a `for` loop still
    holds and the one before).  With a ``pool``, fresh arrays come from it and
    :meth:`release` gives the unheld ones back at the end of the run.
    """

    def __init__(self, keep: int = 4, pool: ArrayPool | None = None):
        self.keep = keep
        self._pool = pool
        self._arrays: list[np.ndarray] = []

    def release(self, pool: ArrayPool) -> None:
        """At the end of a run: give ``pool`` the arrays nobody holds any more
        (a consumer that dropped every chunk leaves them all to a later run)."""
        free = [a for a in self._arrays if sys.getrefcount(a) == 3]  # list, a, argument
        self._arrays = []
        pool.give(*free)

    def get(self, shape: tuple[int, ...]) -> np.ndarray:
        """A uint8 array of ``shape`` that nobody else holds (its content is stale)."""
        for i in range(len(self._arrays)):
            # references: the list entry and getrefcount's argument, nothing else
            if self._arrays[i].shape == shape and sys.getrefcount(self._arrays[i]) == 2:
                return self._arrays[i]
        fresh = self._pool.take(shape, np.uint8) if self._pool is not None else np.empty(
            shape, np.uint8)
        self._arrays = [*self._arrays[-(self.keep - 1):], fresh] if self.keep > 1 else [fresh]
        return fresh
