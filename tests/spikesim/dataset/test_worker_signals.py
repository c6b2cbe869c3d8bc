"""A dataset worker's SIGTERM handler (``spikesim.dataset._watch``)."""

from __future__ import annotations

import signal
import sys
import time

import pytest

from spikesim.dataset import _watch


def test_a_sigterm_during_llvmlite_code_exits_once_it_has_returned():
    """Raised inside one of llvmlite's ctypes callbacks (numba loading kernels), the
    exit would be printed as "Exception ignored ... Traceback" and lost: the handler
    tries again a moment later, and then exits with 143."""
    ns: dict = {}
    exec(compile("import sys\ndef callback():\n    return sys._getframe()\n",
                 "/site-packages/llvmlite/binding/executionengine.py", "exec"), ns)
    inside = ns["callback"]()
    before = signal.getsignal(signal.SIGALRM)
    try:
        assert _watch._exit_on_sigterm(signal.SIGTERM, inside) is None  # deferred
        with pytest.raises(SystemExit) as exited:
            time.sleep(5)  # the retry runs here, outside llvmlite
        assert exited.value.code == 143
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, before)
    with pytest.raises(SystemExit) as exited:
        _watch._exit_on_sigterm(signal.SIGTERM, sys._getframe())
    assert exited.value.code == 143
