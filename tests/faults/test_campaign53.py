"""Faults of the hostile campaign of issue 53, item 5: each a clean one-line error (no
traceback, no crash) or the right result."""

from __future__ import annotations

import contextlib
import io
import json
import subprocess
import sys
import warnings

import numpy as np
import pytest

import spikesim as ss
from spikesim.errors import SpikeSimValueError
from tests.support.dataset_helpers import write_frames
from tests.support.fault_helpers import REPO, cli_env


def _main(prog, argv):
    if prog == "spikesim":
        from spikesim.cli import main
    else:
        from spikejdd.cli import main
    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            code = main([str(a) for a in argv])
        except SystemExit as exc:
            code = exc.code
    return code, err.getvalue(), out.getvalue()


def _fails(prog, argv, *needles):
    code, err, _ = _main(prog, argv)
    assert code == 1 and "Traceback" not in err, err
    line = [ln for ln in err.splitlines() if "error" in ln][-1]
    for n in needles:
        assert n in line, (n, line)
    return line


def _scene_sensor(n=16, m=20):
    return (ss.scenes.procedural("astronaut", motion="pan", size=(n, m)),
            ss.Sensor(height=n, width=m))


# --- physical noise: electrons_per_threshold within what the kernel supports -------------
@pytest.mark.parametrize("e", [1e-18, 1e-30, 5e-4, 1e20, 2e9, float("inf"), True])
def test_electrons_per_threshold_out_of_range_is_refused(e):
    with pytest.raises(SpikeSimValueError) as info:
        ss.noise.PhysicalNoise(electrons_per_threshold=e)
    assert "electrons_per_threshold=" in str(info.value)
    assert "[0.001, 1e+09]" in str(info.value)


