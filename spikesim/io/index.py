"""Multi-file datasets: a folder of per-sequence HDF5 files plus a rebuildable index.

The index ``index.json`` records, for each ``*.h5`` file in the folder (not
recursive), the sequence name (file stem), its shape, readouts, CFA, clock,
ground-truth readout indices, whether it has a clean twin, its full
configuration, and the file's size and modification time.  Everything in it
is derived from the files, so :func:`build_index` can always rebuild it; a
reader that finds it missing or out of date (a file added, removed or
rewritten) rebuilds it in memory and warns when it was stale.  Sequences made
from video clips by the dataset builder also carry ``clip`` (video, start time,
crop box, measured motion).

:func:`resolve_dataset` turns what a user names (a dataset root written by
``spikesim dataset`` with its split folders, a split folder, or one file) into
the file or split folder to read; every command and loader that takes data
calls it.
"""

from __future__ import annotations

import json
import os
import warnings
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from spikesim.errors import SpikeSimFileError, SpikeSimFormatError, SpikeSimValueError, bad_value
from spikesim.io._checks import check_flag
from spikesim.io.atomic import atomic_path, is_temp_name
from spikesim.io.h5 import Sequence, read_header

__all__ = ["INDEX_NAME", "Dataset", "build_index", "dataset_splits", "holds_sequences",
           "load_index", "open_dataset", "resolve_dataset"]

INDEX_NAME = "index.json"
INDEX_FORMAT = "spikesim-index"
INDEX_VERSION = 1
_SUFFIXES = (".h5", ".hdf5")


def _sequence_files(folder: Path) -> list[Path]:
    return sorted(
        p for p in folder.iterdir()
        if p.suffix.lower() in _SUFFIXES and p.is_file() and not is_temp_name(p)
    )


def _stamp(path: Path) -> dict:
    st = path.stat()
    return {"file_size": st.st_size, "file_mtime_ns": st.st_mtime_ns}


def _scan(folder: Path, progress: bool = False) -> dict:
    from tqdm.auto import tqdm

    entries = []
    files = _sequence_files(folder)
    for path in tqdm(files, disable=not progress, desc="index", unit="file", leave=False):
        entry = {"name": path.stem, "file": path.name, **_stamp(path)}
        entry.update(read_header(path))
        clip = (entry["meta"].get("dataset") or {}).get("clip")
        if clip is not None:  # video, start time, crop box, motion of a dataset clip
            entry["clip"] = clip
        entries.append(entry)
    names = [e["name"] for e in entries]
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if names.count(n) > 1})
        raise SpikeSimFormatError(f"{str(folder)!r}: sequence names {dup} occur twice")
    return {"format": INDEX_FORMAT, "format_version": INDEX_VERSION, "sequences": entries}


def build_index(folder: str | os.PathLike, write: bool = True, progress: bool = False) -> dict:
    """Scan a dataset folder, validate every file and (by default) write ``index.json``.

    A file that is not a valid spikesim sequence raises
    :class:`SpikeSimFormatError` naming it.  Returns the index dict.
    """
    folder = _check_folder(folder)
    write = check_flag("write", write)
    index = _scan(folder, check_flag("progress", progress))
    if write:
        with atomic_path(folder / INDEX_NAME) as tmp:
            tmp.write_text(json.dumps(index, indent=1, sort_keys=True))
    return index


def load_index(folder: str | os.PathLike) -> dict | None:
    """The index of ``folder`` if present, valid and up to date with the files, else None."""
    folder = _check_folder(folder)
    path = folder / INDEX_NAME
    if not path.is_file():
        return None
    try:
        index = json.loads(path.read_text())
        if index.get("format") != INDEX_FORMAT or index.get("format_version") != INDEX_VERSION:
            return None
        entries = index["sequences"]
        files = _sequence_files(folder)
        if sorted(e["file"] for e in entries) != [p.name for p in files]:
            return None
        for e in entries:
            if _stamp(folder / e["file"]) != {k: e[k] for k in ("file_size", "file_mtime_ns")}:
                return None
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return index


def _check_folder(folder) -> Path:
    folder = Path(folder)
    if not folder.is_dir():
        raise SpikeSimFileError(f"no such dataset folder: {str(folder)!r}")
    return folder


def holds_sequences(folder: Path) -> bool:
    """True when ``folder`` holds sequences itself: an index, or a spike file that is
    not a writer's temporary."""
    return (folder / INDEX_NAME).is_file() or any(
        p.suffix.lower() in _SUFFIXES and not is_temp_name(p) for p in folder.iterdir()
        if p.is_file())


def dataset_splits(folder: str | os.PathLike) -> list[str]:
    """Names of the split folders (sub-folders holding sequences) of a dataset root."""
    folder = _check_folder(folder)
    return sorted(p.name for p in folder.iterdir() if p.is_dir() and holds_sequences(p))


