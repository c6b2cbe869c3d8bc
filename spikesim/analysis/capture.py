"""Uniform, block-wise access to a spike capture (array, stream, ``.dat`` or HDF5).

Every analysis reads its input through :class:`Capture`, so the same code
serves a simulated :class:`~spikesim.SpikeStream`, an in-memory ``(T, H, W)``
0/1 array, a PKU ``.dat`` file and a spikesim HDF5 file, reading at most
``block`` readouts at a time (bounded memory for long captures).

Two streaming statistics live here because every study needs them:

* :func:`pixel_counts` — spikes per pixel over readouts ``[start, stop)``
  (:func:`spikesim.stream.pixel_counts`, the one counting routine, at this
  module's block size);
* :func:`pixel_intervals` — inter-spike-interval moments per pixel (count,
  sum, sum of squares of the intervals in readouts, between consecutive
  spikes only; the open intervals at the ends are never counted) and,
  optionally, the intervals themselves for selected pixels.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from spikesim._validate import check_window
from spikesim.cfa import normalize_cfa
from spikesim.errors import SpikeSimTypeError, bad_value
from spikesim.stream import pixel_counts as stream_pixel_counts

__all__ = ["Capture", "as_capture", "pixel_counts", "pixel_intervals", "IntervalMoments"]

#: Readouts decoded per block by the streaming statistics.
BLOCK_READOUTS = 1024


class Capture:
    """A read-only view of a spike capture as ``(T, H, W)`` 0/1 readouts.

    Attributes
    ----------
    n_readouts, height, width : int
    cfa : str or None
        Bayer pattern when known (``None`` = monochrome or unknown).
    cfa_known : bool
        Whether the source records its colour filter (a simulated stream, an
        HDF5 file, a ``.dat`` opened with a ``cfa``), so that ``cfa=None``
        means monochrome rather than unknown.
    clock_hz : float or None
        Readout clock when known.
    meta : dict
        Whatever the source records (sensor configuration of a simulation, ...).
    """

    def __init__(self, reader, n_readouts: int, height: int, width: int, cfa=None,
                 clock_hz=None, meta=None, name: str = "capture", cfa_known: bool = False):
        self._reader = reader
        self.n_readouts, self.height, self.width = int(n_readouts), int(height), int(width)
        self.cfa = normalize_cfa(cfa)
        self.cfa_known = bool(cfa_known) or self.cfa is not None
        self.clock_hz = float(clock_hz) if clock_hz else None
        self.meta = dict(meta or {})
        self.name = name

    @property
    def shape(self) -> tuple[int, int, int]:
        return (self.n_readouts, self.height, self.width)

    def read(self, start: int, stop: int) -> np.ndarray:
        """Readouts ``[start, stop)`` as (stop − start, H, W) uint8 0/1."""
        start, stop = max(0, int(start)), min(self.n_readouts, int(stop))
        if stop <= start:
            return np.zeros((0, self.height, self.width), np.uint8)
        return np.asarray(self._reader(start, stop), dtype=np.uint8)

    def read_window(self, start: int = 0, length: int | None = None) -> np.ndarray:
        """Readouts ``[start, start + length)`` (default: to the end): the
        :class:`spikesim.SpikeSource` protocol."""
        start, length = check_window(start, length, self.n_readouts)
        return self.read(start, start + length)

    def blocks(self, start: int = 0, stop: int | None = None, block: int = BLOCK_READOUTS):
        """Yield ``(t0, spikes)`` for consecutive blocks of at most ``block`` readouts."""
        stop = self.n_readouts if stop is None else min(int(stop), self.n_readouts)
        for t0 in range(int(start), stop, block):
            yield t0, self.read(t0, min(t0 + block, stop))

    def require(self, n: int, what: str) -> None:
        """Raise unless the capture holds at least ``n`` readouts (needed for ``what``)."""
        if self.n_readouts < n:
            raise bad_value("capture length", f"{self.n_readouts} readouts",
                            f"at least {n} readouts for {what}")


def as_capture(source, *, height: int | None = None, width: int | None = None,
               flip: bool = True, cfa: str | None = None,
               clock_hz: float | None = None) -> Capture:
    """Wrap ``source`` as a :class:`Capture`.

    ``source`` may be a ``Capture``, a ``SpikeStream``, a ``(T, H, W)`` 0/1
    array, an object with ``read_window`` (``DatFile``, HDF5 ``Sequence``), or a
    path to a ``.dat`` file (``height``/``width``/``flip`` apply) or a spikesim
    HDF5 file or folder.  ``cfa``/``clock_hz`` override what the source says
    (a ``cfa`` given, ``"mono"`` included, makes the colour filter known).
    """
    if isinstance(source, Capture):
        return source
    given = cfa is not None
    if isinstance(source, (str, os.PathLike)):
        from spikesim.io.source import open_source

        source = open_source(source, height=height, width=width, flip=flip, cfa=cfa,
                             clock_hz=clock_hz)
    if isinstance(source, np.ndarray):
        arr = source
        if arr.ndim != 3:
            raise bad_value("capture.shape", arr.shape, "a 3-D (T, H, W) array of 0/1 readouts")
        if arr.dtype != np.bool_ and arr.dtype.kind not in "iu":
            raise SpikeSimTypeError(f"capture must be bool or integer 0/1, got dtype {arr.dtype}")
        if 0 in arr.shape:
            raise bad_value("capture.shape", arr.shape, "T, H, W >= 1")
        return Capture(lambda a, b: arr[a:b], *arr.shape, cfa=cfa, clock_hz=clock_hz,
                       name="array", cfa_known=given)
    if hasattr(source, "unpack") and hasattr(source, "packed"):  # SpikeStream
        meta = dict(source.meta)
        return Capture(lambda a, b: source.unpack(start=a, stop=b), source.n_readouts,
                       source.height, source.width, cfa=cfa or source.cfa,
                       clock_hz=clock_hz or source.clock_hz, meta=meta, name="stream",
                       cfa_known=True)
    if hasattr(source, "read_window"):
        from spikesim.io.dat import DatFile

        meta = dict(getattr(source, "meta", {}) or {})
        # a .dat records no colour filter (only what it was opened with); HDF5 always does
        known = given or not isinstance(source, DatFile)
        return Capture(lambda a, b: source.read_window(a, b - a), source.n_readouts,
                       source.height, source.width, cfa=cfa or getattr(source, "cfa", None),
                       clock_hz=clock_hz or getattr(source, "clock_hz", None), meta=meta,
                       name=str(getattr(source, "name", "capture")), cfa_known=known)
    raise SpikeSimTypeError(
        "capture must be a (T, H, W) array, a SpikeStream, a DatFile/Sequence or a path, "
        f"got {type(source).__name__}")


def pixel_counts(cap: Capture, start: int = 0, stop: int | None = None,
                 progress: bool = False) -> np.ndarray:
    """(H, W) int64 spikes of each pixel over readouts ``[start, stop)``."""
    stop = cap.n_readouts if stop is None else stop
    return stream_pixel_counts(cap, start, stop, BLOCK_READOUTS,
                               read=lambda t, n: cap.read(t, t + n), progress=progress)


@dataclass
class IntervalMoments:
    """Per-pixel inter-spike-interval moments (intervals in readouts).

    ``n``, ``s1``, ``s2`` are (H, W): number of closed intervals, their sum and
    their sum of squares; ``first``/``last`` the first and last spike readout
    (−1 when the pixel never fired); ``nd``, ``d2`` the number of successive
    interval differences ``I[k+1] − I[k]`` and the sum of their squares
    (:meth:`local_var`).  ``samples`` maps a label to a 1-D int64
    array of the intervals of the pixels selected for it.
    """

    n: np.ndarray
    s1: np.ndarray
    s2: np.ndarray
    first: np.ndarray
    last: np.ndarray
    samples: dict
    nd: np.ndarray | None = None
    d2: np.ndarray | None = None

    def mean(self) -> np.ndarray:
        """(H, W) mean interval (NaN where no interval)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self.n > 0, self.s1 / np.maximum(self.n, 1), np.nan)

    def var(self) -> np.ndarray:
        """(H, W) unbiased interval variance (NaN where fewer than 2 intervals)."""
        n = self.n.astype(np.float64)
        with np.errstate(invalid="ignore", divide="ignore"):
            v = (self.s2 - self.s1**2 / np.maximum(n, 1)) / np.maximum(n - 1, 1)
        return np.where(self.n > 1, np.maximum(v, 0.0), np.nan)

    def local_var(self) -> np.ndarray:
        """(H, W) half the mean squared difference of successive intervals,
        ``Σ(I[k+1] − I[k])²/(2·nd)`` (readouts²; NaN where no difference): the
        interval variance without the slow changes of the pixel's mean interval
        that moving light brings (its rounding term differs from :meth:`var`'s:
        :func:`spikesim.analysis.theory.local_frac_term`)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self.nd > 0, self.d2 / (2 * np.maximum(self.nd, 1)), np.nan)


def pixel_intervals(cap: Capture, start: int = 0, stop: int | None = None,
                    keep: dict | None = None, max_samples: int = 2_000_000,
                    progress: bool = False) -> IntervalMoments:
    """Stream the capture once and return :class:`IntervalMoments`.

    Parameters
    ----------
    keep : dict of label → (H, W) bool mask, optional
        Pixels whose individual intervals are returned in ``samples[label]``
        (at most ``max_samples`` per label, the first ones in time order of
        the blocks).
    """
    h, w = cap.height, cap.width
    npx = h * w
    n = np.zeros(npx, np.int64)
    s1 = np.zeros(npx, np.float64)
    s2 = np.zeros(npx, np.float64)
    first = np.full(npx, -1, np.int64)
    last = np.full(npx, -1, np.int64)
    last_iv = np.full(npx, -1, np.int64)  # each pixel's latest interval (-1: none yet)
    nd = np.zeros(npx, np.int64)
    d2 = np.zeros(npx, np.float64)
    keep = keep or {}
    keep_flat = {k: np.asarray(m, bool).ravel() for k, m in keep.items()}
    samples: dict[str, list] = {k: [] for k in keep}
    kept = dict.fromkeys(keep, 0)
    stop = cap.n_readouts if stop is None else stop
    bar = _bar(progress, stop - start, "intervals")
    for t0, blk in cap.blocks(start, stop):
        flat = blk.reshape(blk.shape[0], npx).T  # (pixels, time)
        pix, t = np.nonzero(flat)
        if pix.size:
            t = t.astype(np.int64) + t0
            prev = np.empty_like(t)
            prev[1:] = t[:-1]
            same = np.zeros(pix.size, bool)
            same[1:] = pix[1:] == pix[:-1]
            # first spike of each pixel in this block continues from `last`
            head = ~same
            prev[head] = last[pix[head]]
            valid = same | (prev >= 0)
            iv = (t - prev)[valid]
            pv = pix[valid]
            n += np.bincount(pv, minlength=npx)
            s1 += np.bincount(pv, weights=iv, minlength=npx)
            s2 += np.bincount(pv, weights=iv.astype(np.float64) ** 2, minlength=npx)
            if iv.size:  # successive differences, continuing from each pixel's last interval
                before = np.empty_like(iv)
                before[1:] = iv[:-1]
                cont = np.zeros(iv.size, bool)
                cont[1:] = pv[1:] == pv[:-1]
                before[~cont] = last_iv[pv[~cont]]
                ok = cont | (before >= 0)
                nd += np.bincount(pv[ok], minlength=npx)
                d2 += np.bincount(pv[ok], weights=(iv[ok] - before[ok]).astype(np.float64) ** 2,
                                  minlength=npx)
                end = np.ones(iv.size, bool)
                end[:-1] = pv[1:] != pv[:-1]
                last_iv[pv[end]] = iv[end]
            for k, m in keep_flat.items():
                if kept[k] < max_samples:
                    sel = iv[m[pv]][: max_samples - kept[k]]
                    samples[k].append(sel)
                    kept[k] += sel.size
            tail = np.ones(pix.size, bool)
            tail[:-1] = pix[1:] != pix[:-1]
            last[pix[tail]] = t[tail]
            newp = pix[head]
            unset = first[newp] < 0
            first[newp[unset]] = t[head][unset]
        if bar is not None:
            bar.update(blk.shape[0])
    if bar is not None:
        bar.close()
    out = {k: (np.concatenate(v) if v else np.zeros(0, np.int64)) for k, v in samples.items()}
    return IntervalMoments(n.reshape(h, w), s1.reshape(h, w), s2.reshape(h, w),
                           first.reshape(h, w), last.reshape(h, w), out, nd.reshape(h, w),
                           d2.reshape(h, w))


def _bar(enabled: bool, total: int, desc: str):
    if not enabled:
        return None
    from tqdm.auto import tqdm

    return tqdm(total=total, unit="readout", desc=desc)