def test_electrons_per_threshold_on_the_command_lines(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for argv in (["simulate", "astronaut", "--readouts", "10", "--size", "16x16", "--sensor",
                  "physical", "--set", "noise.electrons_per_threshold=1e-30", "--out", "x.h5"],
                 ["analyze", "snr", "--sensor", "physical", "--set",
                  "noise.electrons_per_threshold=1e-30", "--out", "snr"]):
        _fails("spikesim", argv, "electrons_per_threshold=1e-30", "[0.001, 1e+09]")
    (tmp_path / "m.toml").write_text(
        '[dataset]\nname = "e"\nsize = [16, 16]\nwindow = 20\n\n[sensor]\npreset = "ideal"\n\n'
        '[[noise]]\nmode = "physical"\n'
        'electrons_per_threshold = {loguniform = [1e-20, 1000]}\n\n'
        '[[sources]]\nkind = "procedural"\nscenes = ["astronaut"]\ncount = 1\n')
    for extra in (["--dry-run"], []):  # refused at load: before any plan, file or temporary
        _fails("spikesim", ["dataset", "m.toml", "--out", "ds", *extra],
               "noise[0]: electrons_per_threshold=1e-20", "[0.001, 1e+09]")
        assert not (tmp_path / "ds").exists()


_AT_THE_BOUNDS = """
import json, sys, warnings
import numpy as np, spikesim as ss
warnings.simplefilter("ignore")
lo, hi = ss.noise.ELECTRONS_PER_THRESHOLD_RANGE
out = {}
for reset in ("modulo", "subtract", "zero"):
    for motion in ("pan", None):
        scene = (ss.scenes.procedural("astronaut", motion=motion, size=(16, 64)) if motion
                 else ss.scenes.Static(np.full((16, 64), 0.5, np.float32)))
        for e in (lo, hi):  # defaults elsewhere: every source of the kernel on
            sensor = ss.Sensor(height=16, width=64, cfa=None, reset=reset,
                               noise=ss.noise.PhysicalNoise(electrons_per_threshold=e))
            ss.simulate(scene, sensor, 200, seed=2)
        # at the top: shot noise only, E = 1e9 -> the noise-free rate (not a dark sensor)
        quiet = ss.noise.PhysicalNoise(electrons_per_threshold=hi, dark_current_rel=0.0,
                                       threshold_mismatch=0.0, prnu=0.0,
                                       temporal_threshold_noise=0.0, hot_pixel_fraction=0.0)
        st = ss.simulate(scene, ss.Sensor(height=16, width=64, cfa=None, reset=reset,
                                          noise=quiet), 400, seed=2, clean_twin=True)
        out[f"{reset}-{motion}"] = [float(st.unpack().mean()),  # (width 64: no padding)
                                    float(np.unpackbits(st.clean_packed).mean())]
# at the bottom: the per-spike sampler against the per-readout one (subtract: bursts)
bright = ss.scenes.Static(np.full((64, 64), 1.0, np.float32))
sensor = ss.Sensor(height=64, width=64, cfa=None, reset="subtract",
                   noise=ss.noise.PhysicalNoise(electrons_per_threshold=lo, dark_current_rel=0.0,
                                                hot_pixel_fraction=0.0))
out["low"] = [float(ss.simulate(bright, sensor, 300, seed=s, shot_sampler=k).unpack().mean())
              for k in ("event", "readout") for s in (1, 2, 3)]
print(json.dumps(out))
"""


def test_electrons_per_threshold_bounds_run_and_give_the_right_rate():
    """In a subprocess (a kernel fault must not take the test run down): both ends of
    the range run for every reset, static and moving; at the top the rate is the
    noise-free one; at the bottom the two shot-noise samplers agree."""
    proc = subprocess.run([sys.executable, "-c", _AT_THE_BOUNDS], cwd=REPO, env=cli_env(),
                          capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    low = out.pop("low")
    assert len(out) == 6
    for key, (noisy, clean) in out.items():
        assert clean > 0.1 and abs(noisy - clean) < 0.01 * clean, (key, noisy, clean)
    event, readout = np.mean(low[:3]), np.mean(low[3:])
    spread = np.std(low) + 1e-3
    assert event > 0.01 and abs(event - readout) < 4 * spread, low

# --- tracebacks from the API: absurd readout counts --------------------------------------
@pytest.mark.filterwarnings("ignore::Warning")  # (the key frames' runaway warning)
@pytest.mark.parametrize("n", [10**15, 2**70])
def test_simulate_absurd_readouts_in_the_api(n):
    scene, sensor = _scene_sensor()
    with pytest.raises(SpikeSimValueError, match="n_readouts") as info:
        ss.simulate(scene, sensor, n)
    assert "\n" not in str(info.value)
    if n == 10**15:  # within the index range, but the whole stream would not fit in memory
        assert "GiB" in str(info.value) and "simulate_chunks" in str(info.value)


def test_simulate_chunks_takes_any_indexable_length_and_no_more():
    scene, sensor = _scene_sensor()
    with warnings.catch_warnings():  # (the key frames' runaway warning)
        warnings.simplefilter("ignore")
        run = ss.simulate_chunks(scene, sensor, 10**15)  # streamed: nothing held whole
    assert len(run) == 10**15
    with pytest.raises(SpikeSimValueError, match=r"n_readouts=.*\[1, 9007199254740992\]"):
        ss.simulate_chunks(scene, sensor, 2**53 + 1)


# --- dry runs that passed what the build then failed: video options ----------------------
def _video_manifest(tmp_path, **source):
    clip = write_frames(tmp_path / "clip", 4, size=(48, 64), px_per_frame=2)
    src = {"kind": "video", "path": str(clip), "fps": 100.0, "split": "train", **source}
    return {"dataset": {"name": "v", "size": [16, 16], "window": 20},
            "sensor": {"preset": "ideal"}, "noise": [{"mode": "none", "label": "c"}],
            "sources": [src]}


@pytest.mark.parametrize("options,needle", [
    ({"wobble": 1}, "sources[0].options.wobble=1 is invalid: expected a keyword"),
    ({"max_px": -3}, "sources[0].options.max_px=-3"),
    ({"max_px": {"uniform": [-1, 2]}}, "sources[0].options.max_px=-1.0"),
    ({"flow": {"choice": ["farneback", "nope"]}}, "sources[0].options.flow='nope'"),
    ({"fps": 30}, "sources[0].options.fps"),
])
def test_video_options_are_checked_at_load(tmp_path, options, needle):
    from spikesim.dataset import parse_manifest

    with pytest.raises(SpikeSimValueError) as info:
        parse_manifest(_video_manifest(tmp_path, options=options))
    assert needle in str(info.value), str(info.value)


@pytest.mark.filterwarnings("ignore::Warning")  # (the aspect ratio's warning)
def test_valid_video_options_still_load(tmp_path):
    from spikesim.dataset import parse_manifest, plan_tasks

    m = parse_manifest(_video_manifest(tmp_path, options={"max_px": {"uniform": [0.5, 2]},
                                                          "occlusion": False}))
    (task,) = plan_tasks(m)
    assert 0.5 <= task.scene["options"]["max_px"] <= 2


def test_video_options_dry_run_exits_1(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    write_frames(tmp_path / "clip", 4, size=(48, 64), px_per_frame=2)
    (tmp_path / "m.toml").write_text(
        '[dataset]\nname = "v"\nsize = [16, 16]\nwindow = 20\n\n[sensor]\npreset = "ideal"\n\n'
        '[[sources]]\nkind = "video"\npath = "clip"\nfps = 100.0\noptions = {wobble = 1}\n')
    _fails("spikesim", ["dataset", "m.toml", "--out", "ds", "--dry-run"],
           "sources[0].options.wobble")
    assert not (tmp_path / "ds").exists()


# --- unbounded planning: per_second is capped as count is --------------------------------
@pytest.mark.parametrize("per_second,needle", [
    (1e9, "at most 1,000,000 clips a video"), (1e7, "at most 1,000,000 clips a video"),
    (float("inf"), "a finite number > 0")])
def test_per_second_is_capped(tmp_path, per_second, needle):
    import time

    from spikesim.dataset import parse_manifest

    t0 = time.perf_counter()
    with pytest.raises(SpikeSimValueError, match="sources\\[0\\].per_second") as info:
        parse_manifest(_video_manifest(tmp_path, per_second=per_second, fps=4.0))
    assert needle in str(info.value)
    assert time.perf_counter() - t0 < 30  # refused at once, not after planning


# --- spikejdd: an empty --methods; a relative root given with --set -----------------------
@pytest.mark.parametrize("argv", [
    ["evaluate", "--sweep", "--methods", ""], ["evaluate", "--sweep", "--methods", " , "],
    ["reconstruct", "x.h5", "--methods", "", "--out", "o"]])
def test_empty_methods_is_an_error(tmp_path, monkeypatch, argv):
    monkeypatch.chdir(tmp_path)
    _fails("spikejdd", argv, "--methods", "at least one method")


def test_relative_set_path_is_from_the_current_directory(tmp_path, monkeypatch):
    from spikesim.dataset import load_manifest

    write_frames(tmp_path / "data" / "clip", 4, size=(48, 64), px_per_frame=2)
    folder = tmp_path / "manifests"
    folder.mkdir()
    (folder / "m.toml").write_text(
        '[dataset]\nname = "v"\nsize = [16, 16]\nwindow = 20\n\n[sensor]\npreset = "ideal"\n\n'
        '[[sources]]\nkind = "video"\npath = "${CLIPS}/clip"\nfps = 100.0\n\n'
        '[[sources]]\nkind = "video"\npath = "clip"\nfps = 100.0\n')
    write_frames(folder / "clip", 4, size=(48, 64), px_per_frame=2)
    monkeypatch.chdir(tmp_path)
    m = load_manifest(folder / "m.toml", {"CLIPS": "data"})
    assert m.sources[0].path == str(tmp_path / "data" / "clip")
    assert m.sources[1].path == str(folder / "clip")  # a plain relative path: the manifest's
    m = load_manifest(folder / "m.toml", {"CLIPS": str(tmp_path / "data")})  # absolute: as is
    assert m.sources[0].path == str(tmp_path / "data" / "clip")

