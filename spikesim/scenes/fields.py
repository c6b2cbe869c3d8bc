"""Calibration scenes: flat fields, intensity ramps, mains flicker, a colour chart.

* ``Flat`` – the same radiance everywhere (noise and transfer-curve studies).
* ``Ramp`` – radiance rising left to right, linearly from ``low`` to ``high``
  or geometrically (``log=True``: equal ratios per pixel, to span decades of
  dynamic range in one frame).
* ``Flicker`` – a light powered from the mains: its power follows the square
  of the supply voltage, so it pulses at twice the mains frequency,
  ``I(t) = I₀ · (1 − depth + depth · sin²(2π f t))`` with ``f = mains_hz``
  (50 or 60 Hz → 100 or 120 Hz flicker).  Key frames are spaced so that linear
  interpolation between them errs by at most ``tolerance`` of ``I₀``: the
  error bound ``h² · max|I''| / 8`` with ``max|I''| = 2 depth (2π f)² I₀``
  gives ``h = sqrt(4 · tolerance / depth) / (2π f)``.
* ``ColorChecker`` – the 24 patches of the X-Rite ColorChecker in linear sRGB
  (data from colour-science, see :mod:`spikesim.scenes.sources`) on a black
  surround, 4 rows × 6 columns.
"""

from __future__ import annotations

import math

import numpy as np

from spikesim.errors import bad_value
from spikesim.scenes.analytic import ProceduralScene, check_positive
from spikesim.scenes.sources import IMAGES, colorchecker_linear_srgb, load_image

__all__ = ["Flat", "Ramp", "Flicker", "ColorChecker", "check_level"]


def check_level(name: str, level: object) -> np.ndarray:
    """A radiance level: one number or three (R, G, B), finite and >= 0 → (3,) float32."""
    arr = np.asarray(level, dtype=np.float64) if not isinstance(level, str) else np.array([np.nan])
    if arr.ndim == 0:
        arr = np.repeat(arr[None], 3)
    if arr.shape != (3,) or not np.isfinite(arr).all() or (arr < 0).any():
        raise bad_value(name, level, "a finite number >= 0 or three of them (R, G, B)")
    return arr.astype(np.float32)


class Flat(ProceduralScene):
    """Uniform radiance ``level`` (linear, relative; one value or R, G, B)."""

    def __init__(self, size=(256, 256), *, level=0.5, max_px=1.0, exposure=1.0):
        super().__init__(size, exposure=exposure, max_px=max_px)
        self.name, self.motion = "flat", None
        self.level = check_level("level", level)
        self._img = np.broadcast_to(self.level, (self.height, self.width, 3)).copy()

    def _render(self, t):
        return self._img.copy()

    def _options(self):
        return {"level": [float(v) for v in self.level]}


class Ramp(ProceduralScene):
    """Horizontal ramp from ``low`` (left column) to ``high`` (right column)."""

    def __init__(self, size=(256, 256), *, low=0.0, high=1.0, log=False, max_px=1.0,
                 exposure=1.0):
        super().__init__(size, exposure=exposure, max_px=max_px)
        self.name, self.motion = "ramp", None
        low, high = float(check_level("low", low)[0]), float(check_level("high", high)[0])
        if high <= low:
            raise bad_value("high", high, f"> low={low}")
        if log and low <= 0:
            raise bad_value("low", low, "> 0 for a logarithmic ramp")
        self.low, self.high, self.log = low, high, bool(log)
        u = np.linspace(0.0, 1.0, self.width) if self.width > 1 else np.zeros(1)
        row = low * (high / low) ** u if log else low + (high - low) * u
        self._img = np.broadcast_to(row[None, :, None], (self.height, self.width, 3)).astype(
            np.float32)

    def _render(self, t):
        return self._img.copy()

    def _options(self):
        return {"low": self.low, "high": self.high, "log": self.log}


class Flicker(ProceduralScene):
    """A scene lit by a mains-powered lamp: brightness pulses at ``2 · mains_hz``."""

    def __init__(self, size=(256, 256), *, mains_hz=50.0, depth=0.5, base="flat", level=0.5,
                 tolerance=1e-3, max_px=1.0, exposure=1.0):
        super().__init__(size, exposure=exposure, max_px=max_px)
        self.name, self.motion = "flicker", "flicker"
        self.mains_hz = check_positive("mains_hz", mains_hz)
        depth = float(depth) if isinstance(depth, int | float) else math.nan
        if not 0 < depth <= 1:
            raise bad_value("depth", depth, "0 < depth <= 1")
        self.depth = depth
        self.tolerance = check_positive("tolerance", tolerance)
        if base == "flat":
            self._img = np.broadcast_to(check_level("level", level),
                                        (self.height, self.width, 3)).copy()
        elif base in IMAGES:
            self._img = load_image(base, (self.height, self.width))
        else:
            raise bad_value("base", base, f"'flat' or one of {sorted(IMAGES)}")
        self.base = base
        self.key_interval_s = math.sqrt(4 * self.tolerance / depth) / (2 * math.pi * self.mains_hz)

    def gain(self, t: float) -> float:
        """Relative brightness of the lamp at ``t`` seconds (1 at the peak)."""
        return 1 - self.depth + self.depth * math.sin(2 * math.pi * self.mains_hz * t) ** 2

    def _render(self, t):
        return self._img * np.float32(self.gain(t))

    def _options(self):
        return {"mains_hz": self.mains_hz, "depth": self.depth, "base": self.base,
                "tolerance": self.tolerance}


class ColorChecker(ProceduralScene):
    """X-Rite ColorChecker (24 patches, 4×6) in linear sRGB on a black surround."""

    def __init__(self, size=(256, 384), *, max_px=1.0, exposure=1.0):
        super().__init__(size, exposure=exposure, max_px=max_px)
        self.name, self.motion = "colorchecker", None
        if self.height < 8 or self.width < 12:
            raise bad_value("size", size, "at least (8, 12) pixels for a 4×6 chart")
        names, rgb = colorchecker_linear_srgb()
        self.patch_names = names
        img = np.zeros((self.height, self.width, 3), np.float32)
        ph, pw = self.height / 4, self.width / 6
        gap = 0.1
        for k in range(24):
            i, j = divmod(k, 6)
            r0, r1 = round((i + gap) * ph), round((i + 1 - gap) * ph)
            c0, c1 = round((j + gap) * pw), round((j + 1 - gap) * pw)
            img[r0:r1, c0:c1] = rgb[k]
        self._img = img

    def patch_centres(self) -> list[tuple[int, int]]:
        """(row, col) pixel at the centre of each patch, in chart order."""
        ph, pw = self.height / 4, self.width / 6
        return [(int((k // 6 + 0.5) * ph), int((k % 6 + 0.5) * pw)) for k in range(24)]

    def _render(self, t):
        return self._img.copy()
