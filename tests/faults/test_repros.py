"""The repros of the reliability review, one test each: a clean one-line error (exit 1, no
traceback) or the correct result.  Disk, kill, corruption and concurrency repros live in
the other files of this folder."""

from __future__ import annotations

import json
import subprocess
import warnings

import numpy as np
import pytest

import spikesim as ss
from spikesim.errors import SpikeSimError, SpikeSimTypeError, SpikeSimValueError
from tests.support.fault_helpers import cli_command, cli_env, cli_fails, full_only, run_cli_here


@pytest.fixture()
def h5(h5_original, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    return h5_original[0]


# --- item 6: tracebacks that are now one line -----------------------------------------
def test_preview_fps_zero(h5):
    cli_fails("spikesim", ["preview", h5, "--out", "x.gif", "--fps", "0"], "--fps")


def test_non_utf8_manifest(tmp_path, h5):
    bad = tmp_path / "m.toml"
    bad.write_bytes(b"[dataset]\nname = \"\xff\xfe\"\n")
    cli_fails("spikesim", ["dataset", bad, "--out", "ds"], "UTF-8")


def test_dataset_out_is_an_existing_file(tmp_path, h5):
    (tmp_path / "f").write_text("x")
    cli_fails("spikesim", ["dataset", "builtin:demo", "--out", tmp_path / "f", "--limit", "1"],
           "existing file")


@full_only
def test_unreachable_scheduler(tmp_path, h5):
    pytest.importorskip("distributed")
    cli_fails("spikesim", ["dataset", "builtin:demo", "--out", "ds", "--limit", "1",
                        "--scheduler", "tcp://127.0.0.1:1"], "Dask scheduler")
    assert not (tmp_path / "ds").exists()  # refused before anything is written


@pytest.mark.parametrize("extra,needle", [
    (["--workers", "2", "--dask-local", "2"], "--workers=2 is invalid: expected 1 with "
                                              "--dask-local"),
    (["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "1 with --scheduler"),
    (["--dask-local", "2", "--scheduler", "tcp://127.0.0.1:1"], "not both"),
    (["--workers", "2", "--dask-local", "2", "--dry-run"], "--workers=2"),
])
def test_dataset_refuses_two_executors(tmp_path, h5, extra, needle):
    cli_fails("spikesim", ["dataset", "builtin:demo", "--out", "ds", "--limit", "1", *extra],
           needle)
    assert not (tmp_path / "ds").exists()


@pytest.mark.parametrize("n,needle", [("100000000000000000000", "--readouts"),
                                      (str(10**15), "--readouts"),
                                      (str(10**11), "GiB free")])
def test_simulate_absurd_readouts(tmp_path, h5, n, needle):
    cli_fails("spikesim", ["simulate", "astronaut", "--readouts", n, "--out", "x.h5"], needle)
    assert not list(tmp_path.glob("*x.h5*"))


def test_reconstruct_bad_centers_and_device(h5):
    pytest.importorskip("torch")
    cli_fails("spikejdd", ["reconstruct", h5, "--method", "tfp+bilinear", "--out", "r",
                        "--centers", "abc"], "--centers")
    cli_fails("spikejdd", ["reconstruct", h5, "--out", "r", "--device", "cuda:7"], "--device")


def test_train_unknown_model_field_and_bad_config(tmp_path, h5):
    pytest.importorskip("torch")
    cli_fails("spikejdd", ["train", "--data", h5, "--steps", "1", "--model", "lite", "--set",
                        "nosuch=3", "--out", "run", "--quiet"], "nosuch")
    (tmp_path / "bad.json").write_text("{not json")
    cli_fails("spikejdd", ["train", "--config", tmp_path / "bad.json"], "--config")


def test_info_into_a_closed_pipe(h5):
    proc = subprocess.Popen(cli_command("spikesim", "info", h5, "--json"), env=cli_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()  # as `| head` after its lines
    err = proc.stderr.read().decode()
    proc.wait(timeout=120)
    assert proc.returncode != 0 and "Traceback" not in err and "BrokenPipe" not in err, err


def test_debug_shows_the_traceback(h5):
    """With --debug (anywhere on the line) errors propagate, so Python prints the traceback."""
    from spikesim.cli import main

    with pytest.raises(SpikeSimValueError, match="--stats-readouts"):
        main(["info", str(h5), "--stats-readouts", "-1", "--debug"])


# --- item 10: nonsense that used to be accepted ---------------------------------------
def test_nonsense_options_are_refused(tmp_path, h5):
    cli_fails("spikesim", ["info", h5, "--stats-readouts", "-1"], "--stats-readouts")
    cli_fails("spikesim", ["simulate", "astronaut", "--fps", "-5", "--readouts", "10",
                        "--out", "x.h5"], "--fps")
    cli_fails("spikesim", ["convert", h5, "x.txt"], "DST")
    cli_fails("spikesim", ["preview", h5, "--out", "p.png", "--window", "100000"], "--window")
    assert not [p for p in tmp_path.iterdir() if p.name != "orig.h5"]


def test_video_source_pointing_at_a_spike_file(tmp_path, h5):
    from spikesim.dataset import parse_manifest

    with pytest.raises(SpikeSimValueError, match="not a video source"):
        parse_manifest({
            "dataset": {"name": "v", "size": [16, 16]},
            "sensor": {"preset": "ideal"},
            "noise": [{"mode": "none", "label": "c"}],
            "sources": [{"kind": "video", "path": str(h5), "split": "train"}],
        })


def test_numbers_are_numbers_whatever_their_type():
    s = ss.Sensor(height=np.int64(8), width=np.int32(8), clock_hz=np.float32(20000))
    assert (s.height, s.width) == (8, 8) and type(s.height) is int
    with pytest.raises(SpikeSimValueError, match="sigma_g"):
        ss.noise.PaperNoise(sigma_g="5")
    with pytest.raises(SpikeSimValueError, match="height"):
        ss.Sensor(height=True, width=8)


def test_factory_returning_garbage_is_named(tmp_path, monkeypatch):
    from spikesim.dataset.manifest import resolve_factory

    (tmp_path / "garbage_factory.py").write_text("def make(**kw):\n    return 42\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(SpikeSimTypeError, match="garbage_factory:make.*returned int"):
        resolve_factory("garbage_factory:make")(index=0, size=(8, 8), seed=0)


# --- item 9: runaway work is flagged --------------------------------------------------
def test_runaway_key_frames_warn_and_the_cli_asks_for_force(tmp_path, h5):
    from spikesim.workload import RunawayWorkWarning, estimate_key_frames

    scene = ss.scenes.procedural("astronaut", motion="pan", size=(8, 8), speed=1e9)
    with pytest.warns(RunawayWorkWarning, match="key frames"):
        ss.simulate_chunks(scene, ss.Sensor(height=8, width=8), 10)
    flicker = ss.scenes.procedural("flicker", size=(8, 8))
    assert estimate_key_frames(flicker, 200_000 / 20_000) > 20_000
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a normal request: no warning
        ss.simulate_chunks(ss.scenes.procedural("astronaut", motion="pan", size=(8, 8)),
                           ss.Sensor(height=8, width=8), 400)
    line = cli_fails("spikesim", ["simulate", "flicker", "--size", "8x8", "--readouts", "200000",
                               "--out", "f.h5"], "key frames", "--force")
    assert "flicker" in line


def test_errors_are_spikesim_errors_in_the_library(h5):
    from spikesim.io import open_h5

    with pytest.raises(SpikeSimError):
        open_h5(h5).read_gt(99)
    json.dumps(ss.io.verify(h5))  # reports are JSON-able


# --- found by a user trial after the suite --------------------------------------------------

@pytest.mark.parametrize("prog, argv", [
    ("spikesim", ["simulate", "astronaut", "--readouts", "abc", "--out", "x.h5"]),
    ("spikesim", ["info"]),
    ("spikejdd", ["reconstruct"]),
])
def test_usage_errors_are_one_line(prog, argv):
    code, err, _ = run_cli_here(prog, argv)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "--help" in err, err


def test_verify_checks_dat_lengths_at_the_given_size(tmp_path):
    spikes = np.zeros((10, 64, 64), np.uint8)
    ss.io.write_dat(tmp_path / "a.dat", spikes)
    whole = (tmp_path / "a.dat").read_bytes()
    (tmp_path / "t.dat").write_bytes(whole[:-100])
    assert run_cli_here("spikesim", ["verify", tmp_path / "a.dat", "--height", 64,
                                     "--width", 64])[0] == 0
    code, _, out = run_cli_here("spikesim", ["verify", tmp_path / "t.dat", "--height", 64,
                                      "--width", 64])
    assert code == 1 and "DAMAGED" in out and "64x64" in out  # truncated, at the size given
    # 64x64 is no known size
    code, _, out = run_cli_here("spikesim", ["verify", tmp_path / "a.dat"])
    assert code == 3 and "--height" in out  # not checked: not "all verified"
    code, err, _ = run_cli_here("spikesim", ["verify", tmp_path / "a.dat", "--height", 64])
    assert code == 2 and "--width" in err  # a usage error: 1 would read as damage
