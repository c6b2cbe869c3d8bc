"""Bundled source material for procedural scenes (no downloads).

* Photographs bundled with scikit-image (``skimage.data``), decoded from sRGB
  to linear light and resized to the scene size by cover-cropping (the centre
  of the picture is kept, the aspect ratio is preserved).  Resizing happens in
  linear light (area averaging when shrinking, bicubic when enlarging).
* The 24 patches of the X-Rite ColorChecker (``"ColorChecker24 - After
  November 2014"`` in colour-science, CIE xyY under D50), adapted to D65 with
  the Bradford transform and converted to linear sRGB primaries; the few
  slightly out-of-gamut components are clipped at 0.
"""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np

from spikesim._validate import check_size
from spikesim.errors import bad_value
from spikesim.scenes.photometry import decode_frame

__all__ = ["IMAGES", "load_image", "cover_resize", "resize_linear", "colorchecker_linear_srgb"]

#: Name → (skimage.data function name, one-line description).
IMAGES: dict[str, tuple[str, str]] = {
    "astronaut": ("astronaut", "portrait of astronaut Eileen Collins (colour, 512x512)"),
    "chelsea": ("chelsea", "Chelsea the cat (colour, 300x451)"),
    "coffee": ("coffee", "a cup of coffee on a saucer (colour, 400x600)"),
    "rocket": ("rocket", "a rocket launch against the sky (colour, 427x640)"),
    "camera": ("camera", "the classic cameraman (grey, 512x512)"),
    "hubble": ("hubble_deep_field", "Hubble deep field, mostly dark sky (colour, 872x1000)"),
}


@lru_cache(maxsize=16)
def _raw_linear(name: str) -> np.ndarray:
    import skimage.data

    if name not in IMAGES:
        raise bad_value("image", name, f"one of {sorted(IMAGES)}")
    img = getattr(skimage.data, IMAGES[name][0])()
    out = decode_frame(img, linear=False, name=f"skimage.data.{IMAGES[name][0]}")
    out.setflags(write=False)
    return out


def resize_linear(image: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """``image`` (linear light) resized to ``size`` = (H, W): area averaging when
    shrinking, bicubic when enlarging, clipped to the image's own range (bicubic
    over- and undershoots at edges: no light the image did not have)."""
    h, w = size
    if image.shape[:2] == (h, w):
        return image
    shrink = h < image.shape[0] or w < image.shape[1]
    out = cv2.resize(image, (w, h), interpolation=cv2.INTER_AREA if shrink else cv2.INTER_CUBIC)
    return np.clip(out, 0.0, float(image.max()))


def cover_resize(image: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Crop the centre of ``image`` to the aspect of ``size`` and resize to it (linear light)."""
    h, w = size
    ih, iw = image.shape[:2]
    scale = max(h / ih, w / iw)
    ch, cw = min(ih, max(1, round(h / scale))), min(iw, max(1, round(w / scale)))
    top, left = (ih - ch) // 2, (iw - cw) // 2
    crop = np.ascontiguousarray(image[top : top + ch, left : left + cw], dtype=np.float32)
    out = resize_linear(crop, size)
    if out.ndim == 2:
        out = out[..., None].repeat(3, axis=2)
    return np.clip(out, 0.0, None).astype(np.float32)


def load_image(name: str, size: tuple[int, int]) -> np.ndarray:
    """Bundled photograph ``name`` as (H, W, 3) float32 linear radiance (0..1)."""
    return cover_resize(_raw_linear(name), check_size(size))


@lru_cache(maxsize=1)
def colorchecker_linear_srgb() -> tuple[tuple[str, ...], np.ndarray]:
    """Names and (24, 3) linear-sRGB values of the ColorChecker patches (row-major, 4×6)."""
    import colour  # imported on use: colour-science takes ~2 s to import

    cc = colour.CCS_COLOURCHECKERS["ColorChecker24 - After November 2014"]
    names = tuple(cc.data.keys())
    xyz = colour.xyY_to_XYZ(np.array(list(cc.data.values()), dtype=np.float64))
    rgb = colour.XYZ_to_RGB(
        xyz,
        "sRGB",
        illuminant=cc.illuminant,
        chromatic_adaptation_transform="Bradford",
        apply_cctf_encoding=False,
    )
    rgb = np.clip(rgb, 0.0, None).astype(np.float32)
    rgb.setflags(write=False)
    return names, rgb
