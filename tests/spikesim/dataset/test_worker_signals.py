"""A dataset worker's SIGTERM handler (``spikesim.dataset._watch``)."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import pytest

from spikesim.dataset import _watch


def test_a_sigterm_during_llvmlite_code_exits_once_it_has_returned(monkeypatch):
    """Raised inside one of llvmlite's ctypes callbacks (numba loading kernels), the
    exit would be printed as "Exception ignored ... Traceback" and lost: the handler
    tries again a moment later, and then exits with 143."""
    monkeypatch.setattr(_watch, "_initialized", True)  # a worker past its initializer
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


_DURING_INIT = """
import os, signal, sys
import spikesim.cli_guard as guard
from spikesim.dataset import _watch
install = guard.install_signal_handlers
def install_then_term():
    install()
    os.kill(os.getpid(), signal.SIGTERM)  # as the parent's stop would, mid-initializer
guard.install_signal_handlers = install_then_term
try:
    _watch.init_worker(os.getppid())
except BaseException as exc:
    print("raised", type(exc).__name__)
    sys.exit(3)
print("returned")
"""


def test_a_sigterm_during_the_initializer_exits_quietly_with_143():
    """A SIGTERM while a worker runs the pool's initializer (the parent stopping
    while a worker starts) exits at once with 143: an exception there would be
    printed by the pool as "Exception in initializer: Traceback"."""
    proc = subprocess.run([sys.executable, "-c", _DURING_INIT], capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 128 + signal.SIGTERM, (proc.stdout, proc.stderr)
    assert "raised" not in proc.stdout and "returned" not in proc.stdout
    assert "Traceback" not in proc.stderr
