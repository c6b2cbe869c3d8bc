"""Dataset builds whose workers cannot run: they end, in bounded time, with an error
saying what to do (a Dask cluster whose workers all died; the workers of a script that
builds at its top level, outside ``if __name__ == "__main__":``)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import threading

import pytest

from spikesim.errors import SpikeSimError
from tests.support.fault_helpers import cli_env

MANIFEST = {
    "dataset": {"name": "t", "seed": 5, "size": [24, 40], "window": 9,
                "samples_per_sequence": 2},
    "sensor": {"preset": "ideal"},
    "noise": [{"mode": "none"}],
    "sources": [{"kind": "procedural", "scenes": ["astronaut"], "motions": ["pan"],
                 "count": 3, "split": "train"}],
}

KILLER = textwrap.dedent(
    """
    import os
    import numpy as np
    from spikesim.scenes import Static

    class Killer(Static):
        def radiance(self, t):
            os._exit(3)   # the worker process dies with its task

    def make(index, size, seed):
        return Killer(np.full(tuple(size) + (3,), 0.5, np.float32))
    """
)


def test_dask_build_whose_workers_all_died_ends_with_an_error(tmp_path, monkeypatch):
    """A Dask worker that dies (no nanny to restart it) leaves the scheduler with no
    worker, where Dask waits forever: the build stops after DASK_NO_WORKER_S seconds
    with one line saying what to do, and its summary is written."""
    pytest.importorskip("distributed")
    from dask.distributed import Client, LocalCluster

    from spikesim.dataset import build, build_dataset, parse_manifest

    (tmp_path / "killer_scenes.py").write_text(KILLER)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(build, "DASK_NO_WORKER_S", 2.0, raising=False)
    manifest = parse_manifest({**MANIFEST, "sources": [
        {"kind": "python", "factory": "killer_scenes:make", "count": 2, "split": "inj"}]})
    out = tmp_path / "ds"
    outcome = {}

    def run(address):
        try:
            outcome["summary"] = build_dataset(manifest, out, scheduler=address, progress=False)
        except BaseException as exc:  # noqa: BLE001 - checked below
            outcome["error"] = exc

    with LocalCluster(n_workers=0, dashboard_address=None) as cluster:
        worker = subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_worker", cluster.scheduler_address,
             "--no-nanny", "--nthreads", "1", "--no-dashboard"],
            env=cli_env(PYTHONPATH=os.pathsep.join([str(tmp_path), cli_env()["PYTHONPATH"]])),
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            with Client(cluster) as client:
                client.wait_for_workers(1, timeout=60)
            thread = threading.Thread(target=run, args=(cluster.scheduler_address,),
                                      daemon=True)
            thread.start()
            thread.join(timeout=90)
            assert not thread.is_alive(), "the build hangs with no Dask worker left"
        finally:
            worker.kill()
            worker.wait(timeout=30)
    assert worker.returncode == 3  # it did die with its task
    err = outcome.get("error")
    assert isinstance(err, SpikeSimError), outcome
    assert "no worker for 2 s" in str(err) and "run the same build again" in str(err)
    assert "\n" not in str(err)
    summary = json.loads((out / "build_summary.json").read_text())
    assert summary["executor"].startswith("dask scheduler tcp://")
    assert summary["executor"].endswith("(stopped by an error)") and summary["done"] == 0


SCRIPT = textwrap.dedent(
    """
    from spikesim.dataset import build_dataset, parse_manifest

    summary = build_dataset(parse_manifest({manifest!r}), "ds", workers=2, progress=False)
    print("returned", summary.line())
    """
)


def test_script_building_with_workers_outside_a_main_guard_fails_clearly(tmp_path):
    """Each spawned worker imports the script again and so builds at its import: the
    workers die while starting. Every sequence used to fail and the script exit 0;
    now it fails, saying to put the call under ``if __name__ == "__main__":``, and no
    worker builds anything."""
    (tmp_path / "script.py").write_text(SCRIPT.format(manifest=MANIFEST))
    proc = subprocess.run([sys.executable, "script.py"], cwd=tmp_path, env=cli_env(),
                          capture_output=True, text=True, timeout=240)
    assert proc.returncode == 1, (proc.returncode, proc.stdout[-2000:], proc.stderr[-3000:])
    assert "returned" not in proc.stdout
    last = proc.stderr.strip().splitlines()[-1]
    assert last.startswith("spikesim.errors.SpikeSimError: the worker processes of "
                           "build_dataset died while starting"), proc.stderr[-3000:]
    assert 'if __name__ == "__main__":' in last
    assert "bootstrapping phase" not in proc.stderr  # each worker says it in one line
    assert "build_dataset ran again in a worker process" in proc.stderr
    assert not list((tmp_path / "ds").rglob("*.h5"))


def test_dask_build_waits_with_a_warning_for_a_scheduler_first_worker(tmp_path):
    """A scheduler that has had no worker yet (an adaptive cluster scaling up from
    zero) is waited for, with a warning, not given up on: once a worker joins, the
    build finishes."""
    pytest.importorskip("distributed")
    import warnings

    from dask.distributed import LocalCluster

    from spikesim.dataset import build_dataset, parse_manifest

    manifest = parse_manifest({**MANIFEST, "sources": [{**MANIFEST["sources"][0], "count": 1}]})
    outcome = {}

    def run(address):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                outcome["summary"] = build_dataset(manifest, tmp_path / "ds", scheduler=address,
                                                   progress=False)
            except BaseException as exc:  # noqa: BLE001 - checked below
                outcome["error"] = exc
        outcome["warnings"] = [str(w.message) for w in caught]

    with LocalCluster(n_workers=0, dashboard_address=None, processes=False) as cluster:
        thread = threading.Thread(target=run, args=(cluster.scheduler_address,), daemon=True)
        thread.start()
        thread.join(timeout=3)
        assert thread.is_alive()  # waiting, not refused
        cluster.scale(1)
        thread.join(timeout=120)
        assert not thread.is_alive(), "the build did not finish once a worker joined"
    assert "error" not in outcome, outcome
    assert outcome["summary"].done == 1
    assert any("has no worker yet: waiting for workers to join" in w
               for w in outcome["warnings"]), outcome["warnings"]
