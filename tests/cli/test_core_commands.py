"""The demo, simulate and presets commands, end to end at small size."""

from __future__ import annotations

import json

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


def test_demo_runs_end_to_end_small(tmp_path, capsys):
    """The README's main job, at reduced size: dataset, previews, reconstruction, report."""
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--size", "32", "--limit", "3"]) == 0
    report = (out / "report.md").read_text()
    summary = json.loads((out / "summary.json").read_text())
    assert len(summary["sequences"]) == 3 and summary["built"] == 3
    for item in summary["sequences"]:
        assert (out / "demo" / f"{item['name']}.h5").exists()
        assert (out / item["preview"]).exists() and item["name"] in report
        assert 0.0 < item["firing_rate"] < 0.6
        assert item["noise"] in ("GN", "GPN")
    rec = summary["reconstruction"]
    assert rec and rec["frames"] == 3
    for m in rec["methods"]:
        assert 15 < rec["summary"][m]["all"]["PSNR[linear]"] < 60
        assert m in report
    assert all((out / p["path"]).exists() for p in rec["panels"])
    # a second run reuses the files
    assert main(["demo", "--out", str(out), "--size", "32", "--limit", "3"]) == 0
    assert json.loads((out / "summary.json").read_text())["reused"] == 3


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
    assert "preset" in err and "Traceback" not in err
    assert main(["simulate", "flat", "--readouts", "5", "--out", str(tmp_path / "x.txt")]) == 1
    assert not (tmp_path / "x.txt").exists()
