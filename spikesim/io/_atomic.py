"""Atomic file creation: write to a temporary name, rename into place when complete.

A crash, an exception or a killed process while writing leaves at most a
temporary file (``.NAME.tmp-<pid>-<random>`` beside the target), never a file
under the final name.  ``os.replace`` is atomic on POSIX and Windows when both
names are on the same file system, which a sibling temporary guarantees.
"""

from __future__ import annotations

import contextlib
import os
import secrets
from collections.abc import Iterator
from pathlib import Path

from spikesim.errors import SpikeSimFileError

__all__ = ["atomic_path", "temp_name_for", "is_temp_name"]

_TMP_MARK = ".tmp-"


def temp_name_for(final: Path) -> Path:
    """A unique hidden sibling of ``final`` used while it is being written."""
    return final.with_name(f".{final.name}{_TMP_MARK}{os.getpid()}-{secrets.token_hex(4)}")


def is_temp_name(path: str | os.PathLike) -> bool:
    """True for names made by :func:`temp_name_for` (skipped by directory scans)."""
    name = Path(path).name
    return name.startswith(".") and _TMP_MARK in name


@contextlib.contextmanager
def atomic_path(final: str | os.PathLike, overwrite: bool = True) -> Iterator[Path]:
    """Yield a temporary path; on normal exit rename it to ``final``, else delete it.

    Parameters
    ----------
    final : path
        The name the finished file gets.  Its folder must exist.
    overwrite : bool
        If False and ``final`` exists, raise before writing anything.
    """
    final = Path(final)
    parent = final.parent if str(final.parent) else Path(".")
    if not parent.is_dir():
        raise SpikeSimFileError(f"output folder {str(parent)!r} does not exist")
    if final.is_dir():
        raise SpikeSimFileError(f"output path {str(final)!r} is a folder, expected a file name")
    if not overwrite and final.exists():
        raise SpikeSimFileError(f"output file {str(final)!r} exists (pass overwrite=True)")
    tmp = temp_name_for(final)
    try:
        yield tmp
        os.replace(tmp, final)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
