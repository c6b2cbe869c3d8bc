"""Argument checks shared by the readers and writers of :mod:`spikesim.io`.

A flag is a ``bool`` (Python or NumPy), never a string: ``flip="no"`` is a
typo to report, not a true value to take.  An output path is a ``str`` or
``os.PathLike`` whose suffix says which format it holds, so that a file is
never written in one format under the other's name.
"""

from __future__ import annotations

import os
from pathlib import Path

from spikesim._validate import check_flag
from spikesim.errors import SpikeSimTypeError, bad_value

__all__ = ["check_flag", "check_out_path", "check_path_type"]


def check_path_type(name: str, path: object) -> Path:
    """``path`` as a :class:`Path`; a value that is not a str or os.PathLike is refused."""
    if isinstance(path, bytes) or not isinstance(path, (str, os.PathLike)):
        raise SpikeSimTypeError(
            f"{name} must be a file path (str or os.PathLike), got {type(path).__name__} "
            f"{path!r:.60}: pass the name of the file to write")
    return Path(path)


def check_out_path(name: str, path: object, suffixes: tuple[str, ...], other: str) -> Path:
    """An output path ending in one of ``suffixes`` (any case); ``other`` says what to use
    for another format (e.g. ``"a PKU .dat file: spikesim.io.write_dat"``)."""
    p = check_path_type(name, path)
    if p.suffix.lower() not in suffixes:
        raise bad_value(name, str(p), f"a file name ending in {' or '.join(suffixes)} "
                        f"(for {other})")
    return p
