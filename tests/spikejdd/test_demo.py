"""`spikejdd demo` (the README's `make demo`), end to end at reduced size."""

from __future__ import annotations

import json
import re

from spikejdd.cli import main


def test_demo_runs_end_to_end_small(tmp_path, capsys):
    """The README's main job, at reduced size: dataset, previews, reconstruction, report."""
    out = tmp_path / "demo"
    import torch

    assert main(["demo", "--out", str(out), "--size", "32", "--limit", "3"]) == 0
    # SJDD-Net ran on the demo's one torch thread, although building the data set
    # started numba's threads (which can set torch's through the shared OpenMP runtime)
    assert torch.get_num_threads() == 1
    report = (out / "report.md").read_text()
    summary = json.loads((out / "summary.json").read_text())
    assert len(summary["sequences"]) == 3 and summary["built"] == 3
    for item in summary["sequences"]:
        assert (out / "demo" / f"{item['name']}.h5").exists()
        assert (out / item["preview"]).exists() and item["name"] in report
        assert 0.0 < item["firing_rate"] < 0.6
        assert item["noise"] in ("GN", "GPN")
    rec = summary["reconstruction"]
    # on a CPU SJDD-Net runs with the lite weights (the full model takes 4 times as long)
    assert rec and rec["frames"] == 3 and rec["methods"][-1] == "sjdd@sjdd-lite"
    assert "`--methods sjdd` (or `--device cuda`) runs the default" in report
    for m in rec["methods"]:
        assert 15 < rec["summary"][m]["all"]["PSNR[linear]"] < 60
        assert m in report
    assert all((out / p["path"]).exists() for p in rec["panels"])
    captured = capsys.readouterr()
    assert "sjdd" in captured.out
    # each stage is said on stderr as it starts and as it ends, with its seconds
    stages = [ln for ln in captured.err.splitlines() if ln.startswith("spikejdd demo: [")]
    names = ["simulating the demo data set (32x32, the first 3 sequences)",
             "previewing each sequence", "reconstructing with 5 methods",
             "writing report.md and summary.json"]
    assert len(stages) == 2 * len(names), captured.err
    for k, name in enumerate(names):
        start, end = stages[2 * k], stages[2 * k + 1]
        assert start.startswith(f"spikejdd demo: [{k + 1}/4] {name}") and start.endswith(" ...")
        assert re.fullmatch(rf"spikejdd demo: \[{k + 1}/4\] {re.escape(name)}.*: done in "
                            r"\d+\.\d s", end), end
    # a second run reuses the files
    assert main(["demo", "--out", str(out), "--size", "32", "--limit", "3",
                 "--methods", "tfp39+bilinear"]) == 0
    again = json.loads((out / "summary.json").read_text())
    assert again["reused"] == 3 and again["reconstruction"]["methods"] == ["tfp39+bilinear"]


def test_demo_runs_the_default_sjdd_weights_on_cuda_and_the_lite_ones_on_a_cpu():
    from spikejdd.demo import DEMO_METHODS, _default_methods

    assert _default_methods("cuda") == [*DEMO_METHODS, "sjdd"]
    assert _default_methods("cuda:0")[-1] == "sjdd"
    assert _default_methods("cpu") == [*DEMO_METHODS, "sjdd@sjdd-lite"]
