"""The lazy reader of spikesim HDF5 files (layout and checks: :mod:`spikesim.io.h5.format`).

Readers open the file lazily and reopen it after a fork, and a
:class:`Sequence` pickles without its handle, so it is safe to hand to
spawned or forked worker processes.  Every chunk read of a format-version-2
file is compared with its stored CRC-32 (:mod:`spikesim.io.h5.sums`), once per
open file; version-1 files have HDF5's Fletcher-32 only.
"""

from __future__ import annotations

import os
from pathlib import Path

import h5py
import numpy as np

from spikesim._validate import check_crop, check_window, is_int
from spikesim.bits import crop_packed
from spikesim.errors import SpikeSimFileError, SpikeSimFormatError, bad_value
from spikesim.io._checks import check_flag
from spikesim.io._compression import have_hdf5plugin
from spikesim.io.h5.format import READ_CACHE_BYTES, header_of, sums_dataset
from spikesim.io.h5.sums import ChunkCheck

__all__ = ["Sequence", "open_h5", "read_h5", "read_header"]


_VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v", ".gif")


def _describe_open_error(path: Path, exc: Exception) -> SpikeSimFormatError:
    text = str(exc)
    if "signature" in text:
        why = "not an HDF5 file (no HDF5 signature)"
        if path.suffix.lower() in _VIDEO_SUFFIXES:
            why += (f"; a video is turned into spikes first: spikesim simulate {path.name} "
                    "--out spikes.h5")
    elif "truncat" in text or "eof" in text.lower():
        why = "a truncated HDF5 file (shorter than its header says: an interrupted copy?)"
    else:
        why = f"not a readable HDF5 file ({text})"
    return SpikeSimFormatError(f"{str(path)!r} is {why}")


class Sequence:
    """One spikesim HDF5 sequence, opened lazily for windowed reading.

    Attributes
    ----------
    name, path : str, Path
    height, width : int
    cfa : str or None (monochrome)
    n_readouts : int
    clock_hz : float
    gt_index : (K,) int64 ndarray
    meta : dict (the full metadata recorded by the writer)
    has_clean : bool
    """

    def __init__(self, path: str | os.PathLike, name: str | None = None,
                 header: dict | None = None):
        self.path = Path(path)
        self.name = name or self.path.stem
        self._file = None
        self._pid = None
        self._checks: dict[str, ChunkCheck] = {}
        if header is None:
            header = read_header(self.path)
        self._set_header(header)

    def _set_header(self, header: dict) -> None:
        self.height = int(header["height"])
        self.width = int(header["width"])
        self.cfa = header["cfa"]
        self.n_readouts = int(header["n_readouts"])
        self.clock_hz = float(header["clock_hz"])
        self.gt_index = np.asarray(header["gt_index"], np.int64)
        self.has_clean = bool(header["has_clean"])
        self.meta = header["meta"]
        self.format_version = int(header["format_version"])

    @property
    def seed(self):
        return self.meta.get("seed")

    @property
    def duration_s(self) -> float:
        return self.n_readouts / self.clock_hz if self.clock_hz > 0 else float("nan")

    @property
    def shape(self) -> tuple[int, int, int]:
        return (self.n_readouts, self.height, self.width)

    # --- handle management: lazy, per process ---------------------------------
    def _h5(self) -> h5py.File:
        pid = os.getpid()
        if self._file is None or self._pid != pid:
            # After a fork the inherited handle belongs to the parent: never use it.
            self._file = _open_checked(self.path)
            self._pid = pid
            self._checks = {}
        return self._file

    def _checker(self, name: str) -> ChunkCheck | None:
        """The CRC check of dataset ``name`` (None for a version-1 file)."""
        if self.format_version < 2:
            return None
        f = self._h5()
        check = self._checks.get(name)
        if check is None:
            sums = sums_dataset(f, self.path, name)[()]
            check = self._checks[name] = ChunkCheck(f[name], sums, self.path)
        return check

    def _checked(self, name: str, starts: tuple, data: np.ndarray) -> np.ndarray:
        """``data`` read from ``name`` at ``starts``, its chunks checked against their CRCs."""
        check = self._checker(name)
        if check is not None:
            check.check(starts, data)
        return data

    def close(self) -> None:
        if self._file is not None and self._pid == os.getpid():
            self._file.close()
        self._file = None
        self._pid = None

    def __enter__(self) -> Sequence:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_file"] = None
        state["_pid"] = None
        state["_checks"] = {}
        return state

    def __repr__(self) -> str:
        return (f"Sequence({self.name!r}: {self.n_readouts} readouts of {self.width}x"
                f"{self.height}, cfa={self.cfa}, {len(self.gt_index)} GT frames)")

    # --- reading ----------------------------------------------------------------
    def _dataset(self, clean: bool) -> h5py.Dataset:
        if clean and not self.has_clean:
            raise bad_value("clean", True, f"False: {self.name!r} has no clean twin")
        return self._h5()["clean_spikes" if clean else "spikes"]

    def read_window(self, start: int = 0, length: int | None = None, crop: tuple | None = None,
                    packed: bool = False, clean: bool = False) -> np.ndarray:
        """Readouts ``start .. start+length-1`` of a crop, reading only the chunks involved.

        Returns (length, h, w) uint8 0/1, or (length, h, ceil(w/8)) packed bits
        (little bit order, zero padding) when ``packed``.  ``crop`` is
        ``(top, left, height, width)`` in pixels.
        """
        packed = check_flag("packed", packed)
        clean = check_flag("clean", clean)
        start, length = check_window(start, length, self.n_readouts)
        top, left, h, w = check_crop(crop, self.height, self.width)
        b0, b1 = left // 8, (left + w + 7) // 8
        ds = self._dataset(clean)
        try:
            raw = self._checked(ds.name.lstrip("/"), (start, top, b0),
                                ds[start:start + length, top:top + h, b0:b1])
        except OSError as exc:
            part = f"{ds.name.lstrip('/')} (readouts {start}–{start + length - 1})"
            raise _read_error(self.path, exc, part) from exc
        if left % 8 == 0 and b0 == 0 and b1 == ds.shape[2] and packed and w == self.width:
            return raw
        return crop_packed(raw, left % 8, w, unpack=not packed)

    def read_packed(self, clean: bool = False) -> np.ndarray:
        """The whole (T, H, ceil(W/8)) packed stream."""
        return self.read_window(0, None, packed=True, clean=clean)

    def read_gt(self, k: int, crop: tuple | None = None) -> np.ndarray:
        """Ground-truth frame at position ``k`` of ``gt_index``: (h, w, 3) float32 linear RGB.

        ``k`` counts from 0 like a readout index in :meth:`read_window`; a negative
        position is refused there and here alike.
        """
        n = len(self.gt_index)
        if not is_int(k) or not 0 <= k < n:
            raise bad_value("k", k, f"a position in gt_index, in [0, {n - 1}]" if n else
                            f"nothing: {self.name!r} has no ground truth")
        top, left, h, w = check_crop(crop, self.height, self.width)
        try:
            gt = self._h5()["gt"][int(k):int(k) + 1, top:top + h, left:left + w, :]
            return _finite_gt(self.path, self._checked("gt", (int(k), top, left, 0), gt)[0])
        except OSError as exc:
            part = f"ground truth (frame {int(k)}, readout {int(self.gt_index[k])})"
            raise _read_error(self.path, exc, part) from exc

    def read_all_gt(self) -> np.ndarray:
        try:
            return _finite_gt(self.path, self._checked("gt", (0, 0, 0, 0), self._h5()["gt"][:]))
        except OSError as exc:
            raise _read_error(self.path, exc, "ground truth") from exc

    def to_stream(self):
        """Load everything into a ``SpikeStream`` (needs ``spikesim.simulate``)."""
        from spikesim.stream import SpikeStream

        return SpikeStream(
            packed=self.read_packed(),
            clean_packed=self.read_packed(clean=True) if self.has_clean else None,
            gt=self.read_all_gt(),
            gt_index=self.gt_index.copy(),
            meta=dict(self.meta),
        )


