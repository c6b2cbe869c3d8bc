"""``spikesim analyze ...`` writes Markdown, JSON and PNG reports; bad input gives exit code 1."""

from __future__ import annotations

import json

import pytest

from spikesim.cli import main

SMALL = {
    "transfer": ["--levels", "0,0.5,2", "--readouts", "200", "--size", "4x8", "--window", "50"],
    "isi": ["--levels", "0.2,0.5", "--readouts", "300", "--size", "4x8"],
    "snr": ["--levels", "0,0.1,1", "--windows", "11,41", "--readouts", "400", "--size", "4x8"],
    "quantization": ["--levels", "0.3,2", "--readouts", "200", "--size", "4x8", "--window",
                     "21"],
    "budget": ["flat", "--readouts", "120", "--size", "8x16", "--window", "21",
               "--centers", "2"],
}


@pytest.mark.parametrize("study", sorted(SMALL))
def test_each_study_writes_a_report(study, tmp_path):
    out = tmp_path / study
    assert main(["analyze", study, "--out", str(out), "--no-progress", *SMALL[study]]) == 0
    name = study
    data = json.loads((out / f"{name}.json").read_text())
    assert data["name"] == name
    md = (out / f"{name}.md").read_text()
    assert md.startswith("# ") and f"({name}.png)" in md and "|---|" in md
    assert (out / f"{name}.png").read_bytes()[:4] == b"\x89PNG"


def test_sensor_json_and_overrides(tmp_path):
    import spikesim as ss

    path = tmp_path / "s.json"
    path.write_text(ss.Sensor(cfa=None, full_scale_rate=0.5).to_json())
    out = tmp_path / "t"
    assert main(["analyze", "transfer", "--sensor", str(path), "--set", "reset=zero", "--out",
                 str(out), "--no-progress", *SMALL["transfer"]]) == 0
    data = json.loads((out / "transfer.json").read_text())
    assert data["sensor"]["reset"] == "zero" and data["sensor"]["full_scale_rate"] == 0.5


def test_bad_arguments_exit_with_clear_errors(tmp_path, capsys):
    assert main(["analyze", "transfer", "--out", str(tmp_path), "--size", "big"]) == 1
    assert "--size='big'" in capsys.readouterr().err
    assert main(["analyze", "isi", "--out", str(tmp_path), "--size", "0x8"]) == 1
    assert "--size='0x8' is invalid: expected HxW" in capsys.readouterr().err
    assert main(["analyze", "isi", "--out", str(tmp_path), "--levels", "0.1,x"]) == 1
    assert "--levels" in capsys.readouterr().err
    assert main(["analyze", "calibrate", str(tmp_path / "missing.dat"), "--height", "8",
                 "--width", "8", "--out", str(tmp_path)]) == 1
    assert "missing.dat" in capsys.readouterr().err
    assert main(["analyze", "budget", "flat", "--sensor", "ideal", "--size", "8x8",
                 "--out", str(tmp_path)]) == 1
    assert "sensor.noise" in capsys.readouterr().err
