"""Bayer colour filter arrays: patterns, masks, and how crops and flips move them.

A pattern is named by its top-left 2×2 tile read row by row (``"RGGB"`` means
``R G / G B``).  ``None`` (or ``"mono"``) is a monochrome sensor.  Row 0 is the
top of the image (docs/architecture.md, Conventions).

Two mask layouts are provided:

* ``(H, W, 3)`` one-hot over ``[R, G, B]`` (which colour each pixel samples);
* ``(4, H, W)`` planes ``[R, G1, G2, B]`` as used by SJDD-Net's loader, where
  ``G1`` is the green site on the red row and ``G2`` the green on the blue row.
"""

from __future__ import annotations

import numpy as np

from spikesim.errors import bad_value

__all__ = [
    "PATTERNS",
    "normalize_cfa",
    "channel_index",
    "mask_rgb",
    "mask_planes",
    "cfa_after_crop",
    "cfa_after_flip",
    "mosaic",
    "LUMA_WEIGHTS",
]

PATTERNS: tuple[str, ...] = ("RGGB", "BGGR", "GRBG", "GBRG")

#: Rec. 709 luminance weights used for a monochrome sensor (linear light).
LUMA_WEIGHTS = np.array([0.2126, 0.7152, 0.0722], dtype=np.float64)

_CHANNEL = {"R": 0, "G": 1, "B": 2}


def normalize_cfa(cfa: str | None) -> str | None:
    """Return the canonical pattern name (upper case) or ``None`` for mono."""
    if cfa is None:
        return None
    if not isinstance(cfa, str):
        raise bad_value("cfa", cfa, f"one of {PATTERNS} or None/'mono'")
    name = cfa.strip().upper()
    if name in ("MONO", "NONE", ""):
        return None
    if name not in PATTERNS:
        raise bad_value("cfa", cfa, f"one of {PATTERNS} or None/'mono'")
    return name


def _tile(cfa: str) -> np.ndarray:
    return np.array([[_CHANNEL[cfa[0]], _CHANNEL[cfa[1]]], [_CHANNEL[cfa[2]], _CHANNEL[cfa[3]]]])


def channel_index(cfa: str | None, height: int, width: int) -> np.ndarray | None:
    """(H, W) int8 array of the colour each pixel samples (0=R, 1=G, 2=B); None for mono."""
    cfa = normalize_cfa(cfa)
    if cfa is None:
        return None
    tile = _tile(cfa).astype(np.int8)
    reps = ((height + 1) // 2, (width + 1) // 2)
    return np.tile(tile, reps)[:height, :width].copy()


def mask_rgb(cfa: str | None, height: int, width: int) -> np.ndarray:
    """(H, W, 3) float32 one-hot mask; all ones for a monochrome sensor."""
    idx = channel_index(cfa, height, width)
    if idx is None:
        return np.ones((height, width, 3), np.float32)
    return (idx[..., None] == np.arange(3)).astype(np.float32)


def mask_planes(cfa: str | None, height: int, width: int) -> np.ndarray:
    """(4, H, W) float32 masks ``[R, G1, G2, B]``; G1 is green on the red row.

    For a monochrome sensor every plane is ones / 4 is not meaningful, so this
    raises instead.
    """
    cfa = normalize_cfa(cfa)
    if cfa is None:
        raise bad_value("cfa", cfa, "a Bayer pattern (planes are undefined for mono)")
    tile = _tile(cfa)
    planes = np.zeros((4, 2, 2), np.float32)
    red_row = int(np.argwhere(tile == 0)[0][0])
    for r in range(2):
        for c in range(2):
            ch = tile[r, c]
            if ch == 0:
                planes[0, r, c] = 1
            elif ch == 2:
                planes[3, r, c] = 1
            else:
                planes[1 if r == red_row else 2, r, c] = 1
    reps = (1, (height + 1) // 2, (width + 1) // 2)
    return np.tile(planes, reps)[:, :height, :width].copy()


def _from_tile(tile: np.ndarray) -> str:
    names = "RGB"
    return "".join(names[v] for v in tile.ravel())


def cfa_after_crop(cfa: str | None, top: int, left: int) -> str | None:
    """Pattern of the crop whose top-left pixel is ``(top, left)`` in the original."""
    cfa = normalize_cfa(cfa)
    if cfa is None:
        return None
    if top < 0 or left < 0:
        raise bad_value("top/left", (top, left), "non-negative crop offsets")
    tile = _tile(cfa)
    return _from_tile(np.roll(tile, shift=(-(top % 2), -(left % 2)), axis=(0, 1)))


def cfa_after_flip(
    cfa: str | None, height: int, width: int, horizontal: bool = False, vertical: bool = False
) -> str | None:
    """Pattern after mirroring an ``height × width`` image left-right and/or up-down.

    A flip maps pixel ``x`` to ``width-1-x``, so the new pattern depends on the
    parity of the size: an even width swaps the tile columns, an odd width keeps them.
    """
    cfa = normalize_cfa(cfa)
    if cfa is None:
        return None
    full = channel_index(cfa, height, width)
    if horizontal:
        full = full[:, ::-1]
    if vertical:
        full = full[::-1, :]
    if full.shape[0] < 2 or full.shape[1] < 2:
        raise bad_value("height/width", (height, width), "at least 2×2 to define a Bayer pattern")
    return _from_tile(full[:2, :2])


def mosaic(rgb: np.ndarray, cfa: str | None) -> np.ndarray:
    """Sample an (H, W, 3) image through the CFA: (H, W) values the sensor sees.

    Monochrome sensors see Rec. 709 luminance of the linear RGB input,
    ``0.2126 R + 0.7152 G + 0.0722 B`` evaluated in float64 in that order and
    rounded to float32 (exactly what the simulator integrates).
    """
    rgb = np.asarray(rgb)
    h, w = rgb.shape[:2]
    idx = channel_index(cfa, h, w)
    if idx is None:
        c = rgb.astype(np.float64)
        wr, wg, wb = LUMA_WEIGHTS
        return (wr * c[..., 0] + wg * c[..., 1] + wb * c[..., 2]).astype(np.float32)
    return np.take_along_axis(rgb, idx[..., None].astype(np.intp), axis=2)[..., 0]
