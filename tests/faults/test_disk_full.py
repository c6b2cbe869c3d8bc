"""Writes that hit a file-size limit (RLIMIT_FSIZE) or a full disk (a small tmpfs, or an
injected ENOSPC): one line naming the cause and what to do, exit 1, no crash, no temporary
file, no file under the final name; a dataset still tries and records every sequence."""

from __future__ import annotations

import errno
import io
import json
import subprocess
import uuid
from pathlib import Path

import numpy as np
import pytest

from spikesim.errors import SpikeSimFileError
from tests.support.fault_helpers import (
    assert_clean_failure,
    full_only,
    no_temps,
    run_cli,
    set_file_limit,
    small_stream,
    write_manifest,
)

LIMIT = 200 * 1024
BIG = ["astronaut", "--motion", "pan", "--size", "64x64", "--readouts", "20000",
       "--set", 'noise={"type":"paper","sigma_g":10}']


@pytest.fixture(scope="module")
def warm(tmp_path_factory):
    """One unlimited run first, so that compiled kernels are cached before any limit."""
    tmp = tmp_path_factory.mktemp("warm")
    proc = run_cli("spikesim", "simulate", "astronaut", "--size", "8x8", "--readouts", "20",
                   "--out", "w.h5", cwd=tmp)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return tmp


@pytest.mark.parametrize("suffix", ["h5", pytest.param("dat", marks=full_only)])
def test_simulate_past_the_file_size_limit(warm, tmp_path, suffix):
    proc = run_cli("spikesim", "simulate", *BIG, "--out", f"x.{suffix}", cwd=tmp_path,
                   preexec_fn=set_file_limit(LIMIT))
    assert_clean_failure(proc, "file-size limit", "nothing was written")
    assert not list(tmp_path.iterdir()), list(tmp_path.iterdir())


@full_only
@pytest.mark.parametrize("dst", ["y.h5", "y.dat"])
def test_convert_past_the_file_size_limit(warm, tmp_path, dst):
    proc = run_cli("spikesim", "simulate", *BIG, "--out", "x.h5", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    proc = run_cli("spikesim", "convert", "x.h5", dst, "--compression", "none", cwd=tmp_path,
                   preexec_fn=set_file_limit(LIMIT))
    assert_clean_failure(proc, "file-size limit")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.h5"]


@pytest.mark.parametrize("workers", [2, pytest.param(1, marks=full_only)])
def test_dataset_past_the_file_size_limit_records_every_sequence(warm, tmp_path, workers):
    manifest = write_manifest(tmp_path / "m.toml", count=2, window=301, samples=4)
    proc = run_cli("spikesim", "dataset", manifest, "--out", "ds", "--workers", workers,
                   cwd=tmp_path, preexec_fn=set_file_limit(LIMIT))
    assert proc.returncode == 1, proc.stderr[-3000:]
    assert "Traceback" not in proc.stderr + proc.stdout
    summary = json.loads((tmp_path / "ds" / "build_summary.json").read_text())
    assert summary["failed"] == 2 and len(summary["records"]) == 2
    assert all("file-size limit" in r["error"] for r in summary["records"])
    assert not no_temps(tmp_path / "ds") and not list((tmp_path / "ds").rglob("*.h5"))


def _can_mount_tmpfs(folder: Path) -> bool:
    try:
        subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(folder)],
                       check=True, capture_output=True, timeout=20)
    except (OSError, subprocess.SubprocessError):
        return False
    return True


@full_only
def test_full_tmpfs(warm, tmp_path):
    disk = tmp_path / "disk"
    disk.mkdir()
    if not _can_mount_tmpfs(disk):
        pytest.skip("mounting a tmpfs needs root")
    try:
        for suffix in ("h5", "dat"):
            proc = run_cli("spikesim", "simulate", *BIG, "--force", "--out",
                           disk / f"x.{suffix}", cwd=tmp_path)
            assert_clean_failure(proc, "disk is full", "nothing was written")
            assert not list(disk.iterdir())
        # without --force the free-space check refuses before writing anything
        proc = run_cli("spikesim", "simulate", *BIG, "--out", disk / "x.h5", cwd=tmp_path)
        assert_clean_failure(proc, "GiB free", "--force")
    finally:
        subprocess.run(["umount", str(disk)], capture_output=True, timeout=20)


class _FillingFile(io.FileIO):
    """A file that takes ``room`` bytes and then fails as on a full disk."""

    room = 50_000

    def write(self, data):
        n = memoryview(data).nbytes
        if self.tell() + n > self.room:
            raise OSError(errno.ENOSPC, "No space left on device")
        return super().write(data)


def _filling_open(path, mode="rb", buffering=-1, **kw):
    return _FillingFile(path, mode.replace("b", "").replace("+", "") +
                        ("+" if "+" in mode else ""))


def test_enospc_in_process_h5_and_dat(tmp_path, monkeypatch):
    """An injected ENOSPC (any file system): the same clean error, in this process."""
    import spikesim.io._guard as guard
    import spikesim.io.dat as dat
    from spikesim.io import write_dat, write_h5

    st = small_stream(n=2000, height=32, width=40)
    monkeypatch.setattr(guard, "open", _filling_open, raising=False)
    monkeypatch.setattr(dat, "open", _filling_open, raising=False)
    name = uuid.uuid4().hex
    for writer, suffix in ((write_h5, "h5"), (write_dat, "dat")):
        with pytest.raises(SpikeSimFileError, match="disk is full"):
            writer(tmp_path / f"{name}.{suffix}", st)
    assert not list(tmp_path.iterdir())
    monkeypatch.undo()
    write_h5(tmp_path / "ok.h5", st)  # the process is unharmed and writes normally after
    from spikesim.io import read_h5

    np.testing.assert_array_equal(read_h5(tmp_path / "ok.h5").packed, st.packed)
