"""Atomic file creation: write to a temporary name, rename into place when complete.

A crash, an exception or a killed process while writing leaves at most a
temporary file (``.NAME.tmp-<pid>-<random>`` beside the target), never a file
under the final name.  ``os.replace`` is atomic on POSIX and Windows when both
names are on the same file system, which a sibling temporary guarantees.

A temporary left by a process killed outright (``kill -9``, power loss) is
*stale*: its writer's process id is no longer alive and no process holds the
advisory lock the writers keep on it (:func:`lock_temp`).  Every new write
into a folder removes the folder's stale temporaries first
(:func:`remove_stale_temps`), whatever their name, so a killed run leaves none
behind for long; a temporary of a live writer (another run into the same
folder) is never touched.

A process may register a check that runs just before each rename
(:func:`set_rename_guard`): a dataset worker whose parent has died raises
there, so it never renames a file into place after the parent is gone.
"""

from __future__ import annotations

import contextlib
import os
import re
import secrets
from collections.abc import Callable, Iterator
from pathlib import Path

from spikesim.errors import SpikeSimFileError
from spikesim.io._checks import check_flag, check_path_type

__all__ = [
    "atomic_path",
    "discard_active_temps",
    "is_stale_temp",
    "is_temp_name",
    "lock_temp",
    "remove_stale_temps",
    "set_rename_guard",
    "temp_name_for",
]

_TMP_MARK = ".tmp-"
_TMP_PID = re.compile(r"\.tmp-(\d+)-[0-9a-f]+")
_rename_guard: Callable[[Path], None] | None = None
#: Temporaries this process is writing now (removed by :func:`discard_active_temps`).
_active: set[Path] = set()


def temp_name_for(final: Path) -> Path:
    """A unique hidden sibling of ``final`` used while it is being written."""
    return final.with_name(f".{final.name}{_TMP_MARK}{os.getpid()}-{secrets.token_hex(4)}")


def is_temp_name(path: str | os.PathLike) -> bool:
    """True for names made by :func:`temp_name_for` (skipped by directory scans)."""
    name = Path(path).name
    return name.startswith(".") and _TMP_MARK in name


def set_rename_guard(guard: Callable[[Path], None] | None) -> None:
    """Run ``guard(final)`` before every rename into place in this process (None: no check).

    The guard raises to refuse the rename; the temporary file is then deleted.
    """
    global _rename_guard
    _rename_guard = guard


def discard_active_temps() -> None:
    """Delete every temporary this process is writing (for a process about to exit hard)."""
    for tmp in list(_active):
        with contextlib.suppress(OSError):
            tmp.unlink()
        _active.discard(tmp)


def lock_temp(fd: int) -> None:
    """Hold an advisory lock on an open temporary so that others see it is in use.

    The lock dies with the process (whatever kills it), which is what lets
    :func:`remove_stale_temps` tell a killed writer's file from a live one.
    """
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: the process id check alone
        return
    with contextlib.suppress(OSError):
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)


def _pid_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


def _locked_by_other(path: Path) -> bool:
    try:
        import fcntl
    except ImportError:  # pragma: no cover
        return False
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return True
    finally:
        os.close(fd)  # closing releases the probe's own lock
    return False


def is_stale_temp(path: str | os.PathLike) -> bool:
    """True for a temporary whose writer is gone (dead process id, no lock held)."""
    path = Path(path)
    m = _TMP_PID.search(path.name)
    if not is_temp_name(path) or m is None:
        return False
    return not _pid_alive(int(m.group(1))) and not _locked_by_other(path)


def remove_stale_temps(folder: str | os.PathLike) -> int:
    """Delete the stale temporaries in ``folder``.

    Returns how many were removed.  Temporaries of live writers stay.
    """
    folder = Path(folder)
    removed = 0
    try:
        entries = list(folder.iterdir())
    except OSError:
        return 0
    for p in entries:
        if is_stale_temp(p):
            with contextlib.suppress(OSError):
                p.unlink()
                removed += 1
    return removed


@contextlib.contextmanager
def atomic_path(final: str | os.PathLike, overwrite: bool = True) -> Iterator[Path]:
    """Yield a temporary path; on normal exit rename it to ``final``, else delete it.

    Stale temporaries of ``final`` left by killed writers are removed first.

    Parameters
    ----------
    final : path
        The name the finished file gets.  Its folder must exist.
    overwrite : bool
        If False and ``final`` exists, raise before writing anything.

    Examples
    --------
    >>> from pathlib import Path
    >>> from spikesim.io import atomic_path
    >>> with atomic_path("table.csv") as tmp:
    ...     _ = Path(tmp).write_text("a,b\\n1,2\\n")
    ...     Path("table.csv").exists()  # not yet: only the temporary exists
    False
    >>> Path("table.csv").read_text().splitlines()
    ['a,b', '1,2']
    """
    overwrite = check_flag("overwrite", overwrite)
    final = check_path_type("final", final)
    parent = final.parent if str(final.parent) else Path(".")
    if parent.exists() and not parent.is_dir():
        raise SpikeSimFileError(f"output folder {str(parent)!r} is a file, not a folder: give "
                                "a path in a folder")
    if not parent.is_dir():
        raise SpikeSimFileError(f"output folder {str(parent)!r} does not exist: create it "
                                "first (mkdir -p), or give a path in an existing folder")
    if final.is_dir():
        raise SpikeSimFileError(f"output path {str(final)!r} is a folder, expected a file name")
    if not overwrite and final.exists():
        raise SpikeSimFileError(f"output file {str(final)!r} exists (pass overwrite=True)")
    remove_stale_temps(parent)
    tmp = temp_name_for(final)
    _active.add(tmp)
    try:
        yield tmp
        if _rename_guard is not None:
            _rename_guard(final)
        os.replace(tmp, final)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    finally:
        _active.discard(tmp)
