"""spikesim HDF5 files, format version 1 (docs/io.md): streaming writer, lazy reader.

One sequence per file, everything at the root:

=================  =======================  ======================================
name               shape / type             meaning
=================  =======================  ======================================
``spikes``         (T, H, ceil(W/8)) uint8  packed along W, little bit order
``clean_spikes``   same, optional           the noise-free twin (same seed)
``gt``             (K, H, W, 3) float32     linear RGB ground truth, 0..1
``gt_index``       (K,) int64               readout index of each ``gt`` frame
=================  =======================  ======================================

Root attributes: ``format="spikesim"``, ``format_version``,
``spikesim_version``, ``versions`` (JSON: spikesim, h5py, HDF5, NumPy),
``height``, ``width``, ``cfa`` (``"mono"`` for a monochrome sensor),
``clock_hz``, ``bitorder="little"``, ``n_readouts``, ``start_readout``,
``seed`` (when known), ``sensor``/``noise``/``scene`` (JSON of the full
configuration) and ``meta`` (JSON of the whole metadata dict).

Files are written to a temporary sibling and renamed into place only when
complete (:mod:`spikesim.io._atomic`); a full disk or a file-size limit gives
a :class:`~spikesim.errors.SpikeSimFileError` and no file
(:mod:`spikesim.io._guard`).  Every dataset carries the Fletcher-32 checksum
filter (after compression), so a damaged chunk is an error when read, never
different bits.  Readers open the file lazily and
reopen it after a fork, and a :class:`Sequence` pickles without its handle,
so it is safe to hand to spawned or forked worker processes.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable
from pathlib import Path

import h5py
import numpy as np

from spikesim._version import __version__
from spikesim.errors import SpikeSimFileError, SpikeSimFormatError, SpikeSimTypeError, bad_value
from spikesim.io._atomic import atomic_path
from spikesim.io._compression import DEFAULT_COMPRESSION, compression_kwargs, have_hdf5plugin
from spikesim.io._guard import GuardedFile, write_error
from spikesim.io._window import check_crop, check_window, crop_packed

__all__ = [
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "H5Writer",
    "Sequence",
    "open_h5",
    "read_h5",
    "spike_chunks",
    "write_h5",
]

FORMAT_NAME = "spikesim"
FORMAT_VERSION = 1

#: Chunk extent along (readouts, rows, packed bytes).  A 39-40 readout window
#: of a 64-256 px crop touches 2 x 1-3 x 1-3 chunks of 32 x 128 x 16 bytes
#: (64 KiB, 128 x 128 px): see ``docs/io.md`` for the measurement.
CHUNK_READOUTS = 32
CHUNK_ROWS = 128
CHUNK_BYTES = 16
#: Per-dataset chunk cache of a reader (bytes).
READ_CACHE_BYTES = 8 << 20

_CFA_NAMES = ("mono", "RGGB", "BGGR", "GRBG", "GBRG")
_REQUIRED_ATTRS = ("format_version", "height", "width", "cfa", "clock_hz", "bitorder", "meta")


#: Root attribute holding a SHA-256 of all the others.  HDF5 keeps more than a few
#: attributes in a heap whose blocks carry no checksum; this one makes a changed
#: attribute an error when the file is opened.
DIGEST_ATTR = "attrs_sha256"


def _plain(value):
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return [_plain(v) for v in value.tolist()]
    return value


def _attrs_digest(attrs) -> str:
    """SHA-256 of the root attributes (except the digest itself) in a canonical form."""
    import hashlib

    plain = {str(k): _plain(attrs[k]) for k in attrs if k != DIGEST_ATTR}
    text = json.dumps(plain, sort_keys=True, default=repr, allow_nan=True)
    return hashlib.sha256(text.encode("utf-8", "surrogatepass")).hexdigest()


def _balanced(size: int, target: int) -> int:
    """Chunk extent <= ``target`` that splits ``size`` into equal parts (least edge padding)."""
    parts = -(-size // target)
    return -(-size // parts)


def spike_chunks(height: int, width: int) -> tuple[int, int, int]:
    """Chunk shape of the ``spikes`` dataset for an ``height × width`` sensor.

    About ``CHUNK_READOUTS x CHUNK_ROWS x CHUNK_BYTES``, with the spatial
    extents balanced so that edge chunks waste little (1000 rows: 8 x 125).
    """
    return (CHUNK_READOUTS, _balanced(height, CHUNK_ROWS),
            _balanced((width + 7) // 8, CHUNK_BYTES))


def _json_default(obj):
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if hasattr(obj, "to_dict"):
        return obj.to_dict()
    raise TypeError(f"{type(obj).__name__} is not JSON serialisable")


def _dumps(obj) -> str:
    return json.dumps(obj, default=_json_default, sort_keys=True)


def _versions() -> dict:
    return {
        "spikesim": __version__,
        "h5py": h5py.__version__,
        "hdf5": h5py.version.hdf5_version,
        "numpy": np.__version__,
    }


class H5Writer:
    """Write one sequence incrementally; the file appears only when complete.

    Parameters
    ----------
    path : path
        Final file name (``.h5``).
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
    deletes the temporary file.
    """

    def __init__(self, path: str | os.PathLike, meta: dict, compression: str = DEFAULT_COMPRESSION,
                 clean: bool = False, overwrite: bool = True):
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
        self.clean = bool(clean)
        self._filter = compression_kwargs(compression)
        self.compression = compression
        self.overwrite = overwrite
        self.n_readouts = 0
        self._file = None
        self._guard = None
        self._ctx = None

    def __enter__(self) -> H5Writer:
        self._ctx = atomic_path(self.path, overwrite=self.overwrite)
        tmp = self._ctx.__enter__()
        try:
            self._guard = GuardedFile(tmp)
            # HDF5 >= 1.10 layout (readable by any HDF5 since 2016): attributes of any size, and
            # a checksum on every metadata block, the chunk index included.  With the 1.8
            # layout (B-tree v1 chunk index, unchecked) a flipped bit in the index made a
            # chunk read as zeros without any error.
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

    def _abort(self, exc: BaseException) -> None:
        try:
            if self._file is not None:
                try:
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
        for name, arr in pairs:
            ds = self._file[name]
            ds.resize(t1, axis=0)
            ds[t0:t1] = arr
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
        k0 = self._file["gt"].shape[0]
        k1 = k0 + gt.shape[0]
        for name, arr, dtype in (("gt", gt, np.float32), ("gt_index", idx, np.int64)):
            ds = self._file[name]
            ds.resize(k1, axis=0)
            ds[k0:k1] = arr.astype(dtype, copy=False)
        self._check_io()

    def _finish(self) -> None:
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
            "versions": _dumps(_versions()),
            "height": self.height,
            "width": self.width,
            "cfa": meta.get("cfa") or "mono",
            "clock_hz": float(meta.get("clock_hz") or 0.0),
            "bitorder": "little",
            "n_readouts": self.n_readouts,
            "start_readout": int(meta.get("start_readout") or 0),
            "compression": str(self.compression),
            "sensor": _dumps(sensor),
            "noise": _dumps(sensor.get("noise") if isinstance(sensor, dict) else None),
            "scene": _dumps(meta.get("scene")),
            "meta": _dumps(meta),
        }
        if meta.get("seed") is not None:
            attrs["seed"] = int(meta["seed"])
        attrs[DIGEST_ATTR] = _attrs_digest(attrs)
        f.attrs.update(attrs)

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc is not None:
            self._abort(exc)
            return False
        try:
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


def _progress(total: int, enabled: bool, desc: str):
    from tqdm.auto import tqdm

    return tqdm(total=total, disable=not enabled, unit="readout", desc=desc, leave=False)


def write_h5(path: str | os.PathLike, source, compression: str = DEFAULT_COMPRESSION,
             progress: bool = False, overwrite: bool = True, block_readouts: int = 256) -> Path:
    """Write a ``SpikeStream`` or a chunk run (``ss.simulate_chunks``) to one HDF5 file.

    A run is consumed chunk by chunk and never held whole in memory.  The file
    appears under ``path`` only once complete.  Returns the path.

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


