"""``spikesim info`` shows the noise and motion labels ``spikejdd evaluate`` groups by,
from the one function both use (``spikesim.io.labels.sequence_labels``)."""

from __future__ import annotations

import json

import pytest

from spikesim.cli import main
from spikesim.io import write_h5
from spikesim.io.labels import sequence_labels

GPN = {"type": "paper", "sigma_g": 2.0, "sigma_p": 1.0}


@pytest.mark.parametrize("noise, dataset, label", [
    (GPN, None, "GPN"),
    ({"type": "paper", "sigma_g": 5.0, "sigma_p": 0.0}, None, "GN5"),
    (None, None, "none"),
    (GPN, {"noise_label": "train-mix"}, "train-mix"),  # the dataset builder's label wins
])
def test_info_shows_the_noise_label_evaluate_groups_by(tmp_path, capsys, make_stream, noise,
                                                      dataset, label):
    from spikejdd import evaluate

    assert evaluate.sequence_labels is sequence_labels  # one function, in spikesim
    stream = make_stream(n=50, height=16, width=16, noise=noise)
    stream.meta["scene"] = {"type": "procedural", "motion": "zoom"}
    if dataset:
        stream.meta["dataset"] = dataset
    path = tmp_path / "seq.h5"
    write_h5(path, stream)
    (frame, *_) = evaluate.frames_from_dataset(path)
    assert frame.group == {"noise": label, "motion": "zoom"}

    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert f"  labels     noise {label}, motion zoom (the groups of spikejdd evaluate)" in out
    assert main(["info", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["labels"] == frame.group


def test_a_converted_capture_has_unknown_noise_not_none():
    """A converted .dat records no sensor: its noise is unknown, not the noise-free label."""
    from spikesim.io import sequence_labels

    capture = {"source": "dat", "converted_from": {"path": "cap.dat"}}
    assert sequence_labels(capture) == {"noise": "unknown", "motion": "unknown"}
    assert sequence_labels({"sensor": {"noise": None}})["noise"] == "none"
