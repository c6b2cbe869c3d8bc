"""A scene that does not change: one image, linear light."""

from __future__ import annotations

import numpy as np

from spikesim.errors import SpikeSimTypeError, bad_value
from spikesim.scenes.base import Scene

__all__ = ["Static", "validate_radiance"]


def validate_radiance(image: np.ndarray, name: str = "image") -> np.ndarray:
    """Check a radiance image and return it as C-contiguous (H, W, 3) float32.

    Accepts (H, W) (grey: copied to the three channels) or (H, W, 3), any real
    dtype.  Values are linear light, relative units; they must be finite and
    non-negative (values above 1 are allowed: the sensor saturates per its
    reset mode).
    """
    arr = np.asarray(image)
    if arr.dtype.kind not in "fiu" or arr.dtype == np.bool_:
        raise SpikeSimTypeError(f"{name} must have a real numeric dtype, got {arr.dtype}")
    if arr.ndim == 2:
        arr = np.repeat(arr[..., None], 3, axis=2)
    if arr.ndim != 3 or arr.shape[2] != 3:
        raise bad_value(f"{name}.shape", np.shape(image), "(H, W) or (H, W, 3)")
    if arr.shape[0] < 1 or arr.shape[1] < 1:
        raise bad_value(f"{name}.shape", arr.shape, "H >= 1 and W >= 1")
    arr = np.ascontiguousarray(arr, dtype=np.float32)
    finite = np.isfinite(arr)
    if not finite.all():
        bad = arr[~finite][0]
        raise bad_value(name, f"contains {bad}", "finite radiance (no NaN or inf)")
    low = float(arr.min())
    if low < 0:
        raise bad_value(name, f"minimum {low}", "non-negative linear radiance")
    return arr


class Static(Scene):
    """A still image as a scene.

    Parameters
    ----------
    image : (H, W) or (H, W, 3) array
        Linear-light radiance, relative units (1.0 = full scale).
    """

    key_interval_s = None

    def __init__(self, image: np.ndarray):
        self._image = validate_radiance(image, "image")
        self._image.setflags(write=False)
        self.height, self.width = self._image.shape[:2]
        self._mean: list[float] | None = None

    def radiance(self, t: float) -> np.ndarray:
        return self._image

    def describe(self) -> dict:
        if self._mean is None:  # computed once: every simulation of the scene asks for it
            # rows first: a contiguous reduction, ten times faster than over both axes
            sums = self._image.sum(axis=0, dtype=np.float64).sum(axis=0)
            self._mean = [float(v) / (self.height * self.width) for v in sums]
        return {
            "type": "static",
            "height": self.height,
            "width": self.width,
            "mean_radiance": list(self._mean),
        }

    def __repr__(self) -> str:
        return f"Static(<{self.height}x{self.width} image>)"
