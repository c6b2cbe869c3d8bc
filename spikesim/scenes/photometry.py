"""Photometry: turn stored frame values into linear-light radiance.

Scene radiance in spikesim is *linear light, relative units* (DESIGN.md §2):
1.0 per channel is full scale, the light at which a pixel fires
``full_scale_rate`` spikes per readout.  Video frames are usually stored
sRGB-encoded, so they are decoded with the sRGB electro-optical transfer
function (EOTF) of IEC 61966-2-1:1999 exactly as colour-science implements it
(:func:`colour.models.eotf_sRGB`; same operations, tested bit-equal)::

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

__all__ = [
    "srgb_to_linear",
    "linear_to_srgb",
    "SRGB8_LUT",  # noqa: F822 - provided lazily by __getattr__
    "decode_frame",
    "check_exposure",
]


#: Encoded value of the linear knee 0.0031308 (colour-science computes it the same way).
_SRGB_KNEE = 0.0031308 * 12.92


def _spow(a: np.ndarray, p: float) -> np.ndarray:
    """``sign(a) * |a| ** p`` (colour-science's ``spow``: no NaN for negative ``a``)."""
    return np.sign(a) * np.abs(a) ** p


def srgb_to_linear(values: np.ndarray) -> np.ndarray:
    """sRGB EOTF (IEC 61966-2-1) per colour-science: encoded 0..1 → linear 0..1 (float64).

    The same operations in the same order as :func:`colour.models.eotf_sRGB`
    (tested bit-equal to it) without importing colour-science, which takes
    seconds: every worker process of a dataset build decodes frames."""
    v = np.asarray(values, dtype=np.float64)
    return np.where(_SRGB_KNEE >= v, v / 12.92, _spow((v + 0.055) / 1.055, 2.4))


def linear_to_srgb(values: np.ndarray) -> np.ndarray:
    """Inverse sRGB EOTF (the encoding), per colour-science: linear → encoded (float64).

    Bit-equal to :func:`colour.models.eotf_inverse_sRGB` (tested), without importing it."""
    v = np.asarray(values, dtype=np.float64)
    return np.where(v <= 0.0031308, v * 12.92, 1.055 * _spow(v, 1 / 2.4) - 0.055)


#: Linear value of each 8-bit sRGB code 0..255 (float32), from :func:`srgb_to_linear`.
@functools.lru_cache(maxsize=1)
def _srgb8_lut() -> np.ndarray:
    lut = srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)
    lut.setflags(write=False)
    return lut


def __getattr__(name: str):
    # SRGB8_LUT is built on first use
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
