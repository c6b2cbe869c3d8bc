"""Data-loader workers that die with the training process.

PyTorch's worker checks its parent (``os.getppid()`` against the pid it read
when its loop started) only between two batches, and it reads that pid after
its imports and ``worker_init_fn``: a training process killed (``kill -9``)
while its spawned workers still import reads as their parent the process
that adopted them, so they never notice and wait for work for ever.

:func:`watch_parent` (the ``worker_init_fn`` of :meth:`Trainer._loader
<spikejdd.train.trainer.Trainer._loader>`) is given the parent's pid by the
parent itself.  It exits at once when that process is already gone, asks
Linux for SIGTERM at the parent's death (``PR_SET_PDEATHSIG``; only when the
loader was started from the main thread, since the signal follows the death
of the *thread* that started the worker) and starts a daemon thread that
checks the parent every :data:`POLL_S` seconds and exits the process when it
has gone (other systems, or a SIGTERM that a handler held up).
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
import time

__all__ = ["POLL_S", "watch_parent"]

#: Seconds between two checks of the parent by the watch thread.
POLL_S = 1.0
_PR_SET_PDEATHSIG = 1


def _death_signal(sig: int) -> None:
    """``prctl(PR_SET_PDEATHSIG, sig)`` on Linux (nothing elsewhere or on failure)."""
    if not sys.platform.startswith("linux"):
        return
    import ctypes

    with contextlib.suppress(OSError, AttributeError):  # no prctl: the watch thread remains
        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, int(sig), 0, 0, 0)


def _watch(parent_pid: int) -> None:
    while os.getppid() == parent_pid:
        time.sleep(POLL_S)
    os._exit(1)


def watch_parent(parent_pid: int, main_thread: bool, worker_id: int = 0) -> None:
    """``worker_init_fn``: end this worker within :data:`POLL_S` seconds of the death of
    the process ``parent_pid`` (at once on Linux when ``main_thread``: the loader was
    started by the parent's main thread). Use ``functools.partial(watch_parent,
    os.getpid(), main_thread)`` in the parent."""
    if main_thread:
        _death_signal(signal.SIGTERM)
    if os.getppid() != parent_pid:  # died before this worker got here
        os._exit(1)
    threading.Thread(target=_watch, args=(parent_pid,), name="spikejdd-parent-watch",
                     daemon=True).start()
