"""The sRGB transfer functions of IEC 61966-2-1:1999, the project's one implementation.

Decoding (the electro-optical transfer function, EOTF) maps an encoded value
V in [0, 1] to linear light L::

    L = V / 12.92                      for V <= 0.0031308 · 12.92 (≈ 0.04045)
    L = ((V + 0.055) / 1.055) ** 2.4   otherwise

and encoding is its inverse::

    V = 12.92 · L                      for L <= 0.0031308
    V = 1.055 · L ** (1 / 2.4) − 0.055 otherwise

The same arithmetic as colour-science's ``eotf_sRGB`` and
``eotf_inverse_sRGB`` (tested equal), without its two-second import.

Examples
--------
>>> from spikesim.srgb import linear_to_srgb, linear_to_srgb8, srgb_to_linear
>>> round(float(srgb_to_linear(0.5)), 6)
0.214041
>>> linear_to_srgb8([0.0, 0.18, 1.0, 2.0])  # 18 % grey is code 118
array([  0, 118, 255, 255], dtype=uint8)
"""

from __future__ import annotations

import numpy as np

__all__ = ["srgb_to_linear", "linear_to_srgb", "linear_to_srgb8"]

#: The decoding knee as colour-science computes it: the encoding of 0.0031308
#: (0.0404499…, a hair below the standard's rounded 0.04045).
_KNEE = 0.0031308 * 12.92


def srgb_to_linear(values) -> np.ndarray:
    """Decode sRGB values (0..1 nominal; larger values follow the power branch) to linear
    light, float64."""
    v = np.asarray(values, dtype=np.float64)
    return np.where(v <= _KNEE, v / 12.92, np.power(np.abs((v + 0.055) / 1.055), 2.4))


def linear_to_srgb(values) -> np.ndarray:
    """Encode linear light to sRGB values in [0, 1], float64 (clipped to [0, 1] first:
    display values cannot exceed full scale)."""
    x = np.clip(np.asarray(values, dtype=np.float64), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def linear_to_srgb8(values) -> np.ndarray:
    """Encode linear light to 8-bit sRGB codes (uint8, rounded to nearest)."""
    return np.rint(linear_to_srgb(values) * 255.0).astype(np.uint8)