def _write_chunks(w: H5Writer, run: Iterable, bar) -> None:
    for chunk in run:
        start = getattr(chunk, "start", w.n_readouts)
        if start != w.n_readouts:
            raise bad_value("chunk.start", start, f"{w.n_readouts} (chunks must be contiguous)")
        w.append(chunk.packed, getattr(chunk, "clean_packed", None) if w.clean else None)
        gt = getattr(chunk, "gt", None)
        if gt is not None and len(gt):
            w.add_gt(gt, chunk.gt_index)
        bar.update(np.shape(chunk.packed)[0])


def _describe_open_error(path: Path, exc: Exception) -> SpikeSimFormatError:
    text = str(exc)
    if "signature" in text:
        why = "not an HDF5 file (no HDF5 signature)"
    elif "truncat" in text or "eof" in text.lower():
        why = "a truncated HDF5 file (shorter than its header says: an interrupted copy?)"
    else:
        why = f"not a readable HDF5 file ({text})"
    return SpikeSimFormatError(f"{str(path)!r} is {why}")


def _attr_text(value) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


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
        return self._file

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
        start, length = check_window(start, length, self.n_readouts)
        top, left, h, w = check_crop(crop, self.height, self.width)
        b0, b1 = left // 8, (left + w + 7) // 8
        ds = self._dataset(clean)
        try:
            raw = ds[start:start + length, top:top + h, b0:b1]
        except OSError as exc:
            raise _read_error(self.path, exc) from exc
        if left % 8 == 0 and b0 == 0 and b1 == ds.shape[2] and packed and w == self.width:
            return raw
        return crop_packed(raw, left % 8, w, unpack=not packed)

    def read_packed(self, clean: bool = False) -> np.ndarray:
        """The whole (T, H, ceil(W/8)) packed stream."""
        return self.read_window(0, None, packed=True, clean=clean)

    def read_gt(self, k: int, crop: tuple | None = None) -> np.ndarray:
        """Ground-truth frame at position ``k`` of ``gt_index``: (h, w, 3) float32 linear RGB."""
        n = len(self.gt_index)
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not -n <= k < n:
            raise bad_value("k", k, f"a position in gt_index, in [0, {n - 1}]" if n else
                            f"nothing: {self.name!r} has no ground truth")
        top, left, h, w = check_crop(crop, self.height, self.width)
        try:
            return _finite_gt(self.path, self._h5()["gt"][int(k) % n, top:top + h,
                                                            left:left + w, :])
        except OSError as exc:
            raise _read_error(self.path, exc) from exc

    def read_all_gt(self) -> np.ndarray:
        try:
            return _finite_gt(self.path, self._h5()["gt"][:])
        except OSError as exc:
            raise _read_error(self.path, exc) from exc

    def to_stream(self):
        """Load everything into a ``SpikeStream`` (needs ``spikesim.simulate``)."""
        from spikesim.simulate import SpikeStream

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


