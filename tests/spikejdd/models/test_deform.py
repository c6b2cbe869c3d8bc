"""Deformable convolution: the pure-PyTorch path against an independent slow reference.

The reference samples every tap with an explicit bilinear formula (a loop over
output pixels and kernel taps, float64), following torchvision's documented
semantics: offsets ``(dy, dx)`` per offset group and tap, zero outside the
image corner by corner, optional modulation mask, grouped weights.  Gradients
of the reference come from autograd through that formula, so forward values
and the gradients in the input, offsets, mask, weight and bias are compared
between two independent implementations.  Where torchvision is importable, it
is compared too.
"""

from __future__ import annotations

import math

import pytest
import torch

from spikejdd.models.deform import (
    DeformConv2d,
    deform_conv2d,
    deform_conv2d_torch,
    torchvision_available,
)
from spikesim.errors import SpikeSimValueError


def _bilinear(img, y, x):
    """img (C, H, W); scalar tensors y, x -> (C,), zero outside corner by corner."""
    _, h, w = img.shape
    yv, xv = float(y.detach()), float(x.detach())
    if yv <= -1 or yv >= h or xv <= -1 or xv >= w:
        return img.new_zeros(img.shape[0]) + 0 * (y + x)
    y0, x0 = math.floor(yv), math.floor(xv)
    ly, lx = y - y0, x - x0
    out = img.new_zeros(img.shape[0])
    for dy, wy in ((0, 1 - ly), (1, ly)):
        for dx, wx in ((0, 1 - lx), (1, lx)):
            yy, xx = y0 + dy, x0 + dx
            if 0 <= yy < h and 0 <= xx < w:
                out = out + wy * wx * img[:, yy, xx]
    return out


def reference(inp, offset, weight, bias, stride, padding, dilation, mask=None):
    n, cin, h, w = inp.shape
    cout, cin_g, kh, kw = weight.shape
    groups = cin // cin_g
    taps = kh * kw
    og = offset.shape[1] // (2 * taps)
    ho = (h + 2 * padding - dilation * (kh - 1) - 1) // stride + 1
    wo = (w + 2 * padding - dilation * (kw - 1) - 1) // stride + 1
    cpg = cin // og
    out = []
    for b in range(n):
        plane = []
        for oy in range(ho):
            row = []
            for ox in range(wo):
                cols = []  # (cin, taps)
                for g in range(og):
                    per_tap = []
                    for i in range(kh):
                        for j in range(kw):
                            k = i * kw + j
                            dy = offset[b, g * 2 * taps + 2 * k, oy, ox]
                            dx = offset[b, g * 2 * taps + 2 * k + 1, oy, ox]
                            py = oy * stride - padding + i * dilation + dy
                            px = ox * stride - padding + j * dilation + dx
                            v = _bilinear(inp[b, g * cpg:(g + 1) * cpg], py, px)
                            if mask is not None:
                                v = v * mask[b, g * taps + k, oy, ox]
                            per_tap.append(v)
                    cols.append(torch.stack(per_tap, dim=1))
                cols = torch.cat(cols, dim=0)  # (cin, taps)
                vals = []
                for co in range(cout):
                    gi = co // (cout // groups)
                    c = cols[gi * cin_g:(gi + 1) * cin_g].reshape(-1)
                    vals.append((weight[co].reshape(-1) * c).sum()
                                + (bias[co] if bias is not None else 0))
                row.append(torch.stack(vals))
            plane.append(torch.stack(row, dim=-1))
        out.append(torch.stack(plane, dim=-2))
    return torch.stack(out)


CASES = [  # (n, cin, cout, h, w, k, stride, pad, dil, groups, offset_groups, with_mask)
    (2, 4, 4, 5, 6, 3, 1, 1, 1, 1, 1, False),
    (1, 4, 6, 5, 5, 3, 1, 1, 1, 2, 2, True),
    (1, 4, 4, 6, 7, 3, 2, 1, 1, 4, 4, False),
    (1, 2, 2, 7, 5, 3, 1, 2, 2, 1, 2, True),
    (1, 2, 3, 1, 1, 1, 1, 0, 1, 1, 1, False),
]


