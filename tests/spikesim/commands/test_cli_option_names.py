"""User trial: every bad command-line value is one line naming the option as typed
(``--start``, ``--set clock_hz``, ``--flat-masks``), never the library's parameter
(``start``, ``clock_hz``, ``flat_masks``); leftover arguments are reported by the
subcommand they were given to."""

from __future__ import annotations

import numpy as np
import pytest

from spikesim.cli import main
from spikesim.io import write_dat, write_h5


def _error(capsys) -> str:
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1, err
    return err.rstrip("\n")


@pytest.fixture
def h5(tmp_path, make_stream):
    return str(write_h5(tmp_path / "o.h5", make_stream(n=40, height=8, width=8)))


@pytest.fixture
def dat(tmp_path):
    write_dat(tmp_path / "cut.dat", np.zeros((4, 8, 8), np.uint8))
    return str(tmp_path / "cut.dat")


@pytest.mark.parametrize("flags, line", [
    (["--start", "-2"], "--start=-2 is invalid: expected an integer readout index in [0, 39]"),
    (["--start", "40"], "--start=40 is invalid: expected an integer readout index in [0, 39]"),
    (["--length", "-3"], "--length=-3 is invalid: expected an integer in [1, 40] (the stream "
                         "has 40 readouts, --start 0)"),
    (["--start", "4", "--length", "37"], "--length=37 is invalid: expected an integer in "
                                         "[1, 36] (the stream has 40 readouts, --start 4)"),
    (["--crop", "0,0,9,8"], "--crop=(0, 0, 9, 8) is invalid: expected (top, left, height, "
                            "width) with top+height <= 8"),
])
def test_convert_window_errors_name_the_options(h5, tmp_path, capsys, flags, line):
    dst = tmp_path / "c.h5"
    assert main(["convert", h5, str(dst), "--quiet", *flags]) == 1
    assert _error(capsys).startswith("spikesim convert: error: " + line)
    assert not dst.exists()


@pytest.mark.parametrize("flags, line", [
    (["--set", "clock_hz=-5"], "--set clock_hz=-5 is invalid: expected a finite number > 0 (Hz)"),
    (["--set", "cfa=XY"], "--set cfa='XY' is invalid: expected one of"),
    (["--set", 'noise={"type": "bogus"}'], "--set noise.type='bogus' is invalid"),
    (["--set", 'noise={"type": "paper", "sigma_g": -5}'], "--set noise: sigma_g=-5 is invalid"),
    (["--set", "bogus=1"], "--set=['bogus'] is invalid: expected fields among"),
    (["--sensor", "nosuch"], "--sensor='nosuch' is invalid: expected one of"),
    (["--scene-set", "exposure=-1"], "--scene-set exposure=-1 is invalid: expected a finite "
                                     "number > 0"),
    (["--scene-set", "speed=5"], "--scene-set speed=5 is invalid: expected a scene's own option "
                                 "(`spikesim scenes`); give --speed instead"),
])
def test_simulate_set_and_scene_set_errors_name_the_option(tmp_path, capsys, flags, line):
    out = tmp_path / "x.h5"
    assert main(["simulate", "flat", "--size", "16x16", "--readouts", "2", "--out", str(out),
                 *flags]) == 1
    assert _error(capsys).startswith("spikesim simulate: error: " + line)
    assert not out.exists()


def test_analyze_set_errors_name_the_option(tmp_path, capsys):
    assert main(["analyze", "transfer", "--out", str(tmp_path), "--set", "clock_hz=-5"]) == 1
    assert _error(capsys).startswith(
        "spikesim analyze transfer: error: --set clock_hz=-5 is invalid")


@pytest.mark.parametrize("command", ["info", "preview", "convert"])
@pytest.mark.parametrize("given", [["--height", "250"], ["--width", "8"]])
def test_half_a_dat_frame_size_says_give_both(dat, tmp_path, capsys, command, given):
    extra = {"info": [], "preview": ["--out", str(tmp_path / "p.png")],
             "convert": [str(tmp_path / "c.h5")]}[command]
    assert main([command, dat, *extra, *given, "--partial", "drop"]) == 1
    assert _error(capsys) == (f"spikesim {command}: error: give both --height and --width (the "
                              ".dat frame size), or neither to have it guessed")


def test_file_options_name_the_option(dat, h5, tmp_path, capsys):
    assert main(["info", dat, "--height", "8", "--width", "8", "--cfa", "XY"]) == 1
    assert _error(capsys).startswith("spikesim info: error: --cfa='XY' is invalid")
    assert main(["info", h5, "--split", "nope"]) == 1
    assert _error(capsys).startswith("spikesim info: error: --split='nope' is invalid")
    assert main(["info", str(tmp_path), "--sequence", "nosuch"]) == 1
    assert _error(capsys).startswith("spikesim info: error: --sequence='nosuch' is invalid")


@pytest.mark.parametrize("argv, prog", [
    (["verify", "{dat}", "--partial", "drop"], "spikesim verify"),
    (["info", "{dat}", "--bogus"], "spikesim info"),
    (["analyze", "calibrate", "{dat}", "--out", "x", "--bogus"], "spikesim analyze calibrate"),
])
def test_unknown_arguments_are_reported_by_their_subcommand(dat, capsys, argv, prog):
    """``spikesim verify cut.dat --partial drop`` said ``spikesim: error: ... (see
    spikesim --help)``: the top-level parser's name and help, not verify's."""
    with pytest.raises(SystemExit) as stop:
        main([a.format(dat=dat) for a in argv])
    assert stop.value.code == 2
    unknown = " ".join(argv[argv.index("--partial" if "--partial" in argv else "--bogus"):])
    assert _error(capsys) == (f"{prog}: error: unrecognized arguments: {unknown} "
                              f"(see {prog} --help)")


