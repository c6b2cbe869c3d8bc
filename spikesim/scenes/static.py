"""A scene that does not change: one image, linear light."""

from __future__ import annotations

import warnings

import numpy as np

from spikesim.errors import SpikeSimTypeError, bad_value
from spikesim.scenes.base import Scene

__all__ = ["Static", "validate_grey", "validate_radiance"]


def _check_values(arr: np.ndarray, name: str) -> None:
    """Raise unless every value of ``arr`` is finite and non-negative."""
    finite = np.isfinite(arr)
    if not finite.all():
        bad = arr[~finite][0]
        raise bad_value(name, f"contains {bad}", "finite radiance (no NaN or inf)")
    low = float(arr.min())
    if low < 0:
        raise bad_value(name, f"minimum {low}", "non-negative linear radiance")


#: Largest float32 radiance: finite values above it (float64 input) are stored as it.
FLOAT32_MAX = float(np.finfo(np.float32).max)


def _checked_float32(arr: np.ndarray, name: str) -> np.ndarray:
    """``arr`` (of a valid rank) as C-contiguous float32 once its size and values
    are checked, in its own precision: a finite float64 value beyond float32's
    range (about 3.4e38) becomes :data:`FLOAT32_MAX`, which saturates the sensor
    as it would have (a float32 cast would have made it inf)."""
    if arr.shape[0] < 1 or arr.shape[1] < 1:
        raise bad_value(f"{name}.shape", arr.shape, "H >= 1 and W >= 1")
    _check_values(arr, name)
    if arr.dtype.kind == "f" and arr.dtype.itemsize > 4:
        arr = np.minimum(arr, FLOAT32_MAX)
    return np.ascontiguousarray(arr, dtype=np.float32)


def _check_dtype(arr: np.ndarray, name: str) -> None:
    if arr.dtype.kind not in "fiu" or arr.dtype == np.bool_:
        raise SpikeSimTypeError(f"{name} must have a real numeric dtype, got {arr.dtype}")


def validate_grey(image: np.ndarray, name: str = "image") -> np.ndarray:
    """Check a one-channel (grey) radiance image and return it as C-contiguous
    (H, W) float32 (the same array when it already is one).  Values as in
    :func:`validate_radiance`."""
    arr = np.asarray(image)
    _check_dtype(arr, name)
    if arr.ndim != 2:
        raise bad_value(f"{name}.shape", np.shape(image), "(H, W)")
    return _checked_float32(arr, name)


def validate_radiance(image: np.ndarray, name: str = "image") -> np.ndarray:
    """Check a radiance image and return it as C-contiguous (H, W, 3) float32.

    Accepts (H, W) (grey: copied to the three channels) or (H, W, 3), any real
    dtype.  Values are linear light, relative units; they must be finite and
    non-negative (values above 1 are allowed: the sensor saturates per its
    reset mode; float64 values beyond float32's range are stored as
    :data:`FLOAT32_MAX`, which saturates all the same).
    """
    arr = np.asarray(image)
    _check_dtype(arr, name)
    if arr.ndim == 2:
        return np.repeat(validate_grey(arr, name)[..., None], 3, axis=2)
    if arr.ndim != 3 or arr.shape[2] != 3:
        raise bad_value(f"{name}.shape", np.shape(image), "(H, W) or (H, W, 3)")
    return _checked_float32(arr, name)


def _own(checked: np.ndarray, given: np.ndarray) -> np.ndarray:
    """``checked`` (the validated ``given``) as an array nobody else holds."""
    return checked.copy() if np.may_share_memory(checked, given) else checked


class Static(Scene):
    """A still image as a scene.

    Parameters
    ----------
    image : (H, W) or (H, W, 3) array
        Linear-light radiance, relative units (1.0 = full scale), any real
        dtype, taken as given: an 8-bit picture must be divided by 255 and
        linearised first (``spikesim.srgb``), else 255 means 255 × full scale.
        The scene keeps its own copy.  A grey (H, W) image is kept as one
        channel (:meth:`grey`); its three-channel copy is made only if someone
        asks for :meth:`radiance`.
    """

    key_interval_s = None

    def __init__(self, image: np.ndarray):
        arr = np.asarray(image)
        if arr.dtype == np.uint8 and arr.size and int(arr.max()) > 1:
            warnings.warn(f"Static: image is 8-bit (0..{int(arr.max())}), taken as radiance, so "
                          "everything above 1 saturates; for a picture pass "
                          "spikesim.srgb.srgb_to_linear(image / 255)", UserWarning, stacklevel=2)
        self._grey: np.ndarray | None = None
        self._rgb: np.ndarray | None = None
        # private copies: the scene must not change with the caller's array
        if arr.ndim == 2:
            self._grey = _own(validate_grey(arr, "image"), arr)
            self._grey.setflags(write=False)
        else:
            self._rgb = _own(validate_radiance(arr, "image"), arr)
            self._rgb.setflags(write=False)
        self.height, self.width = arr.shape[:2]
        self._mean: list[float] | None = None

    def radiance(self, t: float) -> np.ndarray:
        if self._rgb is None:
            self._rgb = np.repeat(self._grey[..., None], 3, axis=2)
            self._rgb.setflags(write=False)
        return self._rgb

    def grey(self, t: float) -> np.ndarray | None:
        return self._grey

    def describe(self) -> dict:
        if self._mean is None:  # computed once: every simulation of the scene asks for it
            if self._grey is not None:
                self._mean = [float(self._grey.sum(axis=0, dtype=np.float64).sum())
                              / (self.height * self.width)] * 3
            else:
                # rows first: a contiguous reduction, ten times faster than over both axes
                sums = self._rgb.sum(axis=0, dtype=np.float64).sum(axis=0)
                self._mean = [float(v) / (self.height * self.width) for v in sums]
        return {
            "type": "static",
            "height": self.height,
            "width": self.width,
            "mean_radiance": list(self._mean),
        }

    def __repr__(self) -> str:
        return f"Static(<{self.height}x{self.width} image>)"
