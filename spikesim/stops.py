"""Stops (Ctrl-C, SIGTERM) held while a unit of work must end whole.

Python runs a signal's handler between two bytecodes of the main thread, so
the exception of a stop can be raised inside a callback that C code made into
Python.  HDF5 writes through such callbacks (h5py's ``fileobj`` driver, see
:mod:`spikesim.io._guard`): an exception there is swallowed ("Exception
ignored in ... ObjectID.__dealloc__"), the write fails under HDF5, and the file
goes on as if it had been written, with chunks of zeros, or the process
crashes.  A training step stopped halfway would leave weights and optimizer
out of step.  :func:`deferred_stops` holds the stop until the block ends, then
raises it where Python code can clean up.
"""

from __future__ import annotations

import contextlib
import signal
import threading

__all__ = ["deferred_stops"]


#: The stops held, and SIGCHLD: a handler of it (PyTorch's data loader has one, which
#: raises when a worker dies) would otherwise break into the block the same way.
_STOPS = (signal.SIGINT, signal.SIGTERM)
_HELD = _STOPS + ((signal.SIGCHLD,) if hasattr(signal, "SIGCHLD") else ())


@contextlib.contextmanager
def deferred_stops():
    """Hold Ctrl-C and SIGTERM (and SIGCHLD) while the block runs: a signal that
    arrives inside it is raised, by the handler that was there, when the block
    ends, a stop before a child's exit.  Outside the main thread (where signals
    cannot be handled), or where a handler was set outside Python, the block just
    runs."""
    before = {s: signal.getsignal(s) for s in _HELD}
    if threading.current_thread() is not threading.main_thread() or None in before.values():
        yield  # (None: a handler set outside Python, which could not be put back)
        return
    held: list[int] = []
    for s in before:
        signal.signal(s, lambda signum, frame: held.append(signum))
    try:
        yield
    finally:
        for s, handler in before.items():
            signal.signal(s, handler)
        stops = [s for s in held if s in _STOPS]
        if held:
            signal.raise_signal(stops[0] if stops else held[0])
