"""kill -9 and SIGTERM of writers, dataset parents and workers.

Nothing partial under a final name, no orphaned process, no rename into the
output folder after the parent has died, stale temporary files removed by the
next run, and a worker that always dies fails only its own sequence.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from spikesim.io import verify
from tests.support.fault_helpers import (
    alive,
    children_of,
    cli_command,
    cli_env,
    finals,
    full_only,
    no_temps,
    run_cli,
    write_manifest,
)

LONG = ["astronaut", "--motion", "pan", "--size", "64x64", "--readouts", "2000000",
        "--force", "--out"]


def _start(prog, *args, cwd):
    return subprocess.Popen(cli_command(prog, *args), cwd=cwd, env=cli_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _wait_for(predicate, timeout=120.0, what="condition"):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return
        time.sleep(0.1)
    raise AssertionError(f"timed out waiting for {what}")


def _wait_for_temp(proc, folder: Path, timeout=180.0):
    def ready():
        assert proc.poll() is None, proc.communicate()[1][-2000:]
        return bool(no_temps(folder))
    _wait_for(ready, timeout, "a temporary file")


def test_sigterm_of_a_writer_removes_its_file_and_says_so(tmp_path):
    proc = _start("spikesim", "simulate", *LONG, "x.h5", cwd=tmp_path)
    _wait_for_temp(proc, tmp_path)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err[-2000:]
    assert "stopped by SIGTERM" in err and "Traceback" not in err
    assert not list(tmp_path.iterdir())


def test_kill9_of_a_writer_leaves_a_temp_that_the_next_write_into_its_folder_removes(tmp_path):
    proc = _start("spikesim", "simulate", *LONG, "x.h5", cwd=tmp_path)
    _wait_for_temp(proc, tmp_path)
    proc.kill()
    proc.wait(timeout=30)
    assert no_temps(tmp_path) and not (tmp_path / "x.h5").exists()  # nothing final
    done = run_cli("spikesim", "simulate", "astronaut", "--size", "8x8", "--readouts", "20",
                   "--out", "other.h5", cwd=tmp_path)  # a write of any name into the folder
    assert done.returncode == 0, done.stderr[-2000:]
    assert not no_temps(tmp_path) and (tmp_path / "other.h5").is_file()
    assert all(r["ok"] for r in verify(tmp_path / "other.h5"))


def _dataset(tmp_path, count=6, readouts=(601, 6)):
    manifest = write_manifest(tmp_path / "m.toml", count=count, window=readouts[0],
                              samples=readouts[1], size=(96, 96))
    return _start("spikesim", "dataset", manifest, "--out", "ds", "--workers", "2",
                  cwd=tmp_path)


def test_kill9_of_the_dataset_parent_leaves_no_orphan_and_no_late_rename(tmp_path):
    proc = _dataset(tmp_path)
    _wait_for_temp(proc, tmp_path / "ds", timeout=240)
    kids = children_of(proc.pid)  # pool workers and multiprocessing's resource tracker
    assert len(kids) >= 2, kids
    proc.kill()
    proc.wait(timeout=30)
    at_death = finals(tmp_path / "ds")
    _wait_for(lambda: not any(alive(k) for k in kids), timeout=30, what="orphans to exit")
    assert finals(tmp_path / "ds") == at_death  # nothing renamed into place after the parent
    assert not no_temps(tmp_path / "ds"), no_temps(tmp_path / "ds")  # workers cleaned up
    if at_death:
        assert all(r["ok"] for r in verify(tmp_path / "ds"))


@full_only
def test_sigterm_of_the_dataset_parent_stops_workers_and_records(tmp_path):
    proc = _dataset(tmp_path)
    _wait_for_temp(proc, tmp_path / "ds", timeout=240)
    kids = children_of(proc.pid)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=90)
    assert proc.returncode == 143 and "stopped by SIGTERM" in err, err[-2000:]
    assert "Traceback" not in err
    _wait_for(lambda: not any(alive(k) for k in kids), timeout=30, what="workers to exit")
    summary = json.loads((tmp_path / "ds" / "build_summary.json").read_text())
    assert "interrupted" in summary["executor"]
    assert not no_temps(tmp_path / "ds")
    # every file finished before the stop is counted and indexed, reported or not
    made = finals(tmp_path / "ds")
    assert summary["done"] == len(made)
    if made:
        index = json.loads((tmp_path / "ds" / "train" / "index.json").read_text())
        assert len(index["sequences"]) == len(made)


FACTORY = textwrap.dedent(
    """
    import os
    import multiprocessing
    import numpy as np
    from spikesim.scenes import Static

    class Dies(Static):
        def radiance(self, t):
            if multiprocessing.parent_process() is not None:  # never the test process
                os._exit(3)
            return super().radiance(t)

    def make(index, size, seed):
        img = np.full(tuple(size) + (3,), 0.1 + 0.1 * index, np.float32)
        return Dies(img) if index == 1 else Static(img)
    """
)


def test_a_worker_that_always_dies_fails_only_its_own_sequence(tmp_path, monkeypatch):
    from spikesim.dataset import build_dataset, parse_manifest
    from spikesim.io import open_dataset

    (tmp_path / "dies_factory.py").write_text(FACTORY)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "dies_factory", raising=False)
    m = parse_manifest({
        "dataset": {"name": "d", "seed": 1, "size": [16, 24], "window": 9,
                    "samples_per_sequence": 2},
        "sensor": {"preset": "ideal"},
        "noise": [{"mode": "none", "label": "clean"}],
        "sources": [{"kind": "python", "factory": "dies_factory:make", "count": 4,
                     "split": "inj"}],
    })
    out = tmp_path / "out"
    s = build_dataset(m, out, workers=2, progress=False)
    assert s.failed == 1 and s.done == 3, [r["error"] for r in s.failures]
    failed = s.failures[0]
    assert failed["id"].endswith("1") or "1" in failed["file"], failed
    assert "died" in failed["error"]
    assert not (out / failed["file"]).exists() and not no_temps(out)
    assert len(open_dataset(out / "inj")) == 3
    assert os.path.exists(out / "build_summary.json")


@pytest.mark.skipif(sys.platform != "linux", reason="reads /proc")
def test_parent_watch_module_exits_an_orphan(tmp_path):
    """Unit check of the parent watch: a process whose parent dies exits within seconds."""
    script = textwrap.dedent(
        """
        import os, subprocess, sys, time
        # the middle process starts a grandchild that runs the watch, then dies
        code = ("import os, time\\n"
                "from spikesim.dataset._watch import init_worker\\n"
                "init_worker(os.getppid())\\n"
                "print(os.getpid(), flush=True)\\n"
                "time.sleep(60)\\n")
        child = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                                 text=True)
        print(child.stdout.readline().strip(), flush=True)
        os._exit(0)
        """
    )
    mid = subprocess.run([sys.executable, "-c", script], env=cli_env(), capture_output=True,
                         text=True, timeout=120)
    pid = int(mid.stdout.strip().splitlines()[-1])
    _wait_for(lambda: not alive(pid), timeout=15, what="the orphan to exit")


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
def test_a_stop_inside_an_hdf5_write_leaves_no_file_with_zeros(tmp_path, monkeypatch, sig):
    """A stop whose handler runs inside HDF5's write callback (h5py swallows the
    exception there, and the write fails under HDF5) used to leave a file under its
    final name with chunks of zeros, or lose the stop: now it is held until the HDF5
    call ends, and the writer then removes its temporary."""
    import numpy as np

    import spikesim as ss
    from spikesim.cli_guard import Terminated, install_signal_handlers
    from spikesim.io import _guard

    install_signal_handlers()  # SIGTERM raises Terminated, as under the command line
    calls = {"n": 0}
    real = _guard.GuardedFile.write

    def write_then_stop(self, data):
        calls["n"] += 1
        if calls["n"] == 8:  # in the middle of the chunk writes
            os.kill(os.getpid(), getattr(signal, sig))
        return real(self, data)

    monkeypatch.setattr(_guard.GuardedFile, "write", write_then_stop)
    sensor = ss.Sensor(height=64, width=64, cfa="RGGB")
    stream = ss.simulate(ss.scenes.procedural("astronaut", size=(64, 64)), sensor, 600,
                         gt_readouts=list(range(0, 600, 50)))
    out = tmp_path / "s.h5"
    with pytest.raises(KeyboardInterrupt if sig == "SIGINT" else Terminated):
        ss.io.write_h5(out, stream, block_readouts=64)
    assert calls["n"] > 8 and list(tmp_path.iterdir()) == []
    monkeypatch.setattr(_guard.GuardedFile, "write", real)
    ss.io.write_h5(out, stream, block_readouts=64)  # and a whole write reads back whole
    np.testing.assert_array_equal(ss.io.open_h5(out).read_packed(), stream.packed)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


@full_only  # (a few seconds of builds per case: the full fault suite's)
@pytest.mark.parametrize("sig, code, words", [("SIGINT", 130, "interrupted"),
                                              ("SIGTERM", 143, "stopped by SIGTERM")])
def test_a_stop_of_a_workers_build_to_its_group_stops_it_whole(tmp_path, sig, code, words):
    """Ctrl-C at a terminal, or a scheduler's SIGTERM, reaches the whole process group.
    Workers leave Ctrl-C to the parent and exit quietly on SIGTERM: one line, the
    stop's exit status, no worker traceback, no temporary left, no worker left, no hang
    (Ctrl-C in a worker sending its result could leave the others waiting for the
    result queue forever)."""
    manifest = write_manifest(tmp_path / "m.toml", count=6, window=601, samples=6,
                              size=(96, 96))
    proc = subprocess.Popen(cli_command("spikesim", "dataset", manifest, "--out", "ds",
                                        "--workers", "2"), cwd=tmp_path, env=cli_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    _wait_for_temp(proc, tmp_path / "ds", timeout=240)
    kids = children_of(proc.pid)
    os.killpg(proc.pid, getattr(signal, sig))
    _, err = proc.communicate(timeout=90)
    assert proc.returncode == code and words in err, err[-2000:]
    assert "Process SpawnProcess" not in err, err[-2000:]  # an idle worker's traceback
    # (a worker's SIGTERM that landed in llvmlite's ctypes callback, as numba loaded its
    # kernels, printed "Exception ignored ... Traceback": 1 run in 42)
    assert "Traceback" not in err and "Exception ignored" not in err, err[-2000:]
    _wait_for(lambda: not any(alive(k) for k in kids), timeout=30, what="workers to exit")
    assert not no_temps(tmp_path / "ds")
