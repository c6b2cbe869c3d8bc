"""Faults of the hostile campaign of issue 53, item 5: each a clean one-line error (no
traceback, no crash) or the right result."""

from __future__ import annotations

import json
import subprocess
import sys
import warnings

import numpy as np
import pytest

import spikesim as ss
from spikesim.errors import SpikeSimValueError
from tests.support.dataset_helpers import write_frames
from tests.support.fault_helpers import REPO, cli_env, cli_fails, run_cli_here


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
        cli_fails("spikesim", argv, "electrons_per_threshold=1e-30", "[0.001, 1e+09]")
    (tmp_path / "m.toml").write_text(
        '[dataset]\nname = "e"\nsize = [16, 16]\nwindow = 20\n\n[sensor]\npreset = "ideal"\n\n'
        '[[noise]]\nmode = "physical"\n'
        'electrons_per_threshold = {loguniform = [1e-20, 1000]}\n\n'
        '[[sources]]\nkind = "procedural"\nscenes = ["astronaut"]\ncount = 1\n')
    for extra in (["--dry-run"], []):  # refused at load: before any plan, file or temporary
        cli_fails("spikesim", ["dataset", "m.toml", "--out", "ds", *extra],
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
    cli_fails("spikesim", ["dataset", "m.toml", "--out", "ds", "--dry-run"],
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
    cli_fails("spikejdd", argv, "--methods", "at least one method")


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


# --- checksum blind spot: 16-bit words 0x0000 <-> 0xFFFF ---------------------------------
def _saturated_file(path, version2=True):
    """An uncompressed file (stored bytes = data) whose first spike chunks are all 1s and
    whose ground truth is 1.0 (float32 0x3F800000: a 0x0000 low word)."""
    import h5py

    from spikesim.io.h5.format import attrs_digest
    from spikesim.io.h5.writer import H5Writer

    t, h, w = 70, 12, 40
    packed = np.full((t, h, w // 8), 0xFF, np.uint8)
    packed[40:] = np.random.default_rng(0).integers(0, 256, (t - 40, h, w // 8), np.uint8)
    meta = {"height": h, "width": w, "cfa": "RGGB", "clock_hz": 20000.0}
    with H5Writer(path, meta, compression="none", clean=True) as wr:
        for t0 in range(0, t, 25):  # appends that do not fall on chunk boundaries
            wr.append(packed[t0:t0 + 25], packed[t0:t0 + 25])
        wr.add_gt(np.ones((2, h, w, 3), np.float32), [10, 60])
    if not version2:  # as spikesim wrote it before the chunk CRCs
        with h5py.File(path, "r+") as f:
            for name in ("spikes", "clean_spikes", "gt", "gt_index"):
                del f[f"{name}_crc32"]
            del f.attrs["chunk_checksum"]
            f.attrs["format_version"] = 1
            f.attrs["attrs_sha256"] = attrs_digest(f.attrs)
    return packed


def _swap_word(src, dst, dataset, chunk=0, at=64, old=b"\xff\xff", new=b"\x00\x00"):
    """Copy ``src`` to ``dst`` with one 16-bit word of a stored chunk swapped; a
    Fletcher-32 blind spot (the chunk's stored checksum still matches)."""
    import h5py

    with h5py.File(src, "r") as f:
        info = f[dataset].id.get_chunk_info(chunk)
    data = bytearray(src.read_bytes())
    pos = info.byte_offset + at
    assert bytes(data[pos:pos + 2]) == old
    data[pos:pos + 2] = new
    dst.write_bytes(bytes(data))
    return dst


@pytest.mark.parametrize("dataset,old,new", [
    ("spikes", b"\xff\xff", b"\x00\x00"), ("clean_spikes", b"\xff\xff", b"\x00\x00"),
    ("gt", b"\x00\x00", b"\xff\xff")])
def test_swapped_words_are_damage(tmp_path, monkeypatch, dataset, old, new):
    from spikesim.io import open_h5, verify_file

    monkeypatch.chdir(tmp_path)
    src = tmp_path / "sat.h5"
    packed = _saturated_file(src)
    with open_h5(src) as seq:  # the intact file reads back exactly
        np.testing.assert_array_equal(seq.read_packed(), packed)
        np.testing.assert_array_equal(seq.read_all_gt(), 1.0)
    assert verify_file(src)["ok"] and verify_file(src)["checksums"] == "crc32+fletcher32"
    bad = _swap_word(src, tmp_path / "bad.h5", dataset, old=old, new=new)
    report = verify_file(bad)
    assert report["status"] == "damaged", report
    assert f"damaged data in its {dataset} (chunk 0, 0, 0" in report["problems"][0], report
    code, err, out = run_cli_here("spikesim", ["verify", bad])
    err += out
    assert code == 1 and "DAMAGED" in err and "1 damaged" in err and "CRC-32" in err, err
    cli_fails("spikesim", ["convert", bad, "copy.h5"], "bad.h5", dataset, "CRC-32")
    assert not [p.name for p in tmp_path.iterdir() if "copy" in p.name]
    with open_h5(bad) as seq, pytest.raises(ss.errors.SpikeSimFormatError, match="CRC-32"):
        if dataset == "gt":
            seq.read_gt(0, crop=(2, 3, 4, 5))  # a window touching the chunk: checked too
        else:
            seq.read_window(3, 4, crop=(1, 2, 3, 4), clean=dataset == "clean_spikes")


def test_version_1_files_still_read_and_verify_says_fletcher_only(tmp_path, monkeypatch):
    from spikesim.io import open_h5, verify_file

    monkeypatch.chdir(tmp_path)
    src = tmp_path / "v1.h5"
    packed = _saturated_file(src, version2=False)
    report = verify_file(src)
    assert report["ok"] and report["format_version"] == 1 and report["checksums"] == "fletcher32"
    assert any("Fletcher-32 only" in n and "0xFFFF" in n for n in report["notes"]), report
    code, err, out = run_cli_here("spikesim", ["verify", src])
    assert code == 0 and "Fletcher-32 only" in err + out, err + out
    with open_h5(src) as seq:
        np.testing.assert_array_equal(seq.read_packed(), packed)
    # the blind spot itself: a version-1 file cannot see the swap (why version 2 exists)
    blind = _swap_word(src, tmp_path / "blind.h5", "spikes")
    assert verify_file(blind)["ok"]
    # a copy carries the chunk CRCs
    code, err, _ = run_cli_here("spikesim", ["convert", src, "v2.h5"])
    assert code == 0, err
    assert verify_file(tmp_path / "v2.h5")["checksums"] == "crc32+fletcher32"
    with open_h5(tmp_path / "v2.h5") as seq:
        np.testing.assert_array_equal(seq.read_packed(), packed)
