"""SJDD-Net architecture: parameter counts, shapes, the HQS update, bad input."""

from __future__ import annotations

import pytest
import torch

from spikejdd.models import DEFAULT, LITE, PUBLISHED, PUBLISHED_PARAMETERS, SJDDConfig, SJDDNet
from spikejdd.models.sjdd import _TimeConv, block_starts, count_parameters
from spikesim.errors import SpikeSimTypeError, SpikeSimValueError
from tests.support.sjdd_helpers import TINY, make_inputs

#: Documented in docs/sjdd.md and spikejdd/weights/sjdd-lite.md.
LITE_PARAMETERS = 370_899


def test_default_has_the_published_parameter_count():
    assert count_parameters(SJDDNet()) == PUBLISHED_PARAMETERS == 3_776_101
    assert count_parameters(SJDDNet(PUBLISHED)) == PUBLISHED_PARAMETERS
    assert DEFAULT.hqs_c == 1.0 and PUBLISHED.hqs_c == 3.0


def test_lite_parameter_count_is_the_documented_one():
    assert count_parameters(SJDDNet(LITE)) == LITE_PARAMETERS


def test_published_blocks_are_5_of_15_with_stride_6():
    assert block_starts(39, 15, 5) == [0, 6, 12, 18, 24]


@pytest.mark.parametrize("size", [(13, 17), (1, 1), (8, 8), (21, 10)])
def test_output_shapes_for_any_size(size):
    torch.manual_seed(0)
    model = SJDDNet(TINY).eval()
    x, m = make_inputs(TINY.n_readouts, *size, batch=2)
    with torch.no_grad():
        rgb, nmap = model(x, m)
    assert rgb.shape == (2, 3, *size) and nmap.shape == (2, 1, *size)
    assert torch.isfinite(rgb).all()


def test_default_model_runs_on_an_odd_size():
    torch.manual_seed(0)
    model = SJDDNet().eval()
    x, m = make_inputs(39, 11, 13)
    with torch.no_grad():
        rgb, nmap = model(x, m)
    assert rgb.shape == (1, 3, 11, 13) and nmap.shape == (1, 1, 11, 13)


def test_padding_does_not_leak_into_the_crop_shape_and_is_deterministic():
    torch.manual_seed(1)
    model = SJDDNet(TINY).eval()
    x, m = make_inputs(TINY.n_readouts, 10, 14)
    with torch.no_grad():
        a, _ = model(x, m)
        b, _ = model(x, m)
    torch.testing.assert_close(a, b)


def test_hqs_update_uses_c_and_mu():
    """With the prior replaced by zero every stage gives x_k = y / (c + mu_k)."""
    for c in (1.0, 3.0):
        torch.manual_seed(0)
        model = SJDDNet(TINY.replace(hqs_c=c)).eval()
        with torch.no_grad():
            for k, mu in enumerate(model.mus):
                mu.fill_(0.5 + 0.25 * k)
        model.ccp.forward = lambda x, nm: torch.zeros_like(x)
        x, m = make_inputs(TINY.n_readouts, 8, 8)
        with torch.no_grad():
            out, _ = model(x, m)
            y = model.csr(x, m)
        torch.testing.assert_close(out, y / (c + 0.5 + 0.25 * (TINY.stages - 1)))


def test_mu_parameters_are_learnable_and_initialised():
    model = SJDDNet(TINY)
    assert len(model.mus) == 3
    assert all(float(mu.detach()) == 0.5 and mu.requires_grad for mu in model.mus)


@pytest.mark.parametrize("cin,cout,k,pad", [(1, 3, (7, 3, 3), (3, 1, 1)), (6, 2, 3, 1)])
def test_time_convolution_equals_conv3d(cin, cout, k, pad):
    torch.manual_seed(0)
    conv = _TimeConv(cin, cout, k, padding=pad)
    x = torch.randn(2, 9, cin, 5, 6, dtype=torch.float64, requires_grad=True)
    conv = conv.double()
    ours = conv(x)
    ref = torch.nn.functional.conv3d(x.permute(0, 2, 1, 3, 4), conv.weight, conv.bias,
                                     padding=pad).permute(0, 2, 1, 3, 4)
    torch.testing.assert_close(ours, ref)
    g = torch.randn_like(ref)
    ga = torch.autograd.grad(ours, [x, conv.weight], g)
    gb = torch.autograd.grad(ref, [x, conv.weight], g)
    for a, b in zip(ga, gb, strict=True):
        torch.testing.assert_close(a, b)


def test_one_optimisation_step_reduces_the_loss():
    torch.manual_seed(0)
    model = SJDDNet(TINY)
    x, m = make_inputs(TINY.n_readouts, 16, 16, batch=2)
    gt = torch.rand(2, 3, 16, 16)
    opt = torch.optim.Adam(model.parameters(), lr=1e-4)
    loss0 = torch.nn.functional.mse_loss(model(x, m)[0], gt)
    opt.zero_grad()
    loss0.backward()
    opt.step()
    with torch.no_grad():
        loss1 = torch.nn.functional.mse_loss(model(x, m)[0], gt)
    assert float(loss1) < float(loss0.detach())


def test_wrong_number_of_readouts_is_a_clear_error():
    model = SJDDNet(TINY)
    x, m = make_inputs(TINY.n_readouts + 2, 8, 8)
    with pytest.raises(SpikeSimValueError, match=r"readouts.*n_readouts=9"):
        model(x, m)


def test_mask_stream_mismatch_is_a_clear_error():
    model = SJDDNet(TINY)
    x, m = make_inputs(TINY.n_readouts, 8, 8)
    with pytest.raises(SpikeSimValueError, match="mask.shape"):
        model(x, m[..., :6])
    with pytest.raises(SpikeSimValueError, match="mask.shape"):
        model(x, m[:, :3])
    with pytest.raises(SpikeSimValueError, match="mask.shape"):
        model(torch.cat([x, x]), m)
    with pytest.raises(SpikeSimValueError, match="spikes.shape"):
        model(x[0], m)
    with pytest.raises(SpikeSimTypeError, match="float"):
        model(x.to(torch.uint8), m)


@pytest.mark.parametrize("change", [
    {"n_readouts": 0}, {"block_size": 50}, {"csr_align_feats": (8, 6)}, {"hqs_c": 0.0},
    {"dcn_backend": "magic"}, {"ccp_widths": ()}, {"stages": True},
])
def test_bad_configuration_is_rejected(change):
    with pytest.raises(SpikeSimValueError):
        SJDDConfig(**change)


def test_config_round_trips_through_a_dict():
    assert SJDDConfig.from_dict(LITE.to_dict()) == LITE
    with pytest.raises(SpikeSimValueError, match="config keys"):
        SJDDConfig.from_dict({"widths": 3})
