"""Deformable convolution (DCN v1/v2) that runs anywhere.

:func:`deform_conv2d` has the signature and the semantics of
``torchvision.ops.deform_conv2d``:

* ``input`` (N, C_in, H, W); ``weight`` (C_out, C_in / groups, kh, kw);
* ``offset`` (N, 2 · offset_groups · kh · kw, H_out, W_out), laid out per
  offset group, then per kernel tap ``k = i · kw + j`` (row-major), then
  ``(dy, dx)`` — the vertical displacement first;
* ``mask`` (optional, DCN v2) (N, offset_groups · kh · kw, H_out, W_out);
* tap ``(i, j)`` of output pixel ``(y, x)`` samples the input bilinearly at
  ``(y·s_h − p_h + i·d_h + dy, x·s_w − p_w + j·d_w + dx)``; samples outside the
  image read zero (corner by corner, as torchvision).

Backends: torchvision's compiled operator when ``torchvision`` imports
(``backend="auto"``), otherwise :func:`deform_conv2d_torch`, a pure-PyTorch
implementation — one ``grid_sample`` call gathers every tap of every offset
group, a grouped matrix product applies the weights.  It is differentiable in
the input, offsets, mask, weight and bias, works on CPU and CUDA, and is
checked against an independent loop-based reference in ``tests/spikejdd/models``.

:class:`DeformConv2d` is the module (parameter names ``weight``/``bias`` as
torchvision's, so checkpoints interchange).
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn

from spikesim.errors import bad_value

__all__ = ["deform_conv2d", "deform_conv2d_torch", "DeformConv2d", "torchvision_available",
           "BACKENDS"]

try:  # pragma: no cover - depends on the environment
    from torchvision.ops import deform_conv2d as _tv_deform_conv2d
except Exception:  # ImportError, or a torchvision built against another torch
    _tv_deform_conv2d = None

BACKENDS = ("auto", "torch", "torchvision")


def torchvision_available() -> bool:
    """True when torchvision's compiled ``deform_conv2d`` is importable."""
    return _tv_deform_conv2d is not None


def _pair(v, name: str) -> tuple[int, int]:
    if isinstance(v, int) and not isinstance(v, bool):
        return int(v), int(v)
    try:
        a, b = (int(x) for x in v)
    except (TypeError, ValueError):
        raise bad_value(name, v, "an int or a pair of ints") from None
    return a, b


def _check(input, offset, weight, mask, stride, padding, dilation):
    if input.dim() != 4 or weight.dim() != 4 or offset.dim() != 4:
        raise bad_value("input/offset/weight", (tuple(input.shape), tuple(offset.shape),
                        tuple(weight.shape)), "4-D tensors")
    n, cin, h, w = input.shape
    cout, cin_g, kh, kw = weight.shape
    if cin % cin_g:
        raise bad_value("weight.shape[1]", cin_g, f"a divisor of the input channels {cin}")
    groups = cin // cin_g
    if cout % groups:
        raise bad_value("weight.shape[0]", cout, f"a multiple of groups={groups}")
    taps = kh * kw
    if offset.shape[1] % (2 * taps) or offset.shape[1] == 0:
        raise bad_value("offset.shape[1]", offset.shape[1], f"a multiple of 2*kh*kw = {2 * taps}")
    og = offset.shape[1] // (2 * taps)
    if cin % og:
        raise bad_value("offset groups", og, f"a divisor of the input channels {cin}")
    sh, sw = stride
    ph, pw = padding
    dh, dw = dilation
    ho = (h + 2 * ph - dh * (kh - 1) - 1) // sh + 1
    wo = (w + 2 * pw - dw * (kw - 1) - 1) // sw + 1
    if ho < 1 or wo < 1:
        raise bad_value("input.shape", tuple(input.shape), "an input at least one kernel large")
    if offset.shape[0] != n or tuple(offset.shape[2:]) != (ho, wo):
        raise bad_value("offset.shape", tuple(offset.shape),
                        f"({n}, {offset.shape[1]}, {ho}, {wo})")
    if mask is not None and tuple(mask.shape) != (n, og * taps, ho, wo):
        raise bad_value("mask.shape", tuple(mask.shape), f"({n}, {og * taps}, {ho}, {wo})")
    return groups, og, ho, wo