def _read_error(path: Path, exc: Exception) -> SpikeSimFormatError:
    text = str(exc)
    low = text.lower()
    if "not registered" in low or "plugin" in low or "not available" in low:
        hint = "" if have_hdf5plugin() else " (install hdf5plugin: pip install 'spikesim[fast]')"
        return SpikeSimFormatError(
            f"{str(path)!r}: its data use a compression filter this HDF5 cannot decode{hint}: "
            f"{text}"
        )
    if "fletcher" in low or "checksum" in low:
        return SpikeSimFormatError(
            f"{str(path)!r}: damaged data (a chunk fails its checksum): restore or regenerate "
            "the file"
        )
    return SpikeSimFormatError(
        f"{str(path)!r}: damaged data, cannot be read ({text}): restore or regenerate the file"
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


def _check_dataset(f: h5py.File, path: Path, name: str, dtype, shape_tail: tuple) -> h5py.Dataset:
    if name not in f or not isinstance(f[name], h5py.Dataset):
        raise SpikeSimFormatError(f"{str(path)!r}: dataset {name!r} is missing (format version 1)")
    ds = f[name]
    if ds.dtype != dtype or ds.shape[1:] != shape_tail or ds.ndim != 1 + len(shape_tail):
        raise SpikeSimFormatError(
            f"{str(path)!r}: dataset {name!r} is {ds.dtype} {ds.shape}, expected {np.dtype(dtype)} "
            f"(N, {', '.join(map(str, shape_tail))})"
        )
    return ds


def read_header(path: str | os.PathLike) -> dict:
    """Validate a spikesim HDF5 file and return its header (no spike data read).

    Raises :class:`SpikeSimFormatError` naming what is wrong: not HDF5,
    truncated, not a spikesim file, a newer format version, a missing or
    malformed attribute or dataset.
    """
    path = Path(path)
    f = _open_checked(path)
    try:
        return _header_of(f, path)
    except (OSError, KeyError, RuntimeError) as exc:
        raise _read_error(path, exc) from exc
    finally:
        f.close()


def _header_of(f: h5py.File, path: Path) -> dict:
    attrs = f.attrs
    fmt = _attr_text(attrs["format"]) if "format" in attrs else None
    if fmt != FORMAT_NAME:
        shown = "no 'format' attribute" if fmt is None else f"format={fmt!r}"
        raise SpikeSimFormatError(
            f"{str(path)!r} is an HDF5 file but not a spikesim file ({shown}, expected "
            f"format={FORMAT_NAME!r})"
        )
    missing = [a for a in _REQUIRED_ATTRS if a not in attrs]
    if missing:
        raise SpikeSimFormatError(f"{str(path)!r}: missing root attribute(s) {missing}")
    version = attrs["format_version"]
    if not isinstance(version, (int, np.integer)) or version < 1:
        raise SpikeSimFormatError(f"{str(path)!r}: format_version={version!r} is not a version")
    if version > FORMAT_VERSION:
        by = _attr_text(attrs.get("spikesim_version", "?"))
        raise SpikeSimFormatError(
            f"{str(path)!r} uses format version {int(version)} (written by spikesim {by}); "
            f"this spikesim {__version__} reads format version {FORMAT_VERSION}: upgrade spikesim"
        )
    if _attr_text(attrs["bitorder"]) != "little":
        raise SpikeSimFormatError(
            f"{str(path)!r}: bitorder={_attr_text(attrs['bitorder'])!r}, expected 'little'"
        )
    try:
        height, width = int(attrs["height"]), int(attrs["width"])
        clock_hz = float(attrs["clock_hz"])
        meta = json.loads(_attr_text(attrs["meta"]))
    except (TypeError, ValueError) as exc:
        raise SpikeSimFormatError(f"{str(path)!r}: malformed root attribute ({exc})") from None
    if height < 1 or width < 1 or not isinstance(meta, dict):
        raise SpikeSimFormatError(
            f"{str(path)!r}: height={height}, width={width} or meta is not valid"
        )
    if not (math.isfinite(clock_hz) and clock_hz >= 0):
        raise SpikeSimFormatError(
            f"{str(path)!r}: clock_hz={clock_hz!r} is not a readout clock (a finite number of "
            "Hz > 0, or 0 when unknown)"
        )
    cfa_text = _attr_text(attrs["cfa"])
    if cfa_text not in _CFA_NAMES:
        raise SpikeSimFormatError(
            f"{str(path)!r}: cfa={cfa_text!r} is not a Bayer pattern (one of {_CFA_NAMES})"
        )
    for key in ("sensor", "noise", "scene"):
        if key in attrs:
            try:
                value = json.loads(_attr_text(attrs[key]))
            except (TypeError, ValueError) as exc:
                raise SpikeSimFormatError(
                    f"{str(path)!r}: the {key!r} attribute is not valid JSON ({exc})"
                ) from None
            if value is not None and not isinstance(value, dict):
                raise SpikeSimFormatError(
                    f"{str(path)!r}: the {key!r} attribute is {type(value).__name__}, "
                    "expected a JSON object"
                )
    nb = (width + 7) // 8
    spikes = _check_dataset(f, path, "spikes", np.uint8, (height, nb))
    has_clean = "clean_spikes" in f
    if has_clean:
        clean = _check_dataset(f, path, "clean_spikes", np.uint8, (height, nb))
        if clean.shape != spikes.shape:
            raise SpikeSimFormatError(
                f"{str(path)!r}: clean_spikes {clean.shape} differs from spikes {spikes.shape}"
            )
    gt = _check_dataset(f, path, "gt", np.float32, (height, width, 3))
    gt_index = _check_dataset(f, path, "gt_index", np.int64, ())[:]
    n = spikes.shape[0]
    if gt.shape[0] != gt_index.shape[0]:
        raise SpikeSimFormatError(
            f"{str(path)!r}: gt has {gt.shape[0]} frames but gt_index {gt_index.shape[0]} entries"
        )
    if gt_index.size and (gt_index.min() < 0 or gt_index.max() >= n):
        raise SpikeSimFormatError(
            f"{str(path)!r}: gt_index holds readouts outside [0, {n - 1}]"
        )
    if n == 0:
        raise SpikeSimFormatError(f"{str(path)!r}: the spikes dataset holds no readout")
    for where, stated in (("attribute", attrs.get("n_readouts")),
                          ("meta", meta.get("n_readouts"))):
        if stated is not None and (not isinstance(stated, (int, np.integer)) or stated != n):
            raise SpikeSimFormatError(
                f"{str(path)!r}: n_readouts={stated!r} ({where}) disagrees with the {n} "
                "readouts of the spikes dataset: the file was altered or damaged"
            )
    if DIGEST_ATTR in attrs and _attr_text(attrs[DIGEST_ATTR]) != _attrs_digest(attrs):
        raise SpikeSimFormatError(
            f"{str(path)!r}: its attributes do not match their checksum (damaged, or edited by "
            "another tool): restore or regenerate the file"
        )
    cfa = cfa_text
    meta["gt_index"] = gt_index.tolist()
    return {
        "height": height, "width": width, "cfa": None if cfa == "mono" else cfa,
        "n_readouts": int(n), "clock_hz": clock_hz, "gt_index": gt_index.tolist(),
        "has_clean": has_clean, "meta": meta, "format_version": int(version),
    }


def open_h5(path: str | os.PathLike) -> Sequence:
    """Open (and validate) one spikesim HDF5 file for lazy reading."""
    return Sequence(path)


def read_h5(path: str | os.PathLike):
    """Read a whole spikesim HDF5 file into a ``SpikeStream``."""
    with Sequence(path) as seq:
        return seq.to_stream()
