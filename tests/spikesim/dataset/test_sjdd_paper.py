"""The built-in sjdd-paper manifest on a tiny REDS/DAVIS-shaped tree made here."""

from __future__ import annotations

import json

import pytest

from spikesim.cli import main
from spikesim.dataset import load_manifest, plan_tasks
from spikesim.errors import SpikeSimValueError
from spikesim.io import build_index
from tests.support.dataset_helpers import davis_root, reds_root


@pytest.fixture(scope="module")
def roots(tmp_path_factory):
    base = tmp_path_factory.mktemp("paper")
    reds_root(base / "REDS" / "train_sharp", ("000", "001"), n_frames=3)
    reds_root(base / "REDS" / "val_sharp", ("000",), n_frames=3)
    davis = davis_root(base / "DAVIS", ("bear", "cows"), n_frames=3)
    sets = davis / "ImageSets" / "2017"
    sets.mkdir(parents=True)
    (sets / "train.txt").write_text("bear\n")
    (sets / "val.txt").write_text("cows\n")
    return base / "REDS", base / "DAVIS"


def test_layout_from_set_or_environment(roots, monkeypatch):
    reds, davis = roots
    m = load_manifest("builtin:sjdd-paper", {"REDS": str(reds), "DAVIS": str(davis)})
    tasks = plan_tasks(m)
    by = {}
    for t in tasks:
        by.setdefault(t.split, []).append(t)
    # per video: REDS train 6 clips, DAVIS train 8, DAVIS eval 4, REDS eval 2
    assert {k: len(v) for k, v in by.items()} == {
        "train-gn": 2 * 6 + 8, "train-gpn": 2 * 6 + 8, "eval-davis": 4, "eval-reds": 2}
    assert {t.noise_label for t in by["train-gn"]} == {"GN"}
    assert {t.noise_label for t in by["train-gpn"]} == {"GPN"}
    for t in by["train-gn"]:
        assert t.sensor["noise"]["sigma_g"] <= 15 and t.sensor["noise"]["sigma_p"] == 0
    for t in by["train-gpn"]:
        assert t.sensor["noise"]["sigma_g"] <= 5 and t.sensor["noise"]["sigma_p"] <= 5
    assert all(t.scene["crop"][2:] == [256, 256] for t in tasks)
    assert {t.scene["sequence"] for t in by["eval-davis"]} == {"cows"}
    monkeypatch.setenv("REDS", str(reds))
    monkeypatch.setenv("DAVIS", str(davis))
    assert [t.file for t in plan_tasks(load_manifest("builtin:sjdd-paper"))] == \
        [t.file for t in tasks]
    monkeypatch.delenv("DAVIS")
    with pytest.raises(SpikeSimValueError, match="needs DAVIS: give --set DAVIS="):
        load_manifest("builtin:sjdd-paper")


def test_dry_run_and_a_build(roots, tmp_path, capsys):
    reds, davis = roots
    sets = ["--set", f"REDS={reds}", "--set", f"DAVIS={davis}"]
    assert main(["dataset", "builtin:sjdd-paper", *sets, "--dry-run"]) == 0
    cap = capsys.readouterr()
    est = json.loads(cap.out)  # the JSON alone; the plan line is on stderr
    assert est["sequences"] == 46 and est["estimated_bytes"] > 0
    assert est["estimated_seconds"] > 0 and "MiB" in cap.err
    assert main(["dataset", "builtin:sjdd-paper", *sets, "--out", str(tmp_path),
                 "--limit", "3"]) == 0
    index = build_index(tmp_path / "train-gn")
    assert len(index["sequences"]) == 3
    assert all(e["clip"]["crop"][2:] == [256, 256] for e in index["sequences"])


def test_manifests_command_lists_and_shows(capsys):
    from spikesim.dataset import builtin_manifest_path, builtin_manifests

    assert main(["manifests"]) == 0
    listed = capsys.readouterr().out
    assert all(name in listed for name in builtin_manifests()) and "sjdd-paper" in listed
    assert main(["manifests", "show", "sjdd-paper"]) == 0
    assert capsys.readouterr().out == builtin_manifest_path("sjdd-paper").read_text()
    assert main(["manifests", "show", "builtin:demo"]) == 0
    assert 'name = "demo"' in capsys.readouterr().out
    assert main(["manifests", "show", "nope"]) == 1
    assert "builtin:" in capsys.readouterr().err
    assert main(["manifests", "show"]) == 1


def test_unknown_set_name_is_an_error_listing_the_variables(roots, monkeypatch, capsys):
    reds, davis = roots
    monkeypatch.setenv("DAVIS", str(davis))  # a typo must not pass because DAVIS is set anyway
    with pytest.raises(SpikeSimValueError,
                       match=r"--set DAVS: manifest builtin:sjdd-paper has no variable DAVS "
                             r"\(it uses DAVIS, REDS\)"):
        load_manifest("builtin:sjdd-paper", {"REDS": str(reds), "DAVS": str(davis)})
    with pytest.raises(SpikeSimValueError, match=r"has no variable X \(it uses no \$\{NAME\}"):
        load_manifest("builtin:demo", {"X": "1"})
    rc = main(["dataset", "builtin:sjdd-paper", "--set", f"REDS={reds}", "--set",
               f"DAVS={davis}", "--dry-run"])
    err = capsys.readouterr().err
    assert rc != 0 and "DAVS" in err and "it uses DAVIS, REDS" in err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1
