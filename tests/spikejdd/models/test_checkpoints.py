"""Checkpoints: our format round-trips, the published layout converts strictly."""

from __future__ import annotations

import pytest
import torch

from spikejdd.models import (
    PUBLISHED,
    CheckpointError,
    SJDDNet,
    convert_published_state_dict,
    load_checkpoint,
    load_model,
    save_checkpoint,
    to_published_state_dict,
)
from tests.support.sjdd_helpers import TINY, make_inputs


def test_save_load_reproduces_outputs_and_provenance(tmp_path):
    torch.manual_seed(3)
    model = SJDDNet(TINY).eval()
    x, m = make_inputs(TINY.n_readouts, 12, 10)
    path = save_checkpoint(tmp_path / "a.pt", model, data={"train": "somewhere"}, seed=7,
                           eval={"psnr_linear": 30.0})
    blob = load_checkpoint(path)
    assert blob["seed"] == 7 and blob["data"]["train"] == "somewhere"
    assert blob["eval"]["psnr_linear"] == 30.0 and blob["config"] == TINY.to_dict()
    again = load_model(path)
    with torch.no_grad():
        torch.testing.assert_close(again(x, m)[0], model(x, m)[0], rtol=0, atol=0)


def test_checkpoint_with_missing_keys_is_a_clear_error(tmp_path):
    model = SJDDNet(TINY)
    path = save_checkpoint(tmp_path / "a.pt", model)
    blob = torch.load(path, weights_only=True)
    del blob["state_dict"]["ccp.tail.weight"]
    blob["state_dict"]["extra.weight"] = torch.zeros(1)
    torch.save(blob, path)
    with pytest.raises(CheckpointError, match=r"missing keys: ccp\.tail\.weight.*unexpected keys: "
                                              r"extra\.weight"):
        load_model(path)


def test_shape_mismatch_is_reported(tmp_path):
    model = SJDDNet(TINY)
    path = save_checkpoint(tmp_path / "a.pt", model)
    blob = torch.load(path, weights_only=True)
    blob["config"]["ccp_widths"] = [4, 16]
    torch.save(blob, path)
    with pytest.raises(CheckpointError, match="shape mismatches"):
        load_model(path)


def test_missing_file_and_garbage(tmp_path):
    with pytest.raises(Exception, match="does not exist"):
        load_checkpoint(tmp_path / "nope.pt")
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"not a checkpoint")
    with pytest.raises(CheckpointError, match="cannot read"):
        load_checkpoint(bad)


# --- the published layout ------------------------------------------------------
#: Key names and shapes of the published model, read from its code (module tree of
#: networks/jdd.py with KAIR's flattening ``sequential``), checked independently here.
PUBLISHED_KEYS = {
    "module.repre.encoder_r.conv_3.weight": (8, 1, 7, 3, 3),
    "module.repre.encoder_g.ca.ca_block.2.weight": (48, 24, 1, 1, 1),
    "module.repre.encoder_b.tail.1.weight": (1, 8, 3, 3, 3),
    "module.repre.aligner.down_g.6.weight": (64, 32, 3, 3),
    "module.repre.aligner.offset_r.weight": (72, 129, 3, 3),
    "module.repre.aligner.dcn_b.weight": (64, 16, 3, 3),
    "module.repre.aligner.offset_fusion.0.weight": (72, 216, 3, 3),
    "module.repre.decoder_g.0.weight": (64, 320, 3, 3),
    "module.repre.decoder_b.6.bias": (1,),
    "module.estimator.encoder_g2.head.0.weight": (64, 39, 3, 3),
    "module.estimator.encoder_b.body.3.body.2.weight": (64, 64, 3, 3),
    "module.estimator.fusion.0.weight": (256, 64, 2, 2),
    "module.estimator.fusion.6.weight": (1, 64, 3, 3),
    "module.prior.head_r.0.weight": (16, 2, 3, 3),
    "module.prior.down_b_3.4.weight": (128, 64, 2, 2),
    "module.prior.body.4.weight": (128, 128, 3, 3),
    "module.prior.up_3.0.weight": (128, 64, 2, 2),
    "module.prior.up_1.4.weight": (16, 16, 3, 3),
    "module.prior.tail.weight": (3, 16, 3, 3),
    "module.mus.2": (1,),
}


def test_published_layout_names_and_shapes():
    published = to_published_state_dict(SJDDNet(PUBLISHED))
    for key, shape in PUBLISHED_KEYS.items():
        assert key in published, key
        assert tuple(published[key].shape) == shape, key
    assert sum(v.numel() for v in published.values()) == 3_776_101


def test_converter_round_trip_runs_the_published_model(tmp_path):
    torch.manual_seed(0)
    model = SJDDNet(PUBLISHED).eval()
    path = tmp_path / "best_model.pth"
    torch.save({"epoch": 5, "best_psnr": 30.0, "model_state": to_published_state_dict(model)},
               path)
    blob = load_checkpoint(path)
    assert blob["config"]["hqs_c"] == 3.0
    loaded = load_model(blob)
    x, m = make_inputs(39, 8, 8)
    with torch.no_grad():
        torch.testing.assert_close(loaded(x, m)[0], model(x, m)[0], rtol=0, atol=0)
    # without the DataParallel prefix too
    bare = to_published_state_dict(model, prefix="")
    assert set(convert_published_state_dict(bare)) == set(model.state_dict())


def test_converter_is_strict():
    state = to_published_state_dict(SJDDNet(PUBLISHED))
    missing = dict(state)
    del missing["module.prior.up_1.4.weight"]
    with pytest.raises(CheckpointError, match=r"missing keys: ccp\.up_1\.4\.weight"):
        convert_published_state_dict(missing)
    extra = dict(state)
    extra["module.repre.encoder_r.conv_4.weight"] = torch.zeros(1)
    with pytest.raises(CheckpointError, match=r"unexpected keys: csr\.encoder_r\.conv_4"):
        convert_published_state_dict(extra)
    foreign = dict(state)
    foreign["module.discriminator.weight"] = torch.zeros(1)
    with pytest.raises(CheckpointError, match="outside repre/estimator/prior/mus"):
        convert_published_state_dict(foreign)
    wrong = dict(state)
    wrong["module.mus.0"] = torch.zeros(2)
    with pytest.raises(CheckpointError, match=r"shape mismatches: mus\.0"):
        convert_published_state_dict(wrong)
