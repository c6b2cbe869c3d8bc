"""Photometry: turn stored frame values into linear-light radiance.

Scene radiance in spikesim is *linear light, relative units* (docs/model.md):
1.0 per channel is full scale, the light at which a pixel fires
``full_scale_rate`` spikes per readout.  Video frames are usually stored
sRGB-encoded, so they are decoded with the sRGB electro-optical transfer
function (EOTF) of IEC 61966-2-1:1999 (:mod:`spikesim.srgb`)::

    L = V / 12.92                      for V <= 0.04045
    L = ((V + 0.055) / 1.055) ** 2.4   otherwise

8-bit input goes through a 256-entry lookup table built from that same
function (tested equal to it); 16-bit and float input are decoded by the
function itself.  Input that is already linear (``linear=True``) is only
normalised (uint8 / 255, uint16 / 65535, float as is).  Finally the result is
multiplied by ``exposure`` (dimensionless): ``exposure=2`` doubles the light
reaching the sensor, so a frame value of 0.5 after decoding becomes radiance 1.0
(full scale).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from spikesim.errors import SpikeSimTypeError, bad_value
from spikesim.srgb import srgb_to_linear

__all__ = [
    "SRGB8_LUT",  # noqa: F822 - provided lazily by __getattr__
    "decode_frame",
    "check_exposure",
]


#: Linear value of each 8-bit sRGB code 0..255 (float32), from :func:`srgb_to_linear`.
@functools.lru_cache(maxsize=1)
def _srgb8_lut() -> np.ndarray:
    lut = srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)
    lut.setflags(write=False)
    return lut


def __getattr__(name: str):
    # SRGB8_LUT is built on first use (computed once)
    if name == "SRGB8_LUT":
        return _srgb8_lut()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def check_exposure(exposure: float) -> float:
    """Validate the exposure scale (dimensionless, finite, > 0)."""
    try:
        value = float(exposure)
    except (TypeError, ValueError):
        raise bad_value("exposure", exposure, "a finite number > 0") from None
    if not math.isfinite(value) or value <= 0:
        raise bad_value("exposure", exposure, "a finite number > 0")
    return value


def decode_frame(
    frame: np.ndarray, *, linear: bool = False, exposure: float = 1.0, name: str = "frame"
) -> np.ndarray:
    """Decode one stored frame to (H, W, 3) float32 linear radiance.

    Parameters
    ----------
    frame : (H, W) or (H, W, 3) array, RGB channel order
        uint8 (0..255), uint16 (0..65535) or float (0..1 nominal) values.
    linear : bool
        ``False`` (default): values are sRGB-encoded and are decoded with the
        sRGB EOTF.  ``True``: values are already linear light.
    exposure : float
        Dimensionless scale applied after decoding (1.0 keeps the stored
        white at full scale).
    name : str
        Name used in error messages (e.g. the file name).
    """
    arr = np.asarray(frame)
    exposure = check_exposure(exposure)
    if arr.ndim == 2:
        arr = arr[..., None]
    if arr.ndim != 3 or arr.shape[2] not in (1, 3, 4):
        raise bad_value(f"{name}.shape", np.shape(frame), "(H, W), (H, W, 3) or (H, W, 4)")
    arr = arr[..., :3] if arr.shape[2] >= 3 else np.repeat(arr, 3, axis=2)
    if arr.dtype == np.uint8:
        out = arr.astype(np.float32) / 255.0 if linear else _srgb8_lut()[arr]
    elif arr.dtype == np.uint16:
        scaled = arr.astype(np.float64) / 65535.0
        out = (scaled if linear else srgb_to_linear(scaled)).astype(np.float32)
    elif arr.dtype.kind == "f":
        finite = np.isfinite(arr)
        if not finite.all():
            raise bad_value(name, f"contains {arr[~finite][0]}", "finite values (no NaN or inf)")
        if float(arr.min()) < 0:
            raise bad_value(name, f"minimum {float(arr.min())}", "non-negative values")
        out = (arr if linear else srgb_to_linear(arr)).astype(np.float32)
    else:
        raise SpikeSimTypeError(f"{name} has dtype {arr.dtype}; expected uint8, uint16 or float")
    if exposure != 1.0:
        out = out * np.float32(exposure)
    return np.ascontiguousarray(out, dtype=np.float32)
