"""SJDD-Net: joint demosaicing and denoising of Bayer spike streams.

Dong et al., "Joint Demosaicing and Denoising for Spike Camera", AAAI 2024.
An unrolled half-quadratic-splitting (HQS) network of three parts:

* **CSR** (colour spike representation, :class:`CSR`): per colour — the
  stream times that colour's mask, green from both green sites — a
  multi-scale 3-D encoder (temporal kernels 3, 5, 7; channel attention over
  the three paths; a temporal fusion); then offset-sharing deformable
  alignment of ``n_blocks`` overlapping blocks of ``block_size`` readouts
  (39 readouts → 5 blocks of 15, stride 6): offsets are learned per colour
  from [that colour's mask, block features, reference-block features], fused
  into one offset per block and applied by a deformable convolution per
  colour; per-colour decoders give three full-resolution planes ``y``.
* **SNE** (spike noise estimator, :class:`SNE`): the stream split into four
  half-resolution Bayer planes, one residual encoder each, fused and
  upsampled into a full-resolution noise map.
* **CCP** (colour correlation prior, :class:`CCP`): three colour encoders
  (each plane with the noise map) whose skip features are summed at every
  scale into one decoder, plus a global residual.

``K = stages`` HQS steps share the CCP weights::

    z_k = CCP(x_{k-1}, noise_map);   x_k = (y + μ_k z_k) / (c + μ_k),   x_0 = y

with learnable ``μ_k`` (initialised to ``mu_init`` = 0.5).  **Which c.**  Our
default is ``c = 1``: the exact minimiser of ``‖x − y‖² + μ‖x − z‖²``, a convex
combination of the CSR estimate and the prior's output that keeps the image's
scale, so a freshly initialised or small model starts from the CSR estimate
instead of a third of it.  The published code divides by the channel count
(``c = 3``, ``y.shape[1]``) and the paper's equation 11 by ``n + μ``; use
:meth:`SJDDConfig.published` (``hqs_c=3``) to run published weights.

Internal module names follow the published layout (``csr`` ↔ ``repre``,
``sne`` ↔ ``estimator``, ``ccp`` ↔ ``prior``), so the checkpoint converter in
:mod:`spikejdd.models.checkpoints` is a strict renaming.  The default
configuration has 3,776,101 parameters, the published count; every width,
depth and the stage count are configuration (:data:`LITE` is the CPU model).

Inputs of any size are padded inside (spikes by edge replication, the mask by
zeros, as the published evaluation does) to a multiple of ``2**levels`` of the
CCP (8 by default) and the outputs cropped back.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace

import torch
import torch.nn.functional as F
from torch import nn

from spikejdd.models.deform import BACKENDS, DeformConv2d
from spikesim.errors import SpikeSimTypeError, bad_value

__all__ = ["SJDDConfig", "SJDDNet", "CSR", "SNE", "CCP", "DEFAULT", "LITE", "PUBLISHED",
           "PUBLISHED_PARAMETERS", "count_parameters", "block_starts"]

#: Parameter count of the published default model (AAAI 2024 code).
PUBLISHED_PARAMETERS = 3_776_101

_SLOPE = 0.2  # LeakyReLU of the conv blocks (KAIR convention used by the published code)
_SLOPE_3D = 0.1  # LeakyReLU inside the 3-D encoder and on the per-colour offsets


@dataclass(frozen=True)
class SJDDConfig:
    """Architecture of :class:`SJDDNet` (defaults = the published model).

    Attributes
    ----------
    n_readouts : readouts per input window (39).
    block_size, n_blocks : CSR alignment blocks (15 readouts, 5 blocks; stride
        ``(n_readouts - block_size) // (n_blocks - 1)``).
    csr_encoder_feats : width of the red/blue 3-D encoder paths (green: twice).
    csr_align_feats : (hidden, output) widths of the per-block feature extractor.
    csr_align_depth : hidden 3×3 convolutions in that extractor.
    csr_decoder_feats, csr_decoder_depth : per-colour decoders.
    offset_groups : deformable offset groups (= grouped weights of the DCN, as published).
    ca_reduction : channel-attention reduction of the 3-D encoder.
    sne_feats, sne_res_blocks, sne_fusion_depth : noise estimator.
    ccp_widths : CCP widths per scale (len - 1 downsamplings, padding multiple 2**that).
    ccp_depth : 3×3 convolutions per CCP scale.
    stages : HQS iterations K (CCP weights shared).
    mu_init : initial μ_k.
    hqs_c : denominator constant c of the HQS update (1 ours, 3 published).
    dcn_backend : "auto" | "torch" | "torchvision" (not architectural).
    """

    n_readouts: int = 39
    block_size: int = 15
    n_blocks: int = 5
    csr_encoder_feats: int = 8
    csr_align_feats: tuple[int, int] = (32, 64)
    csr_align_depth: int = 2
    csr_decoder_feats: int = 64
    csr_decoder_depth: int = 2
    offset_groups: int = 4
    ca_reduction: int = 2
    sne_feats: int = 64
    sne_res_blocks: int = 4
    sne_fusion_depth: int = 2
    ccp_widths: tuple[int, ...] = (16, 32, 64, 128)
    ccp_depth: int = 2
    stages: int = 3
    mu_init: float = 0.5
    hqs_c: float = 1.0
    dcn_backend: str = "auto"

    def __post_init__(self):
        ints = ["n_readouts", "block_size", "n_blocks", "csr_encoder_feats", "csr_decoder_feats",
                "offset_groups", "ca_reduction", "sne_feats", "stages"]
        for name in ints:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise bad_value(f"config.{name}", v, "an integer >= 1")
        for name in ("csr_align_depth", "csr_decoder_depth", "sne_res_blocks",
                     "sne_fusion_depth", "ccp_depth"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                raise bad_value(f"config.{name}", v, "an integer >= 0")
        object.__setattr__(self, "csr_align_feats", tuple(int(v) for v in self.csr_align_feats))
        object.__setattr__(self, "ccp_widths", tuple(int(v) for v in self.ccp_widths))
        if len(self.csr_align_feats) != 2 or min(self.csr_align_feats) < 1:
            raise bad_value("config.csr_align_feats", self.csr_align_feats, "two widths >= 1")
        if self.csr_align_feats[1] % self.offset_groups:
            raise bad_value("config.offset_groups", self.offset_groups,
                            f"a divisor of csr_align_feats[1] = {self.csr_align_feats[1]}")
        if len(self.ccp_widths) < 1 or min(self.ccp_widths) < 1:
            raise bad_value("config.ccp_widths", self.ccp_widths, "one or more widths >= 1")
        if self.block_size > self.n_readouts:
            raise bad_value("config.block_size", self.block_size,
                            f"at most n_readouts = {self.n_readouts}")
        if (3 * self.csr_encoder_feats) % self.ca_reduction or \
                3 * self.csr_encoder_feats < self.ca_reduction:
            raise bad_value("config.ca_reduction", self.ca_reduction,
                            f"a divisor of 3 * csr_encoder_feats = {3 * self.csr_encoder_feats}")
        if not (math.isfinite(self.hqs_c) and self.hqs_c > 0):
            raise bad_value("config.hqs_c", self.hqs_c, "a finite number > 0")
        if not (math.isfinite(self.mu_init) and self.mu_init > 0):
            raise bad_value("config.mu_init", self.mu_init, "a finite number > 0")
        if self.dcn_backend not in BACKENDS:
            raise bad_value("config.dcn_backend", self.dcn_backend, f"one of {BACKENDS}")

    # --- helpers ----------------------------------------------------------
    @property
    def pad_multiple(self) -> int:
        """Input sizes are padded to a multiple of this (SNE halves, CCP downsamples)."""
        return max(2, 2 ** (len(self.ccp_widths) - 1))

    def to_dict(self) -> dict:
        d = asdict(self)
        d["csr_align_feats"] = list(self.csr_align_feats)
        d["ccp_widths"] = list(self.ccp_widths)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> SJDDConfig:
        if not isinstance(d, dict):
            raise SpikeSimTypeError(f"config must be a dict, got {type(d).__name__}")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise bad_value("config keys", unknown, f"names among {sorted(known)}")
        return cls(**d)

    def replace(self, **changes) -> SJDDConfig:
        known = {f.name for f in fields(self)}
        unknown = sorted(set(changes) - known)
        if unknown:
            raise bad_value("model field", unknown[0], f"a name among {sorted(known)}")
        return replace(self, **changes)

    @classmethod
    def published(cls, **changes) -> SJDDConfig:
        """The published model exactly, HQS denominator c = 3 included."""
        return cls(hqs_c=3.0, **changes)


#: The published architecture with our HQS constant (c = 1); 3,776,101 parameters.
DEFAULT = SJDDConfig()
#: The published architecture and update rule (c = 3), for published weights.
PUBLISHED = SJDDConfig.published()
#: A small model that trains on a 2-core CPU in tens of minutes (see docs/sjdd.md).
LITE = SJDDConfig(csr_encoder_feats=2, csr_align_feats=(16, 24), csr_align_depth=1,
                  csr_decoder_feats=24, csr_decoder_depth=1, offset_groups=1,
                  sne_feats=16, sne_res_blocks=1, sne_fusion_depth=1,
                  ccp_widths=(16, 24, 32, 48), ccp_depth=1, stages=3)


def count_parameters(module: nn.Module) -> int:
    return sum(p.numel() for p in module.parameters())


def block_starts(n_readouts: int, block_size: int, n_blocks: int) -> list[int]:
    """First readout of each alignment block (stride ``(n - size) // (blocks - 1)``)."""
    stride = (n_readouts - block_size) // (n_blocks - 1) if n_blocks > 1 else 0
    return [i * stride for i in range(n_blocks)]


# --- building blocks -------------------------------------------------------
def _conv(cin: int, cout: int, act: str | None = "L", k: int = 3, stride: int = 1,
          pad: int = 1, transpose: bool = False) -> list[nn.Module]:
    conv = (nn.ConvTranspose2d(cin, cout, k, stride, pad) if transpose
            else nn.Conv2d(cin, cout, k, stride, pad))
    if act is None:
        return [conv]
    return [conv, nn.LeakyReLU(_SLOPE, inplace=True) if act == "L" else nn.ReLU(inplace=True)]


def _seq(*layers: list[nn.Module]) -> nn.Sequential:
    return nn.Sequential(*[m for group in layers for m in group])


class _TimeConv(nn.Conv3d):
    """A ``Conv3d`` (same parameters and state-dict keys) evaluated as one ``Conv2d``.

    Works on the time-major layout (N, T, C, H, W): the ``kt`` temporally
    shifted copies are stacked along channels and convolved in 2-D, which is
    exactly the 3-D convolution with zero temporal padding ``kt // 2`` but runs
    on the fast 2-D kernels (PyTorch's CPU ``conv3d`` backward is very slow for
    few channels).  Checked against ``F.conv3d`` in the tests.
    """

    def forward(self, x):  # (N, T, C, H, W) -> (N, T, C_out, H, W)
        n, t, c, h, w = x.shape
        kt, kh, kw = self.kernel_size
        pt = kt // 2
        if kt > 1:  # (N, T, C, kt, H, W): channel-major like the weight, so no transpose
            xp = F.pad(x, (0, 0, 0, 0, 0, 0, pt, pt))
            x = torch.stack([xp[:, d:d + t] for d in range(kt)], dim=3)
        weight = self.weight.reshape(self.out_channels, c * kt, kh, kw)
        out = F.conv2d(x.reshape(n * t, kt * c, h, w), weight, self.bias,
                       padding=(self.padding[1], self.padding[2]))
        return out.view(n, t, self.out_channels, h, w)


class _ChannelAttention3d(nn.Module):
    """Softmax channel weights per readout (spatial mean → 1×1×1 convs)."""

    def __init__(self, channels: int, reduction: int):
        super().__init__()
        mid = channels // reduction
        self.ca_block = nn.Sequential(
            nn.Conv3d(channels, mid, 1), nn.LeakyReLU(_SLOPE_3D, inplace=True),
            nn.Conv3d(mid, channels, 1), nn.Softmax(dim=1))

    def forward(self, x):  # (N, T, C, H, W) -> (N, T, C, 1, 1)
        v = x.mean(dim=(3, 4))
        c1, act, c2 = self.ca_block[0], self.ca_block[1], self.ca_block[2]
        v = act(F.linear(v, c1.weight.flatten(1), c1.bias))
        v = F.linear(v, c2.weight.flatten(1), c2.bias)
        return torch.softmax(v, dim=-1)[..., None, None]


class _MultiScale3DEncoder(nn.Module):
    """Temporal kernels 3, 5, 7 in parallel, channel attention, temporal fusion to one map."""

    def __init__(self, feats: int, reduction: int):
        super().__init__()
        self.conv_1 = _TimeConv(1, feats, (3, 3, 3), padding=(1, 1, 1))
        self.conv_2 = _TimeConv(1, feats, (5, 3, 3), padding=(2, 1, 1))
        self.conv_3 = _TimeConv(1, feats, (7, 3, 3), padding=(3, 1, 1))
        self.ca = _ChannelAttention3d(3 * feats, reduction)
        self.tail = nn.Sequential(_TimeConv(3 * feats, feats, 3, padding=1),
                                  _TimeConv(feats, 1, 3, padding=1))

    def forward(self, x):  # (N, T, H, W) -> (N, T, H, W)
        x = x.unsqueeze(2)
        paths = [F.leaky_relu(c(x), _SLOPE_3D) for c in (self.conv_1, self.conv_2, self.conv_3)]
        feats = torch.cat(paths, dim=2)
        return self.tail(feats * self.ca(feats)).squeeze(2)


class _Aligner(nn.Module):
    """Offset-sharing deformable alignment of the blocks onto the middle block."""

    def __init__(self, cfg: SJDDConfig):
        super().__init__()
        a0, a1 = cfg.csr_align_feats
        og = cfg.offset_groups
        self.starts = block_starts(cfg.n_readouts, cfg.block_size, cfg.n_blocks)
        self.block_size = cfg.block_size
        off = 2 * 9 * og
        for c in "rgb":
            self.add_module(f"down_{c}", _seq(_conv(cfg.block_size, a0),
                                              *[_conv(a0, a0) for _ in range(cfg.csr_align_depth)],
                                              _conv(a0, a1)))
            self.add_module(f"offset_{c}", nn.Conv2d(2 * a1 + 1, off, 3, 1, 1))
            self.add_module(f"dcn_{c}", DeformConv2d(a1, a1, 3, 1, 1, 1, og,
                                                     backend=cfg.dcn_backend))
        self.offset_fusion = _seq(_conv(3 * off, off))

    def forward(self, feats: dict, masks: dict) -> dict:
        mid = len(self.starts) // 2
        blocks = {c: [f[:, s:s + self.block_size] for s in self.starts]
                  for c, f in feats.items()}
        ref = {c: getattr(self, f"down_{c}")(blocks[c][mid]) for c in "rgb"}
        out = {c: [] for c in "rgb"}
        for i in range(len(self.starts)):
            if i == mid:
                for c in "rgb":
                    out[c].append(ref[c])
                continue
            cur = {c: getattr(self, f"down_{c}")(blocks[c][i]) for c in "rgb"}
            offs = [F.leaky_relu(getattr(self, f"offset_{c}")(
                torch.cat([masks[c], cur[c], ref[c]], dim=1)), _SLOPE_3D) for c in "rgb"]
            shared = self.offset_fusion(torch.cat(offs, dim=1))
            for c in "rgb":
                out[c].append(getattr(self, f"dcn_{c}")(cur[c], shared))
        return {c: torch.cat(v, dim=1) for c, v in out.items()}


class CSR(nn.Module):
    """Colour spike representation: (N, T, H, W) stream + (N, 4, H, W) mask → (N, 3, H, W)."""

    def __init__(self, cfg: SJDDConfig):
        super().__init__()
        f = cfg.csr_encoder_feats
        self.encoder_r = _MultiScale3DEncoder(f, cfg.ca_reduction)
        self.encoder_g = _MultiScale3DEncoder(2 * f, cfg.ca_reduction)
        self.encoder_b = _MultiScale3DEncoder(f, cfg.ca_reduction)
        self.aligner = _Aligner(cfg)
        a1, d = cfg.csr_align_feats[1], cfg.csr_decoder_feats
        for c in "rgb":
            self.add_module(f"decoder_{c}", _seq(
                _conv(a1 * cfg.n_blocks, d), *[_conv(d, d) for _ in range(cfg.csr_decoder_depth)],
                _conv(d, 1)))

    def forward(self, spikes, mask):
        masks = {"r": mask[:, 0:1], "g": mask[:, 1:2] + mask[:, 2:3], "b": mask[:, 3:4]}
        feats = {c: getattr(self, f"encoder_{c}")(spikes * masks[c]) for c in "rgb"}
        aligned = self.aligner(feats, masks)
        return torch.cat([getattr(self, f"decoder_{c}")(aligned[c]) for c in "rgb"], dim=1)


class _ResBlock(nn.Module):
    def __init__(self, feats: int):
        super().__init__()
        self.body = _seq(_conv(feats, feats), _conv(feats, feats, act=None))

    def forward(self, x):
        return x + self.body(x)


class _SpikeEncoder(nn.Module):
    def __init__(self, cin: int, feats: int, n_res: int):
        super().__init__()
        self.head = _seq(_conv(cin, feats))
        self.body = nn.Sequential(*[_ResBlock(feats) for _ in range(n_res)])

    def forward(self, x):
        return self.body(self.head(x))


class SNE(nn.Module):
    """Spike noise estimator: four half-resolution Bayer planes → (N, 1, H, W) noise map."""

    PLANES = ("r", "g1", "g2", "b")

    def __init__(self, cfg: SJDDConfig):
        super().__init__()
        f = cfg.sne_feats
        for p in self.PLANES:
            self.add_module(f"encoder_{p}", _SpikeEncoder(cfg.n_readouts, f, cfg.sne_res_blocks))
        self.fusion = _seq(_conv(4 * f, f, k=2, stride=2, pad=0, transpose=True),
                           *[_conv(f, f) for _ in range(cfg.sne_fusion_depth)], _conv(f, 1))

    def forward(self, spikes, mask):
        planes = [getattr(self, f"encoder_{p}")(F.avg_pool2d(spikes * mask[:, i:i + 1], 2) * 4)
                  for i, p in enumerate(self.PLANES)]
        return self.fusion(torch.cat(planes, dim=1))


class CCP(nn.Module):
    """Colour correlation prior: (N, 3, H, W) image + (N, 1, H, W) noise map → (N, 3, H, W)."""

    def __init__(self, cfg: SJDDConfig):
        super().__init__()
        w, depth = cfg.ccp_widths, cfg.ccp_depth
        self.levels = len(w) - 1
        for c in "rgb":
            self.add_module(f"head_{c}", _seq(_conv(2, w[0], act="R")))
            for k in range(1, self.levels + 1):
                self.add_module(f"down_{c}_{k}", _seq(
                    *[_conv(w[k - 1], w[k - 1], act="R") for _ in range(depth)],
                    _conv(w[k - 1], w[k], act="R", k=2, stride=2, pad=0)))
        self.body = _seq(*[_conv(w[-1], w[-1], act="R") for _ in range(depth + 1)])
        for k in range(self.levels, 0, -1):
            self.add_module(f"up_{k}", _seq(
                _conv(w[k], w[k - 1], act="R", k=2, stride=2, pad=0, transpose=True),
                *[_conv(w[k - 1], w[k - 1], act="R") for _ in range(depth)]))
        self.tail = nn.Conv2d(w[0], 3, 3, 1, 1)

    def forward(self, rgb, noise_map):
        skips = None
        for i, c in enumerate("rgb"):
            x = getattr(self, f"head_{c}")(torch.cat([rgb[:, i:i + 1], noise_map], dim=1))
            feats = [x]
            for k in range(1, self.levels + 1):
                x = getattr(self, f"down_{c}_{k}")(x)
                feats.append(x)
            skips = feats if skips is None else [a + b for a, b in zip(skips, feats, strict=True)]
        x = self.body(skips[-1])
        for k in range(self.levels, 0, -1):
            x = getattr(self, f"up_{k}")(x + skips[k])
        return self.tail(x + skips[0]) + rgb


class SJDDNet(nn.Module):
    """SJDD-Net (see the module doc).  ``forward(spikes, mask) -> (rgb, noise_map)``.

    Parameters
    ----------
    config : SJDDConfig, dict or None
        Architecture; ``None`` = :data:`DEFAULT` (published widths, c = 1).

    Forward inputs: ``spikes`` (N, n_readouts, H, W) float 0/1, ``mask``
    (N, 4, H, W) Bayer planes ``[R, G1, G2, B]`` (``spikesim.cfa.mask_planes``).
    Outputs: linear RGB (N, 3, H, W) and the noise map (N, 1, H, W), both
    cropped to the input size.
    """

    def __init__(self, config: SJDDConfig | dict | None = None):
        super().__init__()
        if config is None:
            config = DEFAULT
        elif isinstance(config, dict):
            config = SJDDConfig.from_dict(config)
        elif not isinstance(config, SJDDConfig):
            raise SpikeSimTypeError(f"config must be an SJDDConfig or dict, got "
                                    f"{type(config).__name__}")
        self.config = config
        self.csr = CSR(config)
        self.sne = SNE(config)
        self.ccp = CCP(config)
        self.mus = nn.ParameterList([nn.Parameter(torch.full((1,), float(config.mu_init)))
                                     for _ in range(config.stages)])

    def check_inputs(self, spikes, mask) -> None:
        """Raise a clear error for inputs this model cannot take."""
        n = self.config.n_readouts
        if not isinstance(spikes, torch.Tensor) or not isinstance(mask, torch.Tensor):
            raise SpikeSimTypeError("spikes and mask must be torch tensors")
        if spikes.dim() != 4:
            raise bad_value("spikes.shape", tuple(spikes.shape), f"(N, {n}, H, W)")
        if spikes.shape[1] != n:
            raise bad_value("spikes.shape[1] (readouts)", spikes.shape[1],
                            f"{n} readouts: this model was built with n_readouts={n}")
        if mask.dim() != 4 or mask.shape[1] != 4:
            raise bad_value("mask.shape", tuple(mask.shape), "(N, 4, H, W) planes [R, G1, G2, B]")
        if mask.shape[0] != spikes.shape[0] or mask.shape[2:] != spikes.shape[2:]:
            raise bad_value("mask.shape", tuple(mask.shape),
                            f"({spikes.shape[0]}, 4, {spikes.shape[2]}, {spikes.shape[3]}) "
                            f"to match spikes {tuple(spikes.shape)}")
        if not spikes.is_floating_point():
            raise SpikeSimTypeError(f"spikes must be a float tensor of 0/1, got {spikes.dtype}")

    def forward(self, spikes, mask):
        self.check_inputs(spikes, mask)
        h, w = spikes.shape[-2:]
        m = self.config.pad_multiple
        ph, pw = (-h) % m, (-w) % m
        mask = mask.to(spikes.dtype)
        if ph or pw:
            spikes = F.pad(spikes, (0, pw, 0, ph), mode="replicate")
            mask = F.pad(mask, (0, pw, 0, ph))
        y = self.csr(spikes, mask).float()  # the HQS update runs in float32 under autocast
        noise_map = self.sne(spikes, mask)
        x = y
        for mu in self.mus:
            z = self.ccp(x, noise_map)
            x = (y + mu * z.float()) / (self.config.hqs_c + mu)
        return x[..., :h, :w], noise_map[..., :h, :w]