def test_verify_bad_option_values_are_usage_errors_not_damage(dat, capsys):
    """verify's exit status 1 means a damaged file: a bad option value is 2."""
    assert main(["verify", dat, "--height", "-5", "--width", "8"]) == 2
    assert _error(capsys) == ("spikesim verify: error: --height=-5 is invalid: expected an "
                              "integer >= 1 (pixels)")
    assert main(["verify", dat, "--height", "8"]) == 2
    assert "give both --height and --width" in _error(capsys)
    assert main(["verify", dat, "--height", "8", "--width", "8"]) == 0


# --- analyze calibrate ---------------------------------------------------------------------

@pytest.fixture
def capture(tmp_path):
    """300 readouts of 32x64 pixels: a ramp of rates, nothing flat (``ramp``), and the
    same size at one rate (``flat``)."""
    rng = np.random.default_rng(0)
    q = np.linspace(0.02, 0.6, 64)[None, None, :] * np.ones((1, 32, 1))
    write_dat(tmp_path / "ramp.dat", (rng.random((300, 32, 64)) < q).astype(np.uint8))
    write_dat(tmp_path / "flat.dat", (rng.random((300, 32, 64)) < 0.3).astype(np.uint8))
    mask = np.zeros((32, 64), bool)
    mask[:8, :8] = True
    np.save(tmp_path / "corner.npy", mask)
    np.save(tmp_path / "small.npy", np.zeros((4, 4), bool))
    labels = np.zeros((32, 64), np.int32)
    labels[:8, :8], labels[20:, 20:] = 1, 2
    np.save(tmp_path / "labels.npy", labels)
    return tmp_path


@pytest.mark.parametrize("name, flags, line", [
    ("flat", ["--no-detect"], "--no-detect needs --flat-masks (and --dark-mask)"),
    ("flat", ["--dark-mask", "small.npy"], "--dark-mask of shape (4, 4) is invalid: expected "
                                           "the capture's (H, W) = (32, 64)"),
    ("flat", ["--flat-masks", "small.npy"], "--flat-masks of shape (4, 4) is invalid"),
    ("flat", ["--flat-masks", "labels.npy", "--dark-mask", "corner.npy"],
     "the regions of --dark-mask and --flat-masks overlap (64 pixels in two regions): "
     "expected disjoint dark and flat regions"),
    ("flat", ["--sigma-t", "5"], "--sigma-t=5.0 is invalid: expected a relative s.d. in "
                                 "[0, 0.1]"),
    ("flat", ["--mismatch-split", "3"], "--mismatch-split=3.0 is invalid"),
    ("flat", ["--full-scale-rate", "3"], "--full-scale-rate=3.0 is invalid: expected a rate "
                                         "in (0, 1] spikes per readout"),
    ("flat", ["--flat-masks", "labels.npy", "--levels", "1,2", "--full-scale-rate", "0.5"],
     "--full-scale-rate=0.5 is invalid: expected no --full-scale-rate when --levels are given"),
])
def test_calibrate_errors_name_its_options(capture, capsys, monkeypatch, name, flags, line):
    monkeypatch.chdir(capture)
    assert main(["analyze", "calibrate", f"{name}.dat", "--height", "32", "--width", "64",
                 "--out", "report", "--no-check", "--no-progress", *flags]) == 1
    err = capsys.readouterr().err
    last = err.splitlines()[-1]
    assert last.startswith("spikesim analyze calibrate: error: ") and line in last, err
    for parameter in ("flat_masks", "dark_mask", "capture=", "temporal_threshold_noise",
                      "mismatch_split", "full_scale_rate", "or None"):
        assert parameter not in last


@pytest.mark.parametrize("flags", [[], ["--dark-mask", "corner.npy"]])
def test_calibrate_without_a_flat_region_says_so(capture, capsys, monkeypatch, flags):
    """Nothing flat (issue 53): calibrated without a flat region, not refused; the
    note says why, naming what detection left out."""
    monkeypatch.chdir(capture)
    assert main(["analyze", "calibrate", "ramp.dat", "--height", "32", "--width", "64",
                 "--cfa", "mono", "--out", "report", "--no-check", "--no-progress",
                 *flags]) == 0
    out = capsys.readouterr().out
    assert "no flat region found (a uniform, static region of >= 256 pixels" in out
    assert "calibrated from per-pixel temporal statistics and spatial residuals" in out


def test_dat_options_given_for_an_hdf5_file_are_said_to_be_ignored(tmp_path, capsys):
    """--height, --cfa and the other .dat options were ignored silently for an HDF5 file."""
    import spikesim as ss
    from spikesim.cli import main

    sensor = ss.Sensor(height=8, width=8, cfa="RGGB")
    stream = ss.simulate(ss.scenes.procedural("flat", size=(8, 8)), sensor, n_readouts=3)
    ss.io.write_h5(tmp_path / "a.h5", stream)
    assert main(["info", str(tmp_path / "a.h5")]) == 0
    assert "ignored" not in capsys.readouterr().err
    assert main(["info", str(tmp_path / "a.h5"), "--height", "8", "--cfa", "GRBG",
                 "--no-flip"]) == 0
    assert capsys.readouterr().err == (
        "spikesim info: note: --height, --no-flip, --cfa ignored: they describe a .dat "
        "capture, and a spikesim HDF5 file records its own\n")
