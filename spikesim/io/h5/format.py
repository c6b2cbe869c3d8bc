"""spikesim HDF5 files, format version 2: the layout, its constants and its checks.

One sequence per file, everything at the root:

=================  =======================  ======================================
name               shape / type             meaning
=================  =======================  ======================================
``spikes``         (T, H, ceil(W/8)) uint8  packed along W, little bit order
``clean_spikes``   same, optional           the noise-free twin (same seed)
``gt``             (K, H, W, 3) float32     linear RGB ground truth, 0..1
``gt_index``       (K,) int64               readout index of each ``gt`` frame
``<name>_crc32``   chunk grid, uint32       CRC-32 of each chunk of ``<name>``
                                            (the four above; version 2)
=================  =======================  ======================================

Every dataset carries HDF5's Fletcher-32 filter; version 2 adds the chunk
CRCs (:mod:`spikesim.io.h5.sums`), which also catch what Fletcher-32 cannot
(a 16-bit word 0x0000 read as 0xFFFF or the reverse).  Version-1 files (no
``*_crc32``) are still read, with Fletcher-32 only.

Root attributes: ``format="spikesim"``, ``format_version``,
``spikesim_version``, ``versions`` (JSON: spikesim, h5py, HDF5, NumPy),
``height``, ``width``, ``cfa`` (``"mono"`` for a monochrome sensor),
``clock_hz``, ``bitorder="little"``, ``n_readouts``, ``start_readout``,
``seed`` (when known), ``sensor``/``noise``/``scene`` (JSON of the full
configuration), ``meta`` (JSON of the whole metadata dict),
``chunk_checksum="crc32"`` (version 2) and ``attrs_sha256`` (a checksum of
all the others).  :func:`header_of` checks an
open file against all of this; the writer is :mod:`spikesim.io.h5.writer`,
the lazy reader :mod:`spikesim.io.h5.reader`.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import h5py
import numpy as np

from spikesim._version import __version__
from spikesim.errors import SpikeSimFormatError
from spikesim.io.h5.sums import CHECKED, ChunkCheck, chunk_grid, sums_name

__all__ = ["FORMAT_NAME", "FORMAT_VERSION", "CRC_VERSION", "DIGEST_ATTR", "spike_chunks",
           "header_of", "attrs_digest", "dumps", "versions", "attr_text", "check_dataset"]

FORMAT_NAME = "spikesim"
FORMAT_VERSION = 2
#: The first format version whose datasets carry chunk CRCs (``<name>_crc32``).
CRC_VERSION = 2

#: Chunk extent along (readouts, rows, packed bytes).  A 39-40 readout window
#: of a 64-256 px crop touches 2 x 1-3 x 1-3 chunks of 32 x 128 x 16 bytes
#: (64 KiB, 128 x 128 px): see ``docs/io.md`` for the measurement.
CHUNK_READOUTS = 32
CHUNK_ROWS = 128
CHUNK_BYTES = 16
#: Per-dataset chunk cache of a reader (bytes).
READ_CACHE_BYTES = 8 << 20

CFA_NAMES = ("mono", "RGGB", "BGGR", "GRBG", "GBRG")
REQUIRED_ATTRS = ("format_version", "height", "width", "cfa", "clock_hz", "bitorder", "meta")


#: Root attribute holding a SHA-256 of all the others.  HDF5 keeps more than a few
#: attributes in a heap whose blocks carry no checksum; this one makes a changed
#: attribute an error when the file is opened.
DIGEST_ATTR = "attrs_sha256"


def plain_attr(value):
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return [plain_attr(v) for v in value.tolist()]
    return value


def attrs_digest(attrs) -> str:
    """SHA-256 of the root attributes (except the digest itself) in a canonical form."""
    import hashlib

    plain = {str(k): plain_attr(attrs[k]) for k in attrs if k != DIGEST_ATTR}
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


def dumps(obj) -> str:
    return json.dumps(obj, default=_json_default, sort_keys=True)


def versions() -> dict:
    return {
        "spikesim": __version__,
        "h5py": h5py.__version__,
        "hdf5": h5py.version.hdf5_version,
        "numpy": np.__version__,
    }


def attr_text(value) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


def check_dataset(f: h5py.File, path: Path, name: str, dtype, shape_tail: tuple) -> h5py.Dataset:
    if name not in f or not isinstance(f[name], h5py.Dataset):
        raise SpikeSimFormatError(f"{str(path)!r}: dataset {name!r} is missing")
    ds = f[name]
    if ds.dtype != dtype or ds.shape[1:] != shape_tail or ds.ndim != 1 + len(shape_tail):
        raise SpikeSimFormatError(
            f"{str(path)!r}: dataset {name!r} is {ds.dtype} {ds.shape}, expected {np.dtype(dtype)} "
            f"(N, {', '.join(map(str, shape_tail))})"
        )
    return ds


def header_of(f: h5py.File, path: Path) -> dict:
    attrs = f.attrs
    fmt = attr_text(attrs["format"]) if "format" in attrs else None
    if fmt != FORMAT_NAME:
        shown = "no 'format' attribute" if fmt is None else f"format={fmt!r}"
        raise SpikeSimFormatError(
            f"{str(path)!r} is an HDF5 file but not a spikesim file ({shown}, expected "
            f"format={FORMAT_NAME!r})"
        )
    missing = [a for a in REQUIRED_ATTRS if a not in attrs]
    if missing:
        raise SpikeSimFormatError(f"{str(path)!r}: missing root attribute(s) {missing}")
    version = attrs["format_version"]
    if not isinstance(version, (int, np.integer)) or version < 1:
        raise SpikeSimFormatError(f"{str(path)!r}: format_version={version!r} is not a version")
    if version > FORMAT_VERSION:
        by = attr_text(attrs.get("spikesim_version", "?"))
        raise SpikeSimFormatError(
            f"{str(path)!r} uses format version {int(version)} (written by spikesim {by}); "
            f"this spikesim {__version__} reads format version {FORMAT_VERSION}: upgrade spikesim"
        )
    if attr_text(attrs["bitorder"]) != "little":
        raise SpikeSimFormatError(
            f"{str(path)!r}: bitorder={attr_text(attrs['bitorder'])!r}, expected 'little'"
        )
    try:
        height, width = int(attrs["height"]), int(attrs["width"])
        clock_hz = float(attrs["clock_hz"])
        meta = json.loads(attr_text(attrs["meta"]))
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
    cfa_text = attr_text(attrs["cfa"])
    if cfa_text not in CFA_NAMES:
        raise SpikeSimFormatError(
            f"{str(path)!r}: cfa={cfa_text!r} is not a Bayer pattern (one of {CFA_NAMES})"
        )
    for key in ("sensor", "noise", "scene"):
        if key in attrs:
            try:
                value = json.loads(attr_text(attrs[key]))
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
    spikes = check_dataset(f, path, "spikes", np.uint8, (height, nb))
    has_clean = "clean_spikes" in f
    if has_clean:
        clean = check_dataset(f, path, "clean_spikes", np.uint8, (height, nb))
        if clean.shape != spikes.shape:
            raise SpikeSimFormatError(
                f"{str(path)!r}: clean_spikes {clean.shape} differs from spikes {spikes.shape}"
            )
    gt = check_dataset(f, path, "gt", np.float32, (height, width, 3))
    gt_index = check_dataset(f, path, "gt_index", np.int64, ())[:]
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
    if version >= CRC_VERSION:
        _check_sums_datasets(f, path, has_clean)
        sums_of_index = sums_dataset(f, path, "gt_index")[()]
        ChunkCheck(f["gt_index"], sums_of_index, path).check((0,), gt_index)
    if DIGEST_ATTR in attrs and attr_text(attrs[DIGEST_ATTR]) != attrs_digest(attrs):
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


def _check_sums_datasets(f: h5py.File, path: Path, has_clean: bool) -> None:
    """Format version 2: every checked dataset has its ``<name>_crc32`` companion, one
    uint32 per chunk (:mod:`spikesim.io.h5.sums`)."""
    for name in CHECKED:
        if name != "clean_spikes" or has_clean:
            sums_dataset(f, path, name)


def sums_dataset(f: h5py.File, path: Path, name: str) -> h5py.Dataset:
    """The ``<name>_crc32`` companion of dataset ``name`` (format version 2), checked
    to hold one uint32 per chunk; a missing or malformed one is a format error."""
    ds, sums = f[name], f.get(sums_name(name))
    grid = chunk_grid(ds.shape, ds.chunks) if ds.chunks else None
    if (not isinstance(sums, h5py.Dataset) or grid is None or sums.dtype != np.uint32
            or sums.shape != grid):
        raise SpikeSimFormatError(
            f"{str(path)!r}: the chunk checksums of {name!r} ({sums_name(name)}) are "
            f"missing or malformed (expected uint32 of shape {grid}): the file was altered "
            "or damaged")
    return sums
