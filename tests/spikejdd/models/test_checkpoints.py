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
    with pytest.raises(Exception, match="is a folder: name a checkpoint file in it"):
        load_checkpoint(tmp_path)
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


@pytest.mark.parametrize("precision", ["float16", "int8"])
def test_reduced_precision_stores_less_and_reads_back_float32_within_its_step(tmp_path,
                                                                              precision):
    torch.manual_seed(4)
    model = SJDDNet(TINY).eval()
    with torch.no_grad():  # a channel of zeros must stay zero (its scale is clamped, not 0)
        model.ccp.tail.weight[0].zero_()
    full = save_checkpoint(tmp_path / "full.pt", model)
    path = save_checkpoint(tmp_path / "small.pt", model, precision=precision)
    raw = torch.load(path, weights_only=True)
    assert raw["format_version"] == (2 if precision == "int8" else 1)
    stored = {str(v.dtype) for v in raw["state_dict"].values() if v.dtype != torch.int64}
    assert stored == {"torch.float16"}
    if precision == "int8":  # the integers are kept out of state_dict: a plain
        assert {str(v.dtype) for v in raw["int8_state"].values()} == {"torch.int8"}
        with pytest.raises(RuntimeError, match="Missing key"):  # load_state_dict fails loudly
            SJDDNet(TINY).load_state_dict(raw["state_dict"])
    assert path.stat().st_size < full.stat().st_size
    original = model.state_dict()
    back = load_checkpoint(path)["state_dict"]
    assert not {"int8_scales", "int8_state"} & set(load_checkpoint(path))
    loaded = load_model(path).state_dict()
    for k, w in original.items():
        v = back[k]
        assert loaded[k].dtype == w.dtype and v.shape == w.shape, k
        assert torch.equal(loaded[k], v.to(w.dtype)), k
        v = v.to(w.dtype)
        if not w.is_floating_point():
            assert torch.equal(v, w), k
        elif precision == "int8" and w.ndim >= 2:
            peak = w.abs().amax(dim=tuple(range(1, w.ndim)), keepdim=True)
            assert torch.all((v - w).abs() <= peak / 254 * (1 + 1e-6)), k  # half a step
            torch.testing.assert_close(v.abs().amax(dim=tuple(range(1, w.ndim)), keepdim=True),
                                       peak, rtol=1e-6, atol=0)  # each channel's peak is exact
        else:
            assert torch.all((v - w).abs() <= w.abs() * 2.0**-11 + 2.0**-24), k
    assert torch.count_nonzero(back["ccp.tail.weight"][0]) == 0
    x, m = make_inputs(TINY.n_readouts, 12, 10)
    with torch.no_grad():
        torch.testing.assert_close(load_model(path)(x, m)[0], model(x, m)[0], rtol=0, atol=0.05)


def test_bad_precision_and_a_scale_without_its_weight_are_clear_errors(tmp_path):
    from spikesim.errors import SpikeSimValueError

    model = SJDDNet(TINY)
    with pytest.raises(SpikeSimValueError, match=r"precision='int4' is invalid"):
        save_checkpoint(tmp_path / "a.pt", model, precision="int4")
    assert not (tmp_path / "a.pt").exists()
    path = save_checkpoint(tmp_path / "b.pt", model, precision="int8")
    blob = torch.load(path, weights_only=True)
    blob["int8_scales"]["nothing.weight"] = torch.ones(1)
    torch.save(blob, path)
    with pytest.raises(CheckpointError, match=r"do not pair up: \['nothing.weight'\]"):
        load_checkpoint(path)
    del blob["int8_scales"]["nothing.weight"]
    key = next(iter(blob["int8_state"]))
    blob["state_dict"][key] = torch.zeros(1)
    torch.save(blob, path)
    with pytest.raises(CheckpointError, match="is not int8 or is stored twice"):
        load_checkpoint(path)
    blob["format_version"] = 3
    torch.save(blob, path)
    with pytest.raises(CheckpointError, match="upgrade spikejdd"):
        load_checkpoint(path)
