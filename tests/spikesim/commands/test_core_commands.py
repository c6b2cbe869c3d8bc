"""The demo, simulate and presets commands, end to end at small size."""

from __future__ import annotations

import json
import re

import pytest

import spikesim as ss
from spikesim.cli import main


def test_presets_command(capsys):
    assert main(["presets"]) == 0
    out = capsys.readouterr().out
    for name in ss.list_presets():
        assert name in out
    assert main(["presets", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert ss.Sensor.from_dict(data["sjdd-gn"]) == ss.Sensor.preset("sjdd-gn")


def test_spikesim_demo_is_the_simulation_half(tmp_path, capsys):
    """`spikesim demo`: dataset, previews and report, no reconstruction (`spikejdd demo`
    adds it; tests/spikejdd/test_demo.py)."""
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--size", "32", "--limit", "2"]) == 0
    report = (out / "report.md").read_text()
    summary = json.loads((out / "summary.json").read_text())
    assert len(summary["sequences"]) == 2 and summary["built"] == 2
    for item in summary["sequences"]:
        assert (out / "demo" / f"{item['name']}.h5").exists()
        assert (out / item["preview"]).exists() and item["name"] in report
        assert 0.0 < item["firing_rate"] < 0.6
    captured = capsys.readouterr()
    assert "reconstruction" not in summary and "spikejdd demo" in captured.out
    # each stage said on stderr as it starts and ends (with its seconds), terminal or not
    stages = [ln for ln in captured.err.splitlines() if ln.startswith("spikesim demo: [")]
    assert [ln.split("] ")[0] for ln in stages] == [f"spikesim demo: [{k}/3" for k in
                                                    (1, 1, 2, 2, 3, 3)], captured.err
    assert stages[0].startswith("spikesim demo: [1/3] simulating the demo data set (32x32, "
                                "the first 2 sequences)") and stages[0].endswith(" ...")
    assert all(re.search(r": done in \d+\.\d s$", ln) for ln in stages[1::2]), stages
    assert stages[5].startswith("spikesim demo: [3/3] writing report.md and summary.json")


def test_stages_say_how_long_a_stage_ran_before_it_failed():
    import io

    from spikesim.demo import Stages

    out = io.StringIO()
    stages = Stages("job", 2, stream=out)
    with pytest.raises(RuntimeError), stages("failing"):
        raise RuntimeError("boom")
    lines = out.getvalue().splitlines()
    assert lines[0] == "job: [1/2] failing ..."
    assert re.fullmatch(r"job: \[1/2\] failing: stopped after \d+\.\d s", lines[1]), lines


@pytest.mark.parametrize("suffix", [".h5", ".dat"])
def test_simulate_command_writes_a_stream(tmp_path, suffix):
    dst = tmp_path / f"s{suffix}"
    args = ["simulate", "flat", "--sensor", "ideal", "--size", "6x20", "--readouts", "50",
            "--set", "cfa=mono", "--set", "full_scale_rate=0.5", "--out", str(dst)]
    assert main(args) == 0
    if suffix == ".h5":
        st = ss.io.read_h5(dst)
        assert st.sensor.full_scale_rate == 0.5 and st.cfa is None
        spikes = st.unpack()
    else:
        spikes = ss.io.read_dat(dst, 6, 20)
    assert spikes.shape == (50, 6, 20)
    assert abs(spikes.mean() - 0.5 * 0.5) < 0.05  # flat scene at level 0.5 by default


def test_command_errors_are_one_line_messages(tmp_path, capsys):
    assert main(["simulate", "flat", "--sensor", "nope", "--readouts", "5",
                 "--out", str(tmp_path / "x.h5")]) == 1
    err = capsys.readouterr().err
    assert "--sensor='nope' is invalid: expected one of" in err and "Traceback" not in err
    assert main(["simulate", "flat", "--readouts", "5", "--out", str(tmp_path / "x.txt")]) == 1
    assert not (tmp_path / "x.txt").exists()


@pytest.mark.parametrize("size", ["0x64", "64x0", "8", "ax8", "70000x8", "4x-2"])
def test_simulate_bad_size_names_the_option(tmp_path, capsys, size):
    assert main(["simulate", "flat", "--size", size, "--readouts", "5",
                 "--out", str(tmp_path / "x.dat")]) == 1
    err = capsys.readouterr().err
    assert f"--size={size!r} is invalid: expected HxW" in err and "height=" not in err
    assert not (tmp_path / "x.dat").exists()


def test_set_with_malformed_json_says_so(tmp_path, capsys):
    out = str(tmp_path / "x.h5")
    assert main(["simulate", "flat", "--set", "noise={bad json", "--readouts", "5",
                 "--out", out]) == 1
    err = capsys.readouterr().err
    assert "--set noise='{bad json' is invalid: expected valid JSON; it is not" in err
    assert "Expecting property name" in err and "PaperNoise" not in err
    # a plain word is still a string, and well-formed JSON still parses
    assert main(["simulate", "flat", "--size", "4x8", "--set", "cfa=RGGB", "--set",
                 'noise={"type":"paper","sigma_g":5}', "--readouts", "5", "--out", out]) == 0
    st = ss.io.read_h5(out)
    assert st.cfa == "RGGB" and st.meta["sensor"]["noise"]["sigma_g"] == 5


def test_cli_warnings_are_one_line_naming_the_command(tmp_path, capsys):
    """A warning raised during a command is printed as ``spikesim CMD: warning:
    MESSAGE``, not with a file name and source line from inside the package."""
    import cv2
    import numpy as np

    folder = tmp_path / "frames"
    folder.mkdir()
    for i in range(3):
        assert cv2.imwrite(str(folder / f"{i:05d}.png"), np.full((24, 32, 3), 60 + 40 * i,
                                                                 np.uint8))
    assert main(["simulate", str(folder), "--sensor", "ideal", "--size", "16x16", "--readouts",
                 "5", "--out", str(tmp_path / "s.h5")]) == 0
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if "warning" in ln]
    assert lines and lines[0].startswith("spikesim simulate: warning: --size 16x16 squashes")
    assert ".py:" not in err


def test_simulate_takes_a_sensor_json_and_says_what_it_simulated(tmp_path, capsys):
    """--sensor takes a sensor .json (what `analyze calibrate` writes), --set still
    overrides it, and the summary line names the reset and noise actually used."""
    sensor = ss.Sensor(height=16, width=24, cfa=None, reset="subtract",
                       noise=ss.noise.PhysicalNoise(charge_noise_electrons=4.0))
    (tmp_path / "chip.json").write_text(sensor.to_json())
    out = tmp_path / "s.h5"
    assert main(["simulate", "astronaut", "--readouts", "30", "--sensor",
                 str(tmp_path / "chip.json"), "--set", "clock_hz=40000", "--out", str(out)]) == 0
    line = capsys.readouterr().out
    assert "cfa=mono, reset=subtract, noise=physical" in line and "with --set" in line
    got = ss.io.open_h5(out).meta["sensor"]
    assert got["noise"]["charge_noise_electrons"] == 4.0 and got["clock_hz"] == 40000.0
    assert main(["simulate", "astronaut", "--readouts", "30", "--sensor", "nope.json",
                 "--out", str(tmp_path / "t.h5")]) == 1
    assert "no such sensor JSON file: 'nope.json'" in capsys.readouterr().err
    bad = tmp_path / "bad.json"
    bad.write_text('{"height": 8, "width": 8, "noise": {"type": "physical", "prnu": -1}}')
    assert main(["simulate", "astronaut", "--readouts", "5", "--sensor", str(bad),
                 "--out", str(tmp_path / "t.h5")]) == 1
    assert f"sensor file '{bad}': prnu=-1 is invalid" in capsys.readouterr().err


def test_set_reaches_the_fields_of_the_noise_model(tmp_path, capsys):
    """--set noise.FIELD=VALUE changes one field of the sensor's noise model (the
    others are kept); an unknown field, a bad value or a sensor without noise is one
    error naming the flag."""
    out = tmp_path / "n.h5"
    assert main(["simulate", "astronaut", "--readouts", "5", "--size", "8x8", "--sensor",
                 "physical", "--set", "noise.electrons_per_threshold=300", "--set",
                 "noise.charge_noise_electrons=2", "--out", str(out)]) == 0
    capsys.readouterr()
    got = ss.io.open_h5(out).meta["sensor"]["noise"]
    default = ss.Sensor.preset("physical").noise
    assert got["electrons_per_threshold"] == 300 and got["charge_noise_electrons"] == 2
    assert got["prnu"] == default.prnu
    for sensor, item, message in (
            ("physical", "noise.electrons=3", "--set noise.FIELD: PhysicalNoise field=['electrons']"
             " is invalid: expected fields among"),
            ("physical", "noise.prnu=-1", "--set noise.prnu=-1 is invalid"),
            ("ideal", "noise.prnu=0.1", "expected a sensor with a noise model (this one has "
             "none)")):
        assert main(["simulate", "astronaut", "--readouts", "5", "--sensor", sensor, "--set",
                     item, "--out", str(tmp_path / "m.h5")]) == 1
        err = capsys.readouterr().err
        assert message in err and len(err.strip().splitlines()) == 1, err
    with pytest.raises(ss.errors.SpikeSimValueError, match="PaperNoise field"):
        ss.noise.PaperNoise().replace(sigma=3)


def test_simulate_passes_scene_options_and_names_the_flags(tmp_path, capsys):
    """--speed and --scene-set KEY=VALUE reach the built-in scene; a key or value the
    scene refuses is named by its flag."""
    out = tmp_path / "f.h5"
    assert main(["simulate", "flat", "--scene-set", "level=0.5", "--size", "8x8", "--set",
                 "cfa=mono", "--readouts", "100", "--out", str(out)]) == 0
    rate = ss.io.open_h5(out).read_window(0, 100).mean()
    assert rate == pytest.approx(0.5 * 0.6, abs=0.011)  # full_scale_rate 0.6
    capsys.readouterr()
    for argv, needle in ((["flat", "--scene-set", "levle=1"], "--scene-set=['levle']"),
                         (["flat", "--speed", "50"], "--speed=50.0"),
                         (["astronaut", "--motion", "wobble"], "--motion='wobble'")):
        assert main(["simulate", *argv, "--size", "8x8", "--readouts", "10", "--out",
                     str(tmp_path / "g.h5")]) == 1
        assert needle in capsys.readouterr().err
    assert not (tmp_path / "g.h5").exists()


def test_simulate_names_a_missing_video_and_an_output_folder_that_is_a_file(tmp_path, capsys):
    """A SCENE that is a path to nothing is a missing file, not an unknown scene name; an
    --out whose folder is a file says so."""
    (tmp_path / "afile").write_text("x")
    for scene, out, message in (
            ("videos/nothere.mp4", "x.h5", "SCENE 'videos/nothere.mp4': no such video file or "
             "frame folder"),
            ("astronaut", "afile/a.h5", "is a file, not a folder")):
        assert main(["simulate", scene, "--readouts", "5", "--size", "8x8",
                     "--out", str(tmp_path / out)]) == 1
        err = capsys.readouterr().err
        assert message in err and len(err.strip().splitlines()) == 1, err


def test_the_first_run_of_a_kernel_family_says_it_compiles(tmp_path, capsys, monkeypatch):
    """The first run of a kernel family after an install compiles it: the run says so
    once per process, on stderr whether or not it is a terminal, with how long it
    takes and where the cache lives (``spikesim.families``)."""
    from spikesim import families

    monkeypatch.delenv("SPIKESIM_QUIET_COMPILE", raising=False)
    monkeypatch.setattr(families, "_announced", set())
    monkeypatch.setattr(families, "is_compiled", lambda name: False)
    monkeypatch.setattr(families, "mark_compiled", lambda name: None)
    args = ["simulate", "astronaut", "--readouts", "5", "--size", "8x8"]
    assert main([*args, "--out", str(tmp_path / "s.h5")]) == 0
    err = capsys.readouterr().err
    assert "compiling the noise-free simulation kernels for this machine" in err
    assert "cached in" in err
    assert main([*args, "--out", str(tmp_path / "t.h5")]) == 0
    assert "compiling" not in capsys.readouterr().err  # once per process
    assert main([*args, "--sensor", "sjdd-gn", "--out", str(tmp_path / "u.h5")]) == 0
    assert "compiling the paper simulation kernels" in capsys.readouterr().err


def test_dataset_quiet_draws_no_bar(tmp_path, capsys):
    from tests.support.fault_helpers import write_manifest

    manifest = write_manifest(tmp_path / "m.toml", count=1, size=(16, 16), window=20, samples=1)
    assert main(["dataset", str(manifest), "--out", str(tmp_path / "ds"), "--quiet"]) == 0
    cap = capsys.readouterr()
    assert "%|" not in cap.err and "done 1" in cap.out
