"""``spikejdd reconstruct``'s option errors name the option typed and come before any work."""

from __future__ import annotations

import numpy as np
import pytest

from spikejdd.cli import main
from spikesim.io import write_dat


@pytest.fixture
def dat(tmp_path):
    spikes = (np.random.default_rng(0).random((40, 8, 8)) < 0.3).astype(np.uint8)
    write_dat(tmp_path / "cap.dat", spikes)
    return str(tmp_path / "cap.dat")


@pytest.mark.parametrize("centers, shown", [
    ("-5", "--centers=-5 is invalid: expected readouts in [0, 39] (the stream has 40 readouts)"),
    ("10,45", "--centers='10,45' is invalid: expected readouts in [0, 39] (the stream has 40 "
              "readouts; 45 is outside)"),
    ("30:50:5", "; 40 is outside)"),
])
def test_a_center_outside_the_stream_names_centers_before_any_bar(dat, tmp_path, capsys,
                                                                  centers, shown):
    """User trial: ``--centers -5`` printed ``center=-5 is invalid`` (the library's
    parameter) on the line of a progress bar left over from the work started."""
    out = tmp_path / "out"
    assert main(["reconstruct", dat, "--height", "8", "--width", "8", "--cfa", "RGGB",
                 "--method", "tfp+bilinear", "--centers", centers, "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("spikejdd reconstruct: error: --centers=")
    assert shown in err and "center=" not in err
    assert "reconstruct:" not in err.replace("spikejdd reconstruct:", "")  # no bar drawn
    assert len(err.splitlines()) == 1
    assert not out.exists()


def test_half_a_dat_frame_size_is_named_as_verify_names_it(dat, tmp_path, capsys):
    assert main(["reconstruct", dat, "--height", "8", "--out", str(tmp_path / "o")]) == 1
    assert capsys.readouterr().err == (
        "spikejdd reconstruct: error: give both --height and --width (the .dat frame size), "
        "or neither to have it guessed\n")
    assert main(["reconstruct", dat, "--height", "8", "--width", "8", "--head-columns", "9",
                 "--out", str(tmp_path / "o")]) == 1
    assert "error: --head-columns=9 is invalid" in capsys.readouterr().err


def test_an_unknown_option_is_reported_by_the_subcommand(dat, tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        main(["reconstruct", dat, "--out", str(tmp_path), "--bogus", "1"])
    assert stop.value.code == 2
    assert capsys.readouterr().err == ("spikejdd reconstruct: error: unrecognized arguments: "
                                       "--bogus 1 (see spikejdd reconstruct --help)\n")


def test_a_converters_error_names_its_option_once(capsys):
    with pytest.raises(SystemExit) as stop:
        main(["evaluate", "--sweep", "--size", "-32x48"])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("spikejdd evaluate: error: --size='-32x48' is invalid: expected HxW")
    assert "argument --size" not in err
