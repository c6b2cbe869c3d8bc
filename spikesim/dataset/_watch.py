"""Pool workers that die with their parent.

A spawned worker runs :func:`init_worker` first.  It installs the command
line's signal handling (SIGTERM exits by an exception, so a file being written
is removed on the way out; Ctrl-C is left to the parent, which stops its workers) and
starts a daemon thread that polls the parent's process id.  When the parent
is gone (``kill -9``, a crash) the thread forbids every further rename into
place (:func:`spikesim.io.atomic.set_rename_guard`), interrupts the task with
SIGTERM and, should that not end the process within :data:`GRACE_S` seconds
(a long kernel call), exits outright.  Nothing is renamed into the output
folder after the parent has died, and no worker outlives it by more than a
few seconds.
"""

from __future__ import annotations

import os
import signal
import threading
import time

from spikesim.errors import SpikeSimFileError

__all__ = ["GRACE_S", "POLL_S", "init_worker", "parent_alive"]

#: Seconds between two checks of the parent.
POLL_S = 0.2
#: Seconds a worker whose parent died gets to clean up before it exits outright.
GRACE_S = 5.0

_parent_pid: int | None = None
_initialized = False  # init_worker has returned (a SIGTERM then unwinds)
_orphaned = threading.Event()


def parent_alive() -> bool:
    """False once this worker's parent process has died (True outside a pool worker)."""
    return _parent_pid is None or (not _orphaned.is_set() and os.getppid() == _parent_pid)


def _refuse_rename(final) -> None:
    if not parent_alive():
        raise SpikeSimFileError(f"not renaming {str(final)!r} into place: the process that "
                                "started this worker has died")


def _watch() -> None:
    while os.getppid() == _parent_pid:
        time.sleep(POLL_S)
    _orphaned.set()
    try:
        os.kill(os.getpid(), signal.SIGTERM)  # interrupts the task; its temp file is removed
    finally:
        time.sleep(GRACE_S)
        # still here (a long kernel call holds the main thread): remove the files
        # being written and exit outright
        from spikesim.io.atomic import discard_active_temps

        discard_active_temps()
        os._exit(1)


#: Seconds after which a SIGTERM that came during llvmlite's code is tried again.
RETRY_S = 0.05


def _in_llvmlite(frame) -> bool:
    """Whether ``frame`` or a caller runs llvmlite's code, where numba loads or compiles
    kernels through ctypes callbacks: an exception raised inside one is not propagated
    but printed ("Exception ignored on calling ctypes callback function") and lost."""
    while frame is not None:
        if "llvmlite" in frame.f_code.co_filename:
            return True
        frame = frame.f_back
    return False


def _exit_on_sigterm(signum, frame):
    """SIGTERM in a worker: unwind (files being written are removed on the way) and
    exit quietly with status 143; an idle worker's exception would print a traceback.
    During llvmlite's code the exit is tried again :data:`RETRY_S` later (SIGALRM), once
    the callback it may be in has returned."""
    if not _initialized:  # still in init_worker: nothing to unwind, and the pool
        os._exit(128 + signal.SIGTERM)  # would print any exception's traceback
    if _in_llvmlite(frame):
        signal.signal(signal.SIGALRM, _exit_on_sigterm)
        signal.setitimer(signal.ITIMER_REAL, RETRY_S)
        return
    raise SystemExit(128 + signal.SIGTERM)


def init_worker(parent_pid: int, started=None) -> None:
    """Pool initializer: signal handling, parent watch and the rename guard; then sets
    the event ``started`` (when given), which tells the parent a worker got this far."""
    global _parent_pid, _initialized
    # a SIGTERM before the handlers are in place waits until they are, and then
    # exits at once: an exception raised in an initializer is printed by the pool
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGTERM})
    from spikesim.cli_guard import install_signal_handlers
    from spikesim.io.atomic import set_rename_guard

    _parent_pid = int(parent_pid)
    install_signal_handlers()
    signal.signal(signal.SIGTERM, _exit_on_sigterm)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGTERM})
    # Ctrl-C reaches the whole process group; the parent stops its workers itself
    # (SIGTERM, after cancelling what is queued).  A worker that Ctrl-C stopped in the
    # middle of a result's send could leave the others waiting for the result queue
    # forever, and the parent waiting for them.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    set_rename_guard(_refuse_rename)
    if os.getppid() != _parent_pid:  # died while this worker started
        os._exit(1)
    threading.Thread(target=_watch, name="spikesim-parent-watch", daemon=True).start()
    if started is not None:
        started.set()
    _initialized = True