def resolve_dataset(path: str | os.PathLike, split: str | None = None) -> Path:
    """The file or split folder to read for ``path``.

    ``path`` may be one sequence file, a folder of sequence files (a split), or
    a dataset root as ``spikesim dataset`` writes it (``ROOT/<split>/*.h5``).
    For a root, ``split`` picks the split folder; it may be left out when the
    root has exactly one.  Raises :class:`SpikeSimFileError` for a missing
    path and :class:`SpikeSimValueError` naming the splits found when the
    choice is missing or wrong.
    """
    p = Path(path)
    if not p.exists() and p.suffix:
        raise SpikeSimFileError(f"no such file or dataset folder: {str(p)!r}")
    if p.is_file():
        if split is not None:
            raise bad_value("split", split, f"no split: {str(p)!r} is a single file")
        return p
    folder = _check_folder(p)
    if split is not None and not isinstance(split, str):
        raise bad_value("split", split, "a split name (a string)")
    splits = dataset_splits(folder)
    if holds_sequences(folder):
        if split is None or split == folder.name:
            return folder
        if split not in splits:
            raise bad_value("split", split, f"{folder.name!r}: {str(folder)!r} is a split folder"
                            + (f" (sub-folders with sequences: {splits})" if splits else ""))
    if split is not None:
        if split not in splits:
            raise bad_value("split", split, f"one of the splits found in {str(folder)!r}: "
                            f"{splits or 'none'}")
        return folder / split
    if len(splits) == 1:
        return folder / splits[0]
    if not splits:
        raise SpikeSimFormatError(f"{str(folder)!r} holds no spikesim sequence (*.h5) and no "
                                  "split folder of them")
    raise SpikeSimValueError(f"{str(folder)!r} is a dataset root with splits {splits}: pick one "
                             "with --split NAME (split=NAME in Python)")


class Dataset:
    """Sequences of a dataset (one file or a folder), opened lazily.

    ``ds.names`` lists the sequences; ``len(ds)``, iteration and
    ``ds.sequence(name_or_position)`` give :class:`~spikesim.io.h5.Sequence`
    objects; ``ds.read_window(seq, start, length, crop)`` reads from one.
    Pickles without open handles (safe for spawned and forked workers).
    """

    def __init__(self, root: Path, sequences: list[Sequence]):
        self.root = root
        self._seqs = sequences
        self._by_name = {s.name: s for s in sequences}

    @property
    def names(self) -> list[str]:
        return [s.name for s in self._seqs]

    def __len__(self) -> int:
        return len(self._seqs)

    def __iter__(self) -> Iterator[Sequence]:
        return iter(self._seqs)

    def sequence(self, key: str | int) -> Sequence:
        if isinstance(key, str):
            if key not in self._by_name:
                raise bad_value("sequence", key, f"one of {self.names[:10]}"
                                + (" ..." if len(self) > 10 else ""))
            return self._by_name[key]
        if isinstance(key, (int, np.integer)) and not isinstance(key, bool) \
                and -len(self) <= key < len(self):
            return self._seqs[int(key)]
        raise bad_value("sequence", key, f"a name or a position in [0, {len(self) - 1}]")

    __getitem__ = sequence

    def read_window(self, seq: str | int, start: int, length: int, crop: tuple | None = None,
                    packed: bool = False, clean: bool = False) -> np.ndarray:
        """``self.sequence(seq).read_window(...)``."""
        return self.sequence(seq).read_window(start, length, crop, packed=packed, clean=clean)

    @property
    def n_readouts(self) -> int:
        return sum(s.n_readouts for s in self._seqs)

    def close(self) -> None:
        for s in self._seqs:
            s.close()

    def __enter__(self) -> Dataset:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"Dataset({str(self.root)!r}: {len(self)} sequences, {self.n_readouts} readouts)"


def open_dataset(path: str | os.PathLike, split: str | None = None) -> Dataset:
    """Open a spikesim dataset: one ``.h5`` file, a folder of them with an index,
    or a dataset root with split folders (``split`` picks one; see
    :func:`resolve_dataset`).

    A folder's ``index.json`` is used when it matches the files; when it is
    missing it is rebuilt in memory from the files, and when it is stale the
    same happens with a warning (run :func:`build_index` to refresh it).
    """
    path = resolve_dataset(path, split)
    if path.is_file():
        return Dataset(path, [Sequence(path)])
    folder = _check_folder(path)
    index = load_index(folder)
    if index is None:
        if (folder / INDEX_NAME).exists():
            warnings.warn(
                f"{str(folder / INDEX_NAME)!r} does not match the files in the folder; rebuilt in "
                "memory (refresh it with spikesim.io.build_index)", UserWarning, stacklevel=2,
            )
        index = _scan(folder)
    if not index["sequences"]:
        raise SpikeSimFormatError(f"{str(folder)!r} holds no spikesim sequence (*.h5)")
    seqs = [Sequence(folder / e["file"], e["name"], header=e) for e in index["sequences"]]
    return Dataset(folder, seqs)
