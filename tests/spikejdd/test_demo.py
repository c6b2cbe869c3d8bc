"""`spikejdd demo` (the README's `make demo`), end to end at reduced size."""

from __future__ import annotations

import json

from spikejdd.cli import main


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
    assert rec and rec["frames"] == 3 and "sjdd" in rec["methods"]
    for m in rec["methods"]:
        assert 15 < rec["summary"][m]["all"]["PSNR[linear]"] < 60
        assert m in report
    assert all((out / p["path"]).exists() for p in rec["panels"])
    assert "sjdd" in capsys.readouterr().out
    # a second run reuses the files
    assert main(["demo", "--out", str(out), "--size", "32", "--limit", "3",
                 "--methods", "tfp39+bilinear"]) == 0
    again = json.loads((out / "summary.json").read_text())
    assert again["reused"] == 3 and again["reconstruction"]["methods"] == ["tfp39+bilinear"]
