"""Every shipped checkpoint loads on CPU and reproduces its stored reference output."""

from __future__ import annotations

import json

import pytest

from spikejdd.models import (
    DEFAULT_WEIGHTS,
    WEIGHTS_DIR,
    count_parameters,
    list_pretrained,
    load_checkpoint,
    load_pretrained,
    pretrained_path,
    reference_check,
)
from spikesim.errors import SpikeSimValueError

NAMES = list_pretrained()


def test_the_default_weights_are_shipped():
    assert DEFAULT_WEIGHTS in NAMES


@pytest.mark.parametrize("name", NAMES)
def test_shipped_checkpoint_reproduces_its_reference(name):
    assert pretrained_path(name).stat().st_size < 5 * 2**20
    assert reference_check(name) <= json.loads(
        (WEIGHTS_DIR / f"{name}.ref.json").read_text())["tolerance"]


@pytest.mark.parametrize("name", NAMES)
def test_shipped_checkpoint_is_documented(name):
    card = (WEIGHTS_DIR / f"{name}.md").read_text()
    blob = load_checkpoint(pretrained_path(name))
    model = load_pretrained(name)
    assert f"{count_parameters(model):,}" in card
    assert blob["seed"] is not None and blob["data"] and blob["eval"]
    for word in ("Data", "Noise", "Steps", "Evaluation"):
        assert word.lower() in card.lower()


def test_unknown_name_lists_the_shipped_ones():
    with pytest.raises(SpikeSimValueError, match="shipped checkpoint"):
        load_pretrained("no-such-model")