def _inputs(case, seed=0):
    n, cin, cout, h, w, k, stride, pad, dil, groups, og, with_mask = case
    g = torch.Generator().manual_seed(seed)
    ho = (h + 2 * pad - dil * (k - 1) - 1) // stride + 1
    wo = (w + 2 * pad - dil * (k - 1) - 1) // stride + 1
    inp = torch.randn(n, cin, h, w, generator=g, dtype=torch.float64)
    # offsets up to ±2.5 px: taps fall inside, across borders and fully outside
    offset = (torch.rand(n, 2 * og * k * k, ho, wo, generator=g, dtype=torch.float64) - 0.5) * 5
    weight = torch.randn(cout, cin // groups, k, k, generator=g, dtype=torch.float64)
    bias = torch.randn(cout, generator=g, dtype=torch.float64)
    mask = (torch.rand(n, og * k * k, ho, wo, generator=g, dtype=torch.float64)
            if with_mask else None)
    return inp, offset, weight, bias, mask, (stride, pad, dil)


@pytest.mark.parametrize("case", CASES)
def test_forward_and_gradients_match_reference(case):
    inp, offset, weight, bias, mask, (s, p, d) = _inputs(case)
    leaves = [t.requires_grad_() for t in (inp, offset, weight, bias)
              ] + ([mask.requires_grad_()] if mask is not None else [])
    ref = reference(inp, offset, weight, bias, s, p, d, mask)
    fast = deform_conv2d_torch(inp, offset, weight, bias, s, p, d, mask)
    assert fast.shape == ref.shape
    torch.testing.assert_close(fast, ref, rtol=1e-10, atol=1e-10)
    gout = torch.randn_like(ref)
    g_ref = torch.autograd.grad(ref, leaves, gout, allow_unused=True)
    g_fast = torch.autograd.grad(fast, leaves, gout, allow_unused=True)
    for a, b, leaf in zip(g_fast, g_ref, leaves, strict=True):
        a = torch.zeros_like(leaf) if a is None else a
        b = torch.zeros_like(leaf) if b is None else b
        torch.testing.assert_close(a, b, rtol=1e-8, atol=1e-8)


def test_gradcheck_fast_path():
    inp, offset, weight, bias, mask, (s, p, d) = _inputs(CASES[1], seed=3)
    args = [t.requires_grad_() for t in (inp, offset, weight, bias, mask)]
    assert torch.autograd.gradcheck(
        lambda a, o, w, b, m: deform_conv2d_torch(a, o, w, b, s, p, d, m), args)


def test_zero_offsets_equal_ordinary_convolution():
    g = torch.Generator().manual_seed(1)
    x = torch.randn(2, 8, 9, 10, generator=g)
    w = torch.randn(8, 2, 3, 3, generator=g)
    off = torch.zeros(2, 2 * 4 * 9, 9, 10)
    out = deform_conv2d_torch(x, off, w, None, 1, 1, 1)
    ref = torch.nn.functional.conv2d(x, w, None, 1, 1, 1, groups=4)
    torch.testing.assert_close(out, ref, rtol=1e-5, atol=1e-5)


def test_integer_offset_shifts_exactly():
    x = torch.arange(30.0).view(1, 1, 5, 6)
    w = torch.ones(1, 1, 1, 1)
    off = torch.zeros(1, 2, 5, 6)
    off[:, 0] = 1.0  # dy = +1: read the row below
    out = deform_conv2d_torch(x, off, w)
    torch.testing.assert_close(out[0, 0, :4], x[0, 0, 1:])
    assert torch.all(out[0, 0, 4] == 0)


@pytest.mark.skipif(not torchvision_available(), reason="torchvision not installed")
@pytest.mark.parametrize("case", CASES)
def test_torchvision_agrees(case):  # pragma: no cover - needs torchvision
    inp, offset, weight, bias, mask, (s, p, d) = _inputs(case)
    leaves = [t.requires_grad_() for t in (inp, offset, weight, bias)]
    a = deform_conv2d(inp, offset, weight, bias, s, p, d, mask, backend="torchvision")
    b = deform_conv2d(inp, offset, weight, bias, s, p, d, mask, backend="torch")
    torch.testing.assert_close(a, b, rtol=1e-8, atol=1e-8)
    gout = torch.randn_like(a)
    for ga, gb in zip(torch.autograd.grad(a, leaves, gout), torch.autograd.grad(b, leaves, gout),
                      strict=True):
        torch.testing.assert_close(ga, gb, rtol=1e-6, atol=1e-6)


def test_backend_and_shape_errors():
    x = torch.randn(1, 4, 5, 5)
    w = torch.randn(4, 4, 3, 3)
    if not torchvision_available():
        with pytest.raises(SpikeSimValueError, match="torchvision is not installed"):
            deform_conv2d(x, torch.zeros(1, 18, 5, 5), w, padding=1, backend="torchvision")
    with pytest.raises(SpikeSimValueError, match="backend"):
        deform_conv2d(x, torch.zeros(1, 18, 5, 5), w, padding=1, backend="cuda-magic")
    with pytest.raises(SpikeSimValueError, match="offset.shape"):
        deform_conv2d_torch(x, torch.zeros(1, 18, 4, 5), w, padding=1)
    with pytest.raises(SpikeSimValueError, match="offset.shape\\[1\\]"):
        deform_conv2d_torch(x, torch.zeros(1, 17, 5, 5), w, padding=1)
    with pytest.raises(SpikeSimValueError, match="mask.shape"):
        deform_conv2d_torch(x, torch.zeros(1, 18, 5, 5), w, padding=1,
                            mask=torch.ones(1, 8, 5, 5))
    with pytest.raises(SpikeSimValueError, match="groups"):
        DeformConv2d(6, 4, 3, groups=4)


def test_module_matches_function():
    torch.manual_seed(0)
    m = DeformConv2d(8, 8, 3, 1, 1, 1, groups=4, backend="torch")
    x = torch.randn(1, 8, 6, 6)
    off = torch.randn(1, 72, 6, 6)
    torch.testing.assert_close(m(x, off), deform_conv2d_torch(x, off, m.weight, m.bias, 1, 1, 1))
    assert set(m.state_dict()) == {"weight", "bias"}