def deform_conv2d_torch(input, offset, weight, bias=None, stride=(1, 1), padding=(0, 0),
                        dilation=(1, 1), mask=None):
    """Pure-PyTorch deformable convolution (see the module doc for the conventions)."""
    stride, padding, dilation = (_pair(stride, "stride"), _pair(padding, "padding"),
                                 _pair(dilation, "dilation"))
    groups, og, ho, wo = _check(input, offset, weight, mask, stride, padding, dilation)
    n, cin, h, w = input.shape
    cout, cin_g, kh, kw = weight.shape
    taps = kh * kw
    dtype = input.dtype
    # base sampling positions of every tap and output pixel, (taps, ho, wo)
    ys = torch.arange(ho, device=input.device, dtype=dtype) * stride[0] - padding[0]
    xs = torch.arange(wo, device=input.device, dtype=dtype) * stride[1] - padding[1]
    ki = torch.arange(kh, device=input.device, dtype=dtype) * dilation[0]
    kj = torch.arange(kw, device=input.device, dtype=dtype) * dilation[1]
    base_y = (ki[:, None, None, None] + ys[None, None, :, None]).expand(kh, kw, ho, wo)
    base_x = (kj[None, :, None, None] + xs[None, None, None, :]).expand(kh, kw, ho, wo)
    off = offset.view(n, og, taps, 2, ho, wo)
    py = base_y.reshape(taps, ho, wo) + off[:, :, :, 0]  # (n, og, taps, ho, wo)
    px = base_x.reshape(taps, ho, wo) + off[:, :, :, 1]
    # grid_sample, align_corners=False: pixel centre x maps to (2x + 1)/W - 1 (valid for W = 1)
    gx = (2 * px + 1) / w - 1
    gy = (2 * py + 1) / h - 1
    grid = torch.stack((gx, gy), dim=-1).view(n * og, taps * ho, wo, 2)
    src = input.reshape(n * og, cin // og, h, w)
    cols = F.grid_sample(src, grid.to(src.dtype), mode="bilinear", padding_mode="zeros",
                         align_corners=False)  # (n*og, cin/og, taps*ho, wo)
    cols = cols.view(n, og, cin // og, taps, ho * wo)
    if mask is not None:
        cols = cols * mask.view(n, og, 1, taps, ho * wo)
    cols = cols.reshape(n, groups, cin_g * taps, ho * wo)
    wmat = weight.reshape(groups, cout // groups, cin_g * taps)
    out = torch.matmul(wmat, cols).reshape(n, cout, ho, wo)
    if bias is not None:
        out = out + bias.view(1, cout, 1, 1)
    return out


def deform_conv2d(input, offset, weight, bias=None, stride=(1, 1), padding=(0, 0),
                  dilation=(1, 1), mask=None, backend: str = "auto"):
    """Deformable convolution; ``backend`` is ``"auto"`` (torchvision if importable),
    ``"torch"`` (always the pure-PyTorch path) or ``"torchvision"`` (raise if absent)."""
    if backend not in BACKENDS:
        raise bad_value("backend", backend, f"one of {BACKENDS}")
    if backend == "torchvision" and _tv_deform_conv2d is None:
        raise bad_value("backend", backend, "'auto' or 'torch' (torchvision is not installed)")
    if backend != "torch" and _tv_deform_conv2d is not None:  # pragma: no cover
        return _tv_deform_conv2d(input, offset, weight, bias, stride=_pair(stride, "stride"),
                                 padding=_pair(padding, "padding"),
                                 dilation=_pair(dilation, "dilation"), mask=mask)
    return deform_conv2d_torch(input, offset, weight, bias, stride, padding, dilation, mask)


class DeformConv2d(nn.Module):
    """Deformable 2-D convolution module (torchvision-compatible parameters).

    ``forward(input, offset, mask=None)``; the number of offset groups is read
    from ``offset``'s channel count, as torchvision does.  Under CUDA autocast
    the operation runs in float32 (sampling positions need the precision).
    """

    def __init__(self, in_channels: int, out_channels: int, kernel_size=3, stride=1, padding=0,
                 dilation=1, groups: int = 1, bias: bool = True, backend: str = "auto"):
        super().__init__()
        if in_channels % groups or out_channels % groups:
            raise bad_value("groups", groups, f"a divisor of {in_channels} and {out_channels}")
        if backend not in BACKENDS:
            raise bad_value("backend", backend, f"one of {BACKENDS}")
        self.in_channels, self.out_channels, self.groups = in_channels, out_channels, groups
        self.kernel_size = _pair(kernel_size, "kernel_size")
        self.stride, self.padding = _pair(stride, "stride"), _pair(padding, "padding")
        self.dilation = _pair(dilation, "dilation")
        self.backend = backend
        self.weight = nn.Parameter(torch.empty(out_channels, in_channels // groups,
                                               *self.kernel_size))
        self.bias = nn.Parameter(torch.empty(out_channels)) if bias else None
        self.reset_parameters()

    def reset_parameters(self) -> None:
        nn.init.kaiming_uniform_(self.weight, a=math.sqrt(5))
        if self.bias is not None:
            fan_in = self.weight.shape[1] * self.weight.shape[2] * self.weight.shape[3]
            bound = 1 / math.sqrt(fan_in)
            nn.init.uniform_(self.bias, -bound, bound)

    def forward(self, input, offset, mask=None):
        if input.is_cuda and torch.is_autocast_enabled():  # pragma: no cover - CUDA only
            with torch.autocast("cuda", enabled=False):
                return self._run(input.float(), offset.float(),
                                 None if mask is None else mask.float())
        return self._run(input, offset, mask)

    def _run(self, input, offset, mask):
        return deform_conv2d(input, offset, self.weight, self.bias, self.stride, self.padding,
                             self.dilation, mask, backend=self.backend)

    def extra_repr(self) -> str:
        return (f"{self.in_channels}, {self.out_channels}, kernel_size={self.kernel_size}, "
                f"stride={self.stride}, padding={self.padding}, dilation={self.dilation}, "
                f"groups={self.groups}, backend={self.backend!r}")
