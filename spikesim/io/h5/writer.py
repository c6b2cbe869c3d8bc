"""The streaming writer of spikesim HDF5 files (layout: :mod:`spikesim.io.h5.format`).

Files are written to a temporary sibling and renamed into place only when
complete (:func:`spikesim.io.atomic_path`); a full disk or a file-size limit
gives a :class:`~spikesim.errors.SpikeSimFileError` and no file
(:mod:`spikesim.io._guard`).  Every dataset carries the Fletcher-32 checksum
filter (after compression), and a CRC-32 of each chunk's data in a companion
dataset (:mod:`spikesim.io.h5.sums`: Fletcher-32 cannot tell the 16-bit
words 0x0000 and 0xFFFF apart), so a damaged chunk is an error when read,
never different bits.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

import h5py
import numpy as np

from spikesim._validate import check_int
from spikesim._version import __version__
from spikesim.errors import SpikeSimFileError, SpikeSimTypeError, SpikeSimValueError, bad_value
from spikesim.io._checks import check_flag, check_out_path
from spikesim.io._compression import DEFAULT_COMPRESSION, compression_kwargs
from spikesim.io._guard import GuardedFile, write_error
from spikesim.io._runs import contiguous_chunks
from spikesim.io.atomic import atomic_path
from spikesim.io.h5.format import (
    DIGEST_ATTR,
    FORMAT_NAME,
    FORMAT_VERSION,
    attrs_digest,
    dumps,
    spike_chunks,
    versions,
)
from spikesim.io.h5.sums import ChunkSums, sums_name
from spikesim.stops import deferred_stops

__all__ = ["H5Writer", "write_h5"]


class H5Writer:
    """Write one sequence incrementally; the file appears only when complete.

    Parameters
    ----------
    path : path
        Final file name, ending in ``.h5`` or ``.hdf5`` (a ``.dat`` file is
        written by :class:`~spikesim.io.DatWriter`).
    meta : dict
        Metadata of the stream (``SpikeStream.meta``): must hold ``height`` and
        ``width``; ``cfa``, ``clock_hz``, ``seed``, ``sensor``, ``scene`` and
        the rest are recorded as given.
    compression : str
        ``none``, ``gzip[:level]``, ``lz4`` or ``zstd[:level]`` (see
        :mod:`spikesim.io._compression`).
    clean : bool
        Create the ``clean_spikes`` dataset (every ``append`` must then pass it).
    overwrite : bool
        Replace an existing file of the same name (atomically).

    Use as a context manager; ``append`` packed readouts in order and
    ``add_gt`` ground-truth frames at any time.  An exception inside the block
    deletes the temporary file; so does a block that appends no readout (an
    error: a file with no readout is not a spike file, readers refuse it).
    """

    def __init__(self, path: str | os.PathLike, meta: dict, compression: str = DEFAULT_COMPRESSION,
                 clean: bool = False, overwrite: bool = True):
        path = _check_h5_path(path)
        if not isinstance(meta, dict):
            raise SpikeSimTypeError(f"meta must be a dict, got {type(meta).__name__}")
        for key in ("height", "width"):
            v = meta.get(key)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise bad_value(f"meta[{key!r}]", v, "an integer >= 1 (pixels)")
        self.path = Path(path)
        self.meta = dict(meta)
        self.height = int(meta["height"])
        self.width = int(meta["width"])
        self.nbytes = (self.width + 7) // 8
        self.clean = check_flag("clean", clean)
        self._filter = compression_kwargs(compression)
        self.compression = compression
        self.overwrite = check_flag("overwrite", overwrite)
        self.n_readouts = 0
        self._file = None
        self._guard = None
        self._ctx = None
        self._sums: dict[str, ChunkSums] = {}

    def __enter__(self) -> H5Writer:
        self._ctx = atomic_path(self.path, overwrite=self.overwrite)
        tmp = self._ctx.__enter__()
        try:
            self._guard = GuardedFile(tmp)
            # HDF5 >= 1.10 layout (readable by any HDF5 since 2016): attributes of any size, and
            # a checksum on every metadata block, the chunk index included.  With the 1.8
            # layout (B-tree v1 chunk index, unchecked) a flipped bit in the index made a
            # chunk read as zeros without any error.
            with deferred_stops():  # (every HDF5 call: see spikesim.stops)
                self._file = h5py.File(self._guard, "w", libver=("v110", "latest"))
                self._create()
            self._check_io()
        except OSError as exc:
            err = exc if isinstance(exc, SpikeSimFileError) else write_error(self.path, exc)
            self._abort(err)
            raise err from None
        except BaseException as exc:
            self._abort(exc)
            raise
        return self

    def _check_io(self) -> None:
        """Raise the first write failure of the temporary file (full disk, size limit)."""
        if self._guard is not None and self._guard.error is not None:
            raise write_error(self.path, self._guard.error)

    def _create(self) -> None:
        f = self._file
        h, w, nb = self.height, self.width, self.nbytes
        chunks = spike_chunks(h, w)
        names = ["spikes"] + (["clean_spikes"] if self.clean else [])
        for name in names:
            f.create_dataset(name, shape=(0, h, nb), maxshape=(None, h, nb), dtype=np.uint8,
                             chunks=chunks, fletcher32=True, **self._filter)
        f.create_dataset("gt", shape=(0, h, w, 3), maxshape=(None, h, w, 3), dtype=np.float32,
                         chunks=(1, min(h, 256), min(w, 256), 3), fletcher32=True,
                         **self._filter)
        f.create_dataset("gt_index", shape=(0,), maxshape=(None,), dtype=np.int64, chunks=(1024,),
                         fletcher32=True)
        self._sums = {name: ChunkSums(f[name].shape[1:], f[name].chunks)
                      for name in (*names, "gt", "gt_index")}

    def _abort(self, exc: BaseException) -> None:
        try:
            if self._file is not None:
                try:
                    with deferred_stops():
                        self._file.close()
                except Exception:  # noqa: BLE001 - the file is being discarded
                    pass
        finally:
            self._file = None
            if self._guard is not None:
                self._guard.close()
                self._guard = None
            self._ctx.__exit__(type(exc), exc, exc.__traceback__)

    def _check_packed(self, name: str, packed) -> np.ndarray:
        arr = np.asarray(packed)
        if arr.dtype != np.uint8 or arr.ndim != 3 or arr.shape[1:] != (self.height, self.nbytes):
            raise bad_value(
                name, f"{arr.dtype} array of shape {arr.shape}",
                f"uint8 (t, {self.height}, {self.nbytes}) packed bits",
            )
        return arr

    def append(self, packed, clean_packed=None) -> None:
        """Append (t, H, ceil(W/8)) packed readouts (and their clean twin when ``clean``)."""
        packed = self._check_packed("packed", packed)
        if self.clean:
            if clean_packed is None:
                raise bad_value("clean_packed", None, "the clean twin's packed bits (clean=True)")
            clean_packed = self._check_packed("clean_packed", clean_packed)
            if clean_packed.shape != packed.shape:
                raise bad_value("clean_packed.shape", clean_packed.shape, f"{packed.shape}")
        t0, t1 = self.n_readouts, self.n_readouts + packed.shape[0]
        pairs = [("spikes", packed)] + ([("clean_spikes", clean_packed)] if self.clean else [])
        with deferred_stops():
            for name, arr in pairs:
                _extend(self._file[name], t0, t1, arr)
                self._sums[name].feed(arr)
        self.n_readouts = t1
        self._check_io()

    def add_gt(self, gt, gt_index) -> None:
        """Append ground-truth frames (k, H, W, 3) linear RGB tied to readouts ``gt_index``."""
        gt = np.asarray(gt)
        idx = np.asarray(gt_index)
        if gt.ndim != 4 or gt.shape[1:] != (self.height, self.width, 3):
            raise bad_value("gt.shape", gt.shape, f"(k, {self.height}, {self.width}, 3)")
        if idx.ndim != 1 or idx.shape[0] != gt.shape[0] or idx.dtype.kind not in "iu":
            raise bad_value("gt_index", idx, f"{gt.shape[0]} integer readout indices")
        if idx.size and idx.min() < 0:
            raise bad_value("gt_index", int(idx.min()), "readout indices >= 0")
        if gt.size and not np.isfinite(gt).all():
            raise bad_value("gt", "non-finite values", "finite linear RGB")
        with deferred_stops():
            k0 = self._file["gt"].shape[0]
            k1 = k0 + gt.shape[0]
            for name, arr, dtype in (("gt", gt, np.float32), ("gt_index", idx, np.int64)):
                arr = arr.astype(dtype, copy=False)
                _extend(self._file[name], k0, k1, arr)
                self._sums[name].feed(arr)
        self._check_io()

    def _finish(self) -> None:
        if self.n_readouts == 0:
            raise SpikeSimValueError(
                f"no readout was written to {str(self.path)!r}: a spike file needs at least one "
                "readout (readers refuse an empty one), so no file was made; append readouts "
                "before closing")
        f = self._file
        idx = f["gt_index"][:]
        if idx.size and idx.max() >= self.n_readouts:
            raise bad_value("gt_index", int(idx.max()), f"< n_readouts = {self.n_readouts}")
        meta = dict(self.meta)
        meta.pop("gt_index", None)  # lives in its dataset; the reader puts it back
        meta["n_readouts"] = self.n_readouts
        meta.setdefault("bitorder", "little")
        meta.setdefault("clean_twin", self.clean)
        sensor = meta.get("sensor")
        attrs = {
            "format": FORMAT_NAME,
            "format_version": FORMAT_VERSION,
            "spikesim_version": __version__,
            "versions": dumps(versions()),
            "height": self.height,
            "width": self.width,
            "cfa": meta.get("cfa") or "mono",
            "clock_hz": float(meta.get("clock_hz") or 0.0),
            "bitorder": "little",
            "n_readouts": self.n_readouts,
            "start_readout": int(meta.get("start_readout") or 0),
            "compression": str(self.compression),
            "sensor": dumps(sensor),
            "noise": dumps(sensor.get("noise") if isinstance(sensor, dict) else None),
            "scene": dumps(meta.get("scene")),
            "meta": dumps(meta),
        }
        if meta.get("seed") is not None:
            attrs["seed"] = int(meta["seed"])
        for name, sums in self._sums.items():  # one CRC-32 per chunk of each dataset
            f.create_dataset(sums_name(name), data=sums.result(), fletcher32=True,
                             chunks=True)
        attrs["chunk_checksum"] = "crc32"
        attrs[DIGEST_ATTR] = attrs_digest(attrs)
        f.attrs.update(attrs)

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc is not None:
            self._abort(exc)
            return False
        try:
            with deferred_stops():
                self._finish()
                self._file.close()
            self._file = None
            self._check_io()
            self._guard.close()
            self._guard = None
        except BaseException as err:
            self._abort(err)
            raise
        self._ctx.__exit__(None, None, None)
        return False


def _extend(ds, i0: int, i1: int, arr) -> None:
    """Grow ``ds`` to ``i1`` rows along axis 0 and write ``arr`` at ``i0:i1``.  (A
    function of its own, so the dataset's handle, whose closing writes its cached
    chunks, is released before the caller's :func:`deferred_stops` block ends.)"""
    ds.resize(i1, axis=0)
    ds[i0:i1] = arr


def _progress(total: int, enabled: bool, desc: str):
    from tqdm.auto import tqdm

    return tqdm(total=total, disable=not enabled, unit="readout", desc=desc, leave=False)


def write_h5(path: str | os.PathLike, source, compression: str = DEFAULT_COMPRESSION,
             progress: bool = False, overwrite: bool = True, block_readouts: int = 256) -> Path:
    """Write a ``SpikeStream`` or a chunk run (``ss.simulate_chunks``) to one HDF5 file.

    A run is consumed chunk by chunk and never held whole in memory.  The file
    appears under ``path`` (ending in ``.h5`` or ``.hdf5``; a ``.dat`` file is
    written by :func:`~spikesim.io.write_dat`) only once complete; a source
    with no readout is an error and leaves no file.  Returns the path.

    Examples
    --------
    >>> import spikesim as ss
    >>> scene = ss.scenes.procedural("astronaut", size=(16, 16))
    >>> stream = ss.simulate(scene, ss.Sensor(height=16, width=16), 41)
    >>> ss.io.write_h5("seq.h5", stream)
    PosixPath('seq.h5')
    >>> back = ss.io.read_h5("seq.h5")
    >>> bool((back.packed == stream.packed).all()), back.gt.shape, back.gt_index.tolist()
    (True, (1, 16, 16, 3), [20])
    """
    path = _check_h5_path(path)
    check_flag("progress", progress)
    check_int("block_readouts", block_readouts, 1, unit="readouts")
    meta = getattr(source, "meta", None)
    if not isinstance(meta, dict):
        raise SpikeSimTypeError(
            "source must be a SpikeStream or a simulate_chunks run (an object with a .meta dict), "
            f"got {type(source).__name__}"
        )
    clean = getattr(source, "clean_packed", None) is not None or bool(meta.get("clean_twin"))
    total = int(meta.get("n_readouts") or 0)
    with H5Writer(path, meta, compression=compression, clean=clean, overwrite=overwrite) as w, \
            _progress(total, progress, Path(path).name) as bar:
        if hasattr(source, "packed"):
            packed = np.asarray(source.packed)
            cpacked = source.clean_packed if clean else None
            for t in range(0, packed.shape[0], block_readouts):
                sl = slice(t, t + block_readouts)
                w.append(packed[sl], None if cpacked is None else cpacked[sl])
                bar.update(packed[sl].shape[0])
            gt = getattr(source, "gt", None)
            if gt is not None and len(gt):
                w.add_gt(gt, source.gt_index)
        else:
            _write_chunks(w, source, bar)
    return Path(path)


def _check_h5_path(path: object) -> Path:
    """The output path of an HDF5 writer: a str or PathLike ending in .h5 or .hdf5."""
    return check_out_path("path", path, (".h5", ".hdf5"),
                          "a PKU .dat file use spikesim.io.write_dat or DatWriter")


def _write_chunks(w: H5Writer, run: Iterable, bar) -> None:
    for chunk in contiguous_chunks(run):
        w.append(chunk.packed, getattr(chunk, "clean_packed", None) if w.clean else None)
        gt = getattr(chunk, "gt", None)
        if gt is not None and len(gt):
            w.add_gt(gt, chunk.gt_index)
        bar.update(np.shape(chunk.packed)[0])
