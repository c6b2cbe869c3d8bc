"""kill -9 of a training with data-loader workers: no worker outlives it."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.support.fault_helpers import alive, children_of, cli_command, cli_env
from tests.support.sjdd_helpers import TINY


def _workers(pid: int) -> list[int]:
    """The spawned loader workers among the children of ``pid`` (not the resource tracker)."""
    out = []
    for kid in children_of(pid):
        try:
            cmd = Path(f"/proc/{kid}/cmdline").read_bytes()
        except OSError:
            continue
        if b"spawn_main" in cmd and b"resource_tracker" not in cmd:
            out.append(kid)
    return out


@pytest.mark.skipif(sys.platform != "linux", reason="reads /proc")
def test_kill9_of_a_training_ends_its_loader_workers(tmp_path):
    """PyTorch's workers read their parent's pid only once their imports are done: a
    training killed while they still import left them waiting for work for ever. Each
    now gets the pid from the parent and exits within seconds of its death (the bound
    is the rest of its imports on a busy machine)."""
    cfg = tmp_path / "tiny.json"
    cfg.write_text(json.dumps({"model": "lite", "model_overrides": TINY.to_dict(),
                               "batch_size": 2, "crop": 8, "eval_every": 1000,
                               "val_size": [12, 12], "val_speeds": [0.0],
                               "val_levels": ["GN10"], "bench_methods": []}))
    proc = subprocess.Popen(cli_command("spikejdd", "train", "--online", "--config", cfg,
                                        "--out", tmp_path / "run", "--steps", "100000",
                                        "--workers", "2", "--threads", "1", "--quiet"),
                            cwd=tmp_path, env=cli_env(), stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    try:
        end = time.monotonic() + 180
        while len(workers := _workers(proc.pid)) < 2:
            assert proc.poll() is None, proc.communicate()[1][-2000:]
            assert time.monotonic() < end, "no loader workers started"
            time.sleep(0.05)
    finally:
        proc.kill()  # at once: the workers are still importing
        proc.communicate(timeout=30)
    end = time.monotonic() + 15
    while any(alive(w) for w in workers) and time.monotonic() < end:
        time.sleep(0.2)
    left = [w for w in workers if alive(w)]
    for w in left:  # (the old code's workers) are not left behind by the test either
        with contextlib.suppress(ProcessLookupError):
            os.kill(w, signal.SIGKILL)
    assert not left, f"loader workers {left} outlived the killed training by 15 s"
