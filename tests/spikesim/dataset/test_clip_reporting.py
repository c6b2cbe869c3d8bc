"""What a user sees about video clips: ``spikesim info`` prints a clip's record, and a
plan whose clips repeat one another exactly warns once with the count."""

from __future__ import annotations

import json
import warnings

import pytest

from spikesim.cli import main
from spikesim.dataset import build_dataset, parse_manifest, plan_tasks
from spikesim.dataset.plan import DuplicateClipWarning
from spikesim.io import read_header
from tests.support.dataset_helpers import reds_root


def small_manifest(root, **source):
    return {
        "dataset": {"name": "clips", "seed": 5, "size": [32, 32], "window": 5},
        "sensor": {"preset": "ideal"},
        "noise": [{"mode": "paper", "label": "GN", "sigma_g": 5}],
        "sources": [{"kind": "reds", "path": str(root), "split": "train", **source}],
    }


@pytest.fixture(scope="module")
def reds(tmp_path_factory):
    return reds_root(tmp_path_factory.mktemp("reds"), n_frames=6, size=(96, 128))


def test_info_prints_the_clip_record(reds, tmp_path, capsys):
    m = parse_manifest(small_manifest(reds, crop={"size": [32, 32], "position": [8, 16]},
                                      start_s=0.05))
    assert build_dataset(m, tmp_path, progress=False).done == 1
    path = next((tmp_path / "train").glob("*.h5"))
    clip = read_header(path)["meta"]["dataset"]["clip"]
    assert main(["info", str(path)]) == 0
    lines = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("  clip ")]
    assert len(lines) == 1
    motion = clip["motion_px_per_readout"]
    assert lines[0].split(None, 1)[1] == (
        f"video 000 from 0.05 s, crop top 8 left 16, 32x32 px; motion median "
        f"{motion['median']:.3g}, p95 {motion['p95']:.3g} px/readout "
        f"({motion['pairs']} frame pairs)")
    assert motion["pairs"] >= 1 and motion["p95"] > 0  # the texture pans
    assert main(["info", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["clip"] == clip


def test_info_of_a_sequence_without_clip_has_no_clip_line(tmp_path, capsys):
    import spikesim as ss

    path = tmp_path / "bars.h5"
    stream = ss.simulate(ss.scenes.procedural("disk", size=(16, 16)),
                         ss.Sensor.preset("ideal", height=16, width=16), 8, seed=1)
    ss.io.write_h5(path, stream)
    assert main(["info", str(path)]) == 0
    assert "  clip " not in capsys.readouterr().out


def test_identical_clips_warn_once_with_the_count(reds):
    same = {"count": 3, "start_s": 0.05, "crop": {"size": [32, 32], "position": "center"}}
    with pytest.warns(DuplicateClipWarning, match=r"^2 video clip\(s\) repeat") as caught:
        tasks = plan_tasks(parse_manifest(small_manifest(reds, **same)))
    assert len([w for w in caught if w.category is DuplicateClipWarning]) == 1
    assert len(tasks) == 3
    # a second source (another split) on the very same clip repeats it too
    d = small_manifest(reds, start_s=0.05, crop={"size": [32, 32], "position": "center"})
    d["sources"].append({**d["sources"][0], "split": "eval"})
    with pytest.warns(DuplicateClipWarning, match=r"^1 video clip\(s\) repeat"):
        plan_tasks(parse_manifest(d))
    # random start times and crops: no warning
    with warnings.catch_warnings():
        warnings.simplefilter("error", DuplicateClipWarning)
        plan_tasks(parse_manifest(small_manifest(reds, count=3,
                                                 crop={"size": [32, 32]})))
