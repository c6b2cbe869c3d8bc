"""`spikesim simulate VIDEO`: --crop, --start-s/--stop-s, --gt/--gt-every, and the video's
warnings on stderr, on a small frame folder (6 frames of 32x48, a texture panning 1 px a
frame) played at 1000 fps so that a few milliseconds cover the clip."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

import spikesim as ss
from spikesim.cli import main


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    out = tmp_path_factory.mktemp("frames")
    rng = np.random.default_rng(7)
    base = cv2.resize(rng.integers(0, 255, (8, 14, 3), np.uint8), (56, 32),
                      interpolation=cv2.INTER_CUBIC)
    for i in range(6):
        assert cv2.imwrite(str(out / f"{i:05d}.png"), base[:, i : i + 48])
    return out


def _err_lines(capsys, word: str) -> list[str]:
    return [ln for ln in capsys.readouterr().err.splitlines() if word in ln]


def test_crop_trim_and_gt_every_give_the_python_api_stream(folder, tmp_path, capsys):
    """The options are exactly the Python API's: the same bits and ground truth as
    ``ss.simulate(ss.scenes.video(..., crop=, start_s=, stop_s=), ..., gt_readouts=)``,
    the crop at its stored size when --size is not given."""
    out = tmp_path / "s.h5"
    assert main(["simulate", str(folder), "--fps", "1000", "--crop", "4,8,16,24",
                 "--start-s", "0.0015", "--stop-s", "0.0045", "--readouts", "50",
                 "--gt-every", "10", "--seed", "3", "--out", str(out)]) == 0
    assert not _err_lines(capsys, "warning")  # 2.5 ms of video: within it
    got = ss.io.read_h5(out)
    scene = ss.scenes.video(folder, fps=1000.0, crop=(4, 8, 16, 24), start_s=0.0015,
                            stop_s=0.0045)
    want = ss.simulate(scene, ss.Sensor.preset("ideal", height=16, width=24), 50, seed=3,
                       gt_readouts=[5, 15, 25, 35, 45])
    assert got.gt_index.tolist() == [5, 15, 25, 35, 45]
    np.testing.assert_array_equal(got.packed, want.packed)
    np.testing.assert_array_equal(got.gt, want.gt)
    described = got.meta["scene"]
    assert described["crop"] == [4, 8, 16, 24] and described["first_frame"] == 1
    assert (described["start_s"], described["stop_s"], described["n_frames"]) == (0.0015,
                                                                                  0.0045, 4)


@pytest.mark.parametrize("flags, index", [
    ([], [10]), (["--gt", "middle"], [10]), (["--gt", "all"], list(range(20))),
    (["--gt", "none"], []), (["--gt", "7,1,3"], [1, 3, 7]), (["--gt-every", "8"], [4, 12]),
])
def test_gt_options_choose_the_ground_truth_readouts(folder, tmp_path, flags, index):
    out = tmp_path / "g.h5"
    assert main(["simulate", str(folder), "--fps", "1000", "--size", "16x24", "--readouts",
                 "20", "--out", str(out), *flags]) == 0
    got = ss.io.read_h5(out)
    assert got.gt_index.tolist() == index and len(got.gt) == len(index)


@pytest.mark.parametrize("flags, line", [
    (["--crop", "0,0,40,10"], "--crop=(0, 0, 40, 10) is invalid: expected a box inside the "
                              "32x48 frame"),
    (["--start-s", "-1"], "--start-s=-1.0 is invalid: expected a finite number >= 0"),
    (["--start-s", "nan"], "--start-s=nan is invalid"),
    (["--start-s", "0.002", "--stop-s", "0.002"], "--stop-s=0.002 is invalid: expected a "
                                                  "finite number > 0.002"),
    (["--start-s", "0.0051"], "--start-s/--stop-s: video="),
    (["--gt", "some"], "--gt='some' is invalid: expected middle, all, none, or readout indices"),
    (["--gt", "3,20"], "--gt=20 is invalid: expected an integer in [0, 19]"),
    (["--gt-every", "0"], "--gt-every=0 is invalid: expected an integer in [1, 20]"),
    (["--gt", "all", "--gt-every", "4"], "--gt-every=4 is invalid: expected no --gt-every "
                                         "with --gt all"),
    (["--scene-set", "level=1"], "--speed/--scene-set=['level=1'] is invalid"),
])
def test_bad_video_options_are_one_line_naming_the_option(folder, tmp_path, capsys, flags,
                                                          line):
    out = tmp_path / "x.h5"
    assert main(["simulate", str(folder), "--fps", "1000", "--size", "16x24", "--readouts",
                 "20", "--out", str(out), *flags]) == 1
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert err.startswith("spikesim simulate: error: " + line), err
    assert not out.exists()


@pytest.mark.parametrize("flags, line", [
    (["--crop", "0,0,8"], "error: --crop '0,0,8': expected TOP,LEFT,HEIGHT,WIDTH"),
    (["--start-s", "soon"], "error: argument --start-s: invalid float value: 'soon'"),
])
def test_malformed_video_options_are_usage_errors(folder, tmp_path, capsys, flags, line):
    out = tmp_path / "x.h5"
    with pytest.raises(SystemExit) as stop:
        main(["simulate", str(folder), "--readouts", "20", "--out", str(out), *flags])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and err.startswith(f"spikesim simulate: {line}"), err


@pytest.mark.parametrize("flags", [["--crop", "0,0,8,8"], ["--start-s", "0.1"],
                                   ["--stop-s", "0.1"]])
def test_video_options_are_refused_for_a_built_in_scene(tmp_path, capsys, flags):
    out = tmp_path / "x.h5"
    assert main(["simulate", "flat", "--size", "8x8", "--readouts", "5", "--out", str(out),
                 *flags]) == 1
    err = capsys.readouterr().err
    assert f"error: {flags[0]}=" in err and "none for a built-in scene" in err, err
    assert not out.exists()


def test_ground_truth_needs_an_h5_output(folder, tmp_path, capsys):
    out = tmp_path / "x.dat"
    assert main(["simulate", str(folder), "--fps", "1000", "--size", "16x24", "--readouts",
                 "20", "--gt", "all", "--out", str(out)]) == 1
    assert "--gt='all' is invalid: expected no ground truth with a .dat output" in \
        capsys.readouterr().err
    assert not out.exists()


def test_the_video_end_warning_reaches_stderr_naming_the_whole_request(folder, tmp_path,
                                                                       capsys):
    """600 readouts at 20 kHz ask for 30 ms of a 5 ms clip: one warning line that names
    30 ms (the whole request, not the end of the first 256-readout chunk, 12.8 ms), and
    the stream is still written (the last frame held)."""
    out = tmp_path / "long.h5"
    assert main(["simulate", str(folder), "--fps", "1000", "--size", "16x24", "--readouts",
                 "600", "--gt", "none", "--out", str(out)]) == 0
    lines = _err_lines(capsys, "warning")
    assert lines == ["spikesim simulate: warning: the video ends at 0.005 s (6 frames at 1000 "
                     "fps) and 0.03 s are asked for: the rest holds its last frame (ask for "
                     "fewer readouts, or a longer clip)"]
    assert ss.io.open_h5(out).n_readouts == 600


def test_a_squashing_size_warns_naming_the_cli_options(folder, tmp_path, capsys):
    """The aspect warning says what to change on the command line (--size, --crop), not
    the Python API's keywords; a --crop of the --size aspect does not warn."""
    out = tmp_path / "q.h5"
    assert main(["simulate", str(folder), "--fps", "1000", "--size", "16x16", "--readouts",
                 "5", "--out", str(out)]) == 0
    lines = _err_lines(capsys, "warning")
    assert lines == ["spikesim simulate: warning: --size 16x16 squashes the 32x48 frames "
                     "(aspect ratio changed by +50 %); to keep the content's shape give a "
                     "--size of their aspect, or --crop a box of the --size aspect first"]
    assert main(["simulate", str(folder), "--fps", "1000", "--size", "16x16", "--crop",
                 "0,8,32,32", "--readouts", "5", "--out", str(out)]) == 0
    assert not _err_lines(capsys, "warning")