def _finite_gt(path: Path, gt: np.ndarray) -> np.ndarray:
    if gt.size and not np.isfinite(gt).all():
        raise SpikeSimFormatError(
            f"{str(path)!r}: its ground truth holds NaN or infinite values (damaged or "
            "written by another tool): regenerate the file"
        )
    return gt


def _read_error(path: Path, exc: Exception, part: str = "") -> SpikeSimFormatError:
    """The error for a failed read of ``path``; ``part`` names what was read
    (``"spikes (readouts 0–255)"``), so the damage can be placed."""
    text = str(exc)
    where = f" in its {part}" if part else ""
    low = text.lower()
    if "not registered" in low or "plugin" in low or "not available" in low:
        hint = "" if have_hdf5plugin() else " (install hdf5plugin: pip install 'spikesim[fast]')"
        return SpikeSimFormatError(
            f"{str(path)!r}: its data use a compression filter this HDF5 cannot decode{hint}: "
            f"{text}"
        )
    if "fletcher" in low or "checksum" in low:
        return SpikeSimFormatError(
            f"{str(path)!r}: damaged data{where} (a chunk fails its checksum): restore or "
            "regenerate the file"
        )
    return SpikeSimFormatError(
        f"{str(path)!r}: damaged data{where}, cannot be read ({text}): restore or regenerate "
        "the file"
    )


def _open_checked(path: Path) -> h5py.File:
    if not path.is_file():
        raise SpikeSimFileError(f"no such spikesim file: {str(path)!r}")
    if path.stat().st_size == 0:
        raise SpikeSimFormatError(f"{str(path)!r} is empty (0 bytes): not a spikesim HDF5 file")
    have_hdf5plugin()  # registers LZ4/Zstd decoders when installed
    try:
        return h5py.File(path, "r", rdcc_nbytes=READ_CACHE_BYTES)
    except (OSError, ValueError, RuntimeError) as exc:
        raise _describe_open_error(path, exc) from exc


def read_header(path: str | os.PathLike) -> dict:
    """Validate a spikesim HDF5 file and return its header (no spike data read).

    Raises :class:`SpikeSimFormatError` naming what is wrong: not HDF5,
    truncated, not a spikesim file, a newer format version, a missing or
    malformed attribute or dataset.
    """
    path = Path(path)
    f = _open_checked(path)
    try:
        return header_of(f, path)
    except (OSError, KeyError, RuntimeError) as exc:
        raise _read_error(path, exc) from exc
    finally:
        f.close()


def open_h5(path: str | os.PathLike) -> Sequence:
    """Open (and validate) one spikesim HDF5 file for lazy reading."""
    return Sequence(path)


def read_h5(path: str | os.PathLike):
    """Read a whole spikesim HDF5 file into a ``SpikeStream``."""
    with Sequence(path) as seq:
        return seq.to_stream()
