"""Write errors that surface as exceptions instead of crashes.

HDF5 does not survive a write that fails under it: on a full disk or past a
file-size limit (``ulimit -f``) h5py keeps retrying the flush from object
finalisers and the process ends in a segmentation fault.  The writer therefore
gives HDF5 a :class:`GuardedFile` (h5py's ``fileobj`` driver): the first
failing write is recorded, the rest are swallowed, HDF5 always sees success,
and the writer checks :attr:`GuardedFile.error` after every block and raises
:func:`write_error`, a one-line :class:`~spikesim.errors.SpikeSimFileError`.
The temporary file is then deleted, so nothing partial stays behind.
"""

from __future__ import annotations

import errno
import io
import os
from pathlib import Path

from spikesim.errors import SpikeSimFileError
from spikesim.io.atomic import lock_temp

__all__ = ["GuardedFile", "write_error"]


def write_error(path: str | os.PathLike, exc: OSError) -> SpikeSimFileError:
    """One-line error for a failed write of ``path`` saying what to do."""
    code = getattr(exc, "errno", None)
    if code == errno.ENOSPC:
        why = "the disk is full: free space or write to another folder"
    elif code == errno.EFBIG:
        why = ("the file exceeds this process's file-size limit (ulimit -f) or the file "
               "system's: raise the limit or write a shorter stream")
    elif code == errno.EDQUOT:
        why = "the disk quota is exhausted: free space or write to another folder"
    elif code in (errno.EACCES, errno.EPERM, errno.EROFS):
        why = "no permission to write there: choose another output folder"
    else:
        why = f"{exc.strerror or exc}"
    return SpikeSimFileError(f"writing {str(path)!r} failed: {why}; nothing was written")


class GuardedFile(io.RawIOBase):
    """A read-write binary file whose write failures are recorded, never raised to HDF5.

    After the first failure writes and truncations are no-ops that report
    success; the caller must check :attr:`error` and abandon the file.
    The file descriptor holds the advisory lock of a live temporary
    (:func:`spikesim.io.atomic.lock_temp`).
    """

    def __init__(self, path: str | os.PathLike):
        super().__init__()
        self.path = Path(path)
        self.error: OSError | None = None
        self._f = open(self.path, "w+b", buffering=0)  # noqa: SIM115 - closed by close()
        lock_temp(self._f.fileno())

    def readable(self) -> bool:
        return True

    def writable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def seek(self, offset: int, whence: int = io.SEEK_SET) -> int:
        return self._f.seek(offset, whence)

    def tell(self) -> int:
        return self._f.tell()

    def readinto(self, buffer) -> int:
        return self._f.readinto(buffer)

    def write(self, data) -> int:
        view = memoryview(data)
        n = view.nbytes
        if self.error is None:
            try:
                done = self._f.write(view)
                if done < n:  # a short write (rare on files): finish it byte-wise
                    view = view.cast("B")
                    while done < n:
                        done += self._f.write(view[done:])
                return n
            except OSError as exc:
                self.error = exc
        self._f.seek(n, io.SEEK_CUR)
        return n

    def truncate(self, size: int | None = None) -> int:
        if self.error is None:
            try:
                return self._f.truncate(size)
            except OSError as exc:
                self.error = exc
        return self.tell() if size is None else size

    def flush(self) -> None:
        return None

    def close(self) -> None:
        if not self._f.closed:
            self._f.close()
        super().close()
