"""Image quality metrics: PSNR and SSIM on RGB, peak 1.0 (docs/architecture.md, Conventions).

Conventions (fixed; every score carries its label):

* inputs are (H, W, 3) (or (H, W)) float images in [0, 1]; both are clamped
  to [0, 1] first, never rounded; no border crop; the data range is explicit
  (1.0), never inferred from the data;
* ``domain="linear"`` scores linear light as stored; ``domain="srgb"`` first
  applies the sRGB encoding curve (IEC 61966-2-1) to both images;
* SSIM (Wang, Bovik, Sheikh, Simoncelli, IEEE TIP 13(4), 2004, eq. 13 with
  K1 = 0.01, K2 = 0.03) in two variants:

  - ``"gauss11"`` — 11×11 Gaussian window, σ = 1.5, population statistics, as
    in Wang et al.'s reference code and restoration papers;
  - ``"uniform7"`` — 7×7 uniform window with sample (N−1) covariance, the
    default of ``skimage.metrics.structural_similarity``;

  per-channel SSIM maps are averaged over the pixels whose window lies fully
  inside the image (the "valid" region, as both references do) and over channels.

PSNR = 10·log10(1 / MSE) over all pixels and channels (``inf`` for identical images).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from scipy import ndimage

from spikesim.errors import SpikeSimTypeError, bad_value
from spikesim.srgb import linear_to_srgb as srgb_encode  # re-exported: the one sRGB curve

__all__ = ["psnr", "ssim", "srgb_encode", "score", "SSIM_VARIANTS", "DOMAINS", "label"]

SSIM_VARIANTS: tuple[str, ...] = ("gauss11", "uniform7")
DOMAINS: tuple[str, ...] = ("linear", "srgb")

_K1, _K2 = 0.01, 0.03


def _prepare(x: np.ndarray, ref: np.ndarray, domain: str) -> tuple[np.ndarray, np.ndarray]:
    a, b = np.asarray(x), np.asarray(ref)
    for name, arr in (("x", a), ("ref", b)):
        if arr.dtype.kind not in "fiu" or arr.dtype == np.bool_:
            raise SpikeSimTypeError(f"{name} must be a real float image, got dtype {arr.dtype}")
        if arr.ndim not in (2, 3) or (arr.ndim == 3 and arr.shape[2] not in (1, 3)):
            raise bad_value(f"{name}.shape", arr.shape, "(H, W) or (H, W, 3)")
    if a.shape != b.shape:
        raise bad_value("x.shape", a.shape, f"the shape of ref {b.shape}")
    if domain not in DOMAINS:
        raise bad_value("domain", domain, f"one of {DOMAINS}")
    a = np.clip(a.astype(np.float64), 0.0, 1.0)
    b = np.clip(b.astype(np.float64), 0.0, 1.0)
    if not (np.isfinite(a).all() and np.isfinite(b).all()):
        raise bad_value("x/ref", "non-finite values", "finite images (no NaN)")
    if domain == "srgb":
        a, b = srgb_encode(a), srgb_encode(b)
    if a.ndim == 2:
        a, b = a[..., None], b[..., None]
    return a, b


def label(metric: str, domain: str, variant: str | None = None) -> str:
    """Label of a score, e.g. ``"PSNR[linear]"`` or ``"SSIM-gauss11[srgb]"``."""
    return f"{metric}{'-' + variant if variant else ''}[{domain}]"


def psnr(x: np.ndarray, ref: np.ndarray, domain: Literal["linear", "srgb"] = "linear") -> float:
    """PSNR in dB with peak 1.0 after clamping to [0, 1] (see module doc)."""
    a, b = _prepare(x, ref, domain)
    mse = float(np.mean((a - b) ** 2))
    return float("inf") if mse == 0 else float(10.0 * np.log10(1.0 / mse))


def _gauss_kernel_1d(sigma: float = 1.5, radius: int = 5) -> np.ndarray:
    t = np.arange(-radius, radius + 1, dtype=np.float64)
    k = np.exp(-0.5 * (t / sigma) ** 2)
    return k / k.sum()


def _filter(img: np.ndarray, variant: str) -> np.ndarray:
    if variant == "gauss11":
        k = _gauss_kernel_1d()
        out = ndimage.correlate1d(img, k, axis=0, mode="reflect")
        return ndimage.correlate1d(out, k, axis=1, mode="reflect")
    return ndimage.uniform_filter(img, size=7, mode="reflect")


def ssim(
    x: np.ndarray,
    ref: np.ndarray,
    variant: Literal["gauss11", "uniform7"] = "gauss11",
    domain: Literal["linear", "srgb"] = "linear",
) -> float:
    """Mean SSIM over channels and the valid region (see module doc)."""
    if variant not in SSIM_VARIANTS:
        raise bad_value("variant", variant, f"one of {SSIM_VARIANTS}")
    a, b = _prepare(x, ref, domain)
    win = 11 if variant == "gauss11" else 7
    if a.shape[0] < win or a.shape[1] < win:
        raise bad_value("x.shape", a.shape[:2], f"at least {win}×{win} pixels for SSIM-{variant}")
    c1, c2 = _K1**2, _K2**2
    scale = win * win / (win * win - 1.0) if variant == "uniform7" else 1.0
    vals = []
    for ch in range(a.shape[2]):
        p, q = a[..., ch], b[..., ch]
        mu_p, mu_q = _filter(p, variant), _filter(q, variant)
        var_p = scale * (_filter(p * p, variant) - mu_p * mu_p)
        var_q = scale * (_filter(q * q, variant) - mu_q * mu_q)
        cov = scale * (_filter(p * q, variant) - mu_p * mu_q)
        s = ((2 * mu_p * mu_q + c1) * (2 * cov + c2)) / (
            (mu_p**2 + mu_q**2 + c1) * (var_p + var_q + c2)
        )
        pad = (win - 1) // 2
        vals.append(s[pad:-pad, pad:-pad].mean())
    return float(np.mean(vals))


def score(x: np.ndarray, ref: np.ndarray, domains: tuple[str, ...] = DOMAINS) -> dict[str, float]:
    """Every metric under every convention, keyed by :func:`label`."""
    out: dict[str, float] = {}
    for d in domains:
        out[label("PSNR", d)] = psnr(x, ref, d)
        for v in SSIM_VARIANTS:
            out[label("SSIM", d, v)] = ssim(x, ref, v, d)
    return out
