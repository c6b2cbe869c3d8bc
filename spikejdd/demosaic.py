"""Bayer demosaicing of one (H, W) mosaic into (H, W, 3) linear RGB.

Methods (all take float input in linear light and return float64):

* ``bilinear`` — our own: per-channel normalised convolution (Knutsson &
  Westin 1993) with the classic bilinear kernels, so every output pixel is the
  weighted mean of the *available* same-colour samples in its 3×3
  neighbourhood.  Inside the image this equals textbook bilinear
  interpolation; at the border it averages only the samples that exist, so a
  flat image is reproduced exactly everywhere (colour-demosaicing's bilinear
  pads with zeros and darkens the one-pixel border).
* ``malvar2004`` and ``menon2007`` are run on a Bayer-phase-preserving
  mirror padding of the mosaic (see ``_phase_preserving``), fixing the
  library's wrong-colour border.
* ``malvar2004`` — Malvar, He, Cutler, "High-quality linear interpolation for
  demosaicing of Bayer-patterned color images", ICASSP 2004, via
  ``colour_demosaicing.demosaicing_CFA_Bayer_Malvar2004``.
* ``menon2007`` — Menon, Andriani, Calvagno, "Demosaicing with directional
  filtering and a posteriori decision", IEEE TIP 16(1), 2007, via
  ``colour_demosaicing.demosaicing_CFA_Bayer_Menon2007``.
* ``opencv_ea`` — OpenCV's edge-aware demosaic (``COLOR_Bayer*2RGB_EA``, a
  variable-number-of-gradients style interpolation).  OpenCV takes integers,
  so the mosaic is clipped to [0, 1] and quantised to 16 bits (step 1.5e-5).

A monochrome sensor (``cfa=None``) has nothing to demosaic: the grey value is
copied to the three channels.
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np

from spikesim.cfa import mask_rgb, normalize_cfa
from spikesim.errors import SpikeSimTypeError, bad_value

__all__ = ["DEMOSAIC_METHODS", "demosaic", "bilinear", "malvar2004", "menon2007", "opencv_ea"]

_KERNEL_G = np.array([[0, 1, 0], [1, 4, 1], [0, 1, 0]], np.float64) / 4.0
_KERNEL_RB = np.array([[1, 2, 1], [2, 4, 2], [1, 2, 1]], np.float64) / 4.0

#: OpenCV names a Bayer pattern by the 2×2 tile starting at row 1, column 1,
#: so our top-left name maps to the diagonal opposite (checked in the tests).
_OPENCV_CODE = {
    "RGGB": cv2.COLOR_BayerBG2RGB_EA,
    "BGGR": cv2.COLOR_BayerRG2RGB_EA,
    "GRBG": cv2.COLOR_BayerGB2RGB_EA,
    "GBRG": cv2.COLOR_BayerGR2RGB_EA,
}


def _conv(img: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    # correlation == convolution for these symmetric kernels; zero outside the image
    return cv2.filter2D(img, cv2.CV_64F, kernel, borderType=cv2.BORDER_CONSTANT)


def bilinear(raw: np.ndarray, cfa: str) -> np.ndarray:
    """Bilinear demosaic with exact borders (normalised convolution); see module doc."""
    raw = np.asarray(raw, np.float64)
    masks = mask_rgb(cfa, *raw.shape).astype(np.float64)
    out = np.empty(raw.shape + (3,), np.float64)
    for ch in range(3):
        kernel = _KERNEL_G if ch == 1 else _KERNEL_RB
        m = masks[..., ch]
        out[..., ch] = _conv(raw * m, kernel) / _conv(m, kernel)
    return out


#: Border added around the mosaic before calling colour-demosaicing (even, so
#: the pattern name is unchanged; >= the 5×5 / 5-tap filter radius).
_PAD = 4


def _phase_preserving(fn: Callable[[np.ndarray, str], np.ndarray], raw, cfa: str) -> np.ndarray:
    """Run ``fn`` on a mirror-padded mosaic and crop back.

    colour-demosaicing convolves with SciPy's default ``mode="reflect"``, which
    repeats the edge pixel and so puts the wrong colour next to the border
    (a flat grey image comes back with errors up to 40 % on the edge rows).
    NumPy's ``"reflect"`` padding mirrors *about* the edge pixel, which keeps
    the Bayer phase, so the library's own border rule never sees a wrong colour.
    """
    arr = np.asarray(raw, np.float64)
    padded = np.pad(arr, _PAD, mode="reflect")
    out = np.asarray(fn(padded, cfa), np.float64)
    return out[_PAD:-_PAD, _PAD:-_PAD]


def malvar2004(raw: np.ndarray, cfa: str) -> np.ndarray:
    """Malvar–He–Cutler 2004 gradient-corrected linear demosaic (colour-demosaicing)."""
    from colour_demosaicing import demosaicing_CFA_Bayer_Malvar2004

    return _phase_preserving(demosaicing_CFA_Bayer_Malvar2004, raw, cfa)


def menon2007(raw: np.ndarray, cfa: str) -> np.ndarray:
    """Menon–Andriani–Calvagno 2007 DDFAPD demosaic with refining step (colour-demosaicing)."""
    from colour_demosaicing import demosaicing_CFA_Bayer_Menon2007

    return _phase_preserving(demosaicing_CFA_Bayer_Menon2007, raw, cfa)


def opencv_ea(raw: np.ndarray, cfa: str) -> np.ndarray:
    """OpenCV edge-aware demosaic on a 16-bit quantisation of ``clip(raw, 0, 1)``."""
    q = np.round(np.clip(np.asarray(raw, np.float64), 0.0, 1.0) * 65535.0).astype(np.uint16)
    return cv2.cvtColor(q, _OPENCV_CODE[cfa]).astype(np.float64) / 65535.0


DEMOSAIC_METHODS: dict[str, Callable[[np.ndarray, str], np.ndarray]] = {
    "bilinear": bilinear,
    "malvar2004": malvar2004,
    "menon2007": menon2007,
    "opencv_ea": opencv_ea,
}


def demosaic(raw: np.ndarray, cfa: str | None, method: str = "bilinear") -> np.ndarray:
    """Demosaic an (H, W) linear mosaic sampled through ``cfa`` into (H, W, 3) float64.

    Parameters
    ----------
    raw : (H, W) real array
        One value per pixel, linear light (scene units).
    cfa : {"RGGB", "BGGR", "GRBG", "GBRG"} or None
        Pattern of the top-left 2×2 tile of ``raw``; ``None``/"mono" copies
        the grey value to R, G and B.
    method : {"bilinear", "malvar2004", "menon2007", "opencv_ea"}
    """
    if method not in DEMOSAIC_METHODS:
        raise bad_value("demosaic method", method, f"one of {tuple(DEMOSAIC_METHODS)}")
    arr = np.asarray(raw)
    if arr.dtype.kind not in "fiu" or arr.dtype == np.bool_:
        raise SpikeSimTypeError(f"raw must have a real numeric dtype, got {arr.dtype}")
    if arr.ndim != 2:
        raise bad_value("raw.shape", arr.shape, "a 2-D mosaic (H, W)")
    pattern = normalize_cfa(cfa)
    if pattern is None:
        return np.repeat(arr.astype(np.float64)[..., None], 3, axis=2)
    if arr.shape[0] < 2 or arr.shape[1] < 2:
        raise bad_value("raw.shape", arr.shape, "at least 2×2 pixels for a Bayer mosaic")
    return DEMOSAIC_METHODS[method](arr, pattern)
