"""Several ``spikesim dataset`` runs into one folder at once: all succeed, every file valid.

A run removes only the temporary files of writers that are gone, never
those of another live run, and each file is renamed into place whole, so the
last rename of a name wins with a complete file either way.
"""

from __future__ import annotations

import subprocess

import pytest

from spikesim.io import verify
from tests.support.fault_helpers import FULL, cli_command, cli_env, no_temps, write_manifest


@pytest.mark.parametrize("runs,workers", [(2, 1)] + ([(3, 2)] if FULL else []))
def test_concurrent_runs_into_one_folder(tmp_path, runs, workers):
    manifest = write_manifest(tmp_path / "m.toml", count=4, window=41, samples=4, size=(32, 32))
    procs = [subprocess.Popen(cli_command("spikesim", "dataset", manifest, "--out", "ds",
                                          "--workers", workers),
                              cwd=tmp_path, env=cli_env(), stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(runs)]
    results = [p.communicate(timeout=600) for p in procs]
    for p, (out, err) in zip(procs, results, strict=True):
        assert p.returncode == 0, (out[-2000:], err[-2000:])
        assert "Traceback" not in err and "failed 0" in out, out[-2000:]
    assert not no_temps(tmp_path / "ds")
    assert len(list((tmp_path / "ds" / "train").glob("*.h5"))) == 4
    reports = verify(tmp_path / "ds")
    assert len(reports) == 4 and all(r["ok"] for r in reports), reports
