"""Common machinery of procedural scenes: exact radiance at any time.

A procedural scene is a closed-form function of time.  Images enter it as a
*continuous* radiance field: the cubic B-spline that interpolates the texture
samples (Unser, "Splines: a perfect fit for signal and image processing",
IEEE Signal Processing Magazine 16(6), 1999), evaluated with
:func:`scipy.ndimage.map_coordinates` (order 3, prefiltered once).  The spline
passes exactly through the samples, so an integer-pixel displacement
reproduces the shifted texture exactly, and sub-pixel positions are evaluated
to floating-point precision of that continuous field.  Negative lobes of the
spline are clipped at 0 (radiance is non-negative).

Boundary handling: the texture is extended by mirror reflection into a
seamless periodic plane (period 2H × 2W: SciPy mode ``"reflect"``, the
half-sample symmetric extension, for the prefilter and the samples alike —
the same field as ``"grid-wrap"`` on the 2H × 2W mirrored tile, at a quarter
of the prefilter's cost), so any motion reveals mirrored copies of the
picture, never black borders or a seam.

Key frames: the simulator interpolates linearly between key frames, so each
moving scene sets ``key_interval_s = max_px / speed`` where ``speed`` is its
largest content speed in pixels per second; nothing then moves more than
``max_px`` pixels between key frames.
"""

from __future__ import annotations

from abc import abstractmethod

import numpy as np

from spikesim._validate import check_positive, check_size, check_time
from spikesim.scenes.base import Scene
from spikesim.scenes.video import as_video

__all__ = ["ProceduralScene", "SplineTexture"]


#: Shortest side prefiltered with SciPy's ``"reflect"`` mode (shorter: the mirrored tile).
_REFLECT_MIN_SIDE = 16


class SplineTexture:
    """Continuous (cubic B-spline) radiance field over a mirrored periodic texture.

    Coordinates are in texture pixels, pixel centres at integers, row 0 at the
    top.  ``mirror=False`` keeps the texture as is with edge values repeated
    (SciPy ``"nearest"``), used for small sprites that are masked anyway.
    """

    def __init__(self, image: np.ndarray, mirror: bool = True):
        from scipy import ndimage  # here, not at import: a worker making video clips never needs it

        img = np.asarray(image, dtype=np.float64)
        self.height, self.width = img.shape[:2]
        self.mirror = mirror
        self._mode = "reflect" if mirror else "nearest"
        if mirror and min(self.height, self.width) < _REFLECT_MIN_SIDE:
            # SciPy's "reflect" prefilter starts from a truncated boundary sum, exact to
            # 1e-15 only from 13 samples: short sides are tiled and wrapped instead
            img = np.concatenate([img, img[::-1]], axis=0)
            img = np.concatenate([img, img[:, ::-1]], axis=1)
            self._mode = "grid-wrap"
        self._coef = [
            ndimage.spline_filter(np.ascontiguousarray(img[..., c]), order=3, mode=self._mode)
            for c in range(3)
        ]
        # the spline overshoots at sharp edges (up to 13 % above full scale on the
        # astronaut's white suit): samples are clipped to the texture's own range
        self._range = [(max(float(img[..., c].min()), 0.0), float(img[..., c].max()))
                       for c in range(3)]

    def sample(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Radiance at (rows, cols) (same shape arrays) → shape + (3,) float32, within
        the texture's range per channel (no spline overshoot)."""
        from scipy import ndimage

        coords = np.stack([rows, cols])
        out = np.empty(rows.shape + (3,), np.float32)
        for c in range(3):
            out[..., c] = ndimage.map_coordinates(
                self._coef[c], coords, order=3, mode=self._mode, prefilter=False
            )
            np.clip(out[..., c], *self._range[c], out=out[..., c])
        return out


class ProceduralScene(Scene):
    """Base of procedural scenes: validated time, exposure, description, video rendering."""

    #: registry name and motion, set by subclasses/factory
    name: str = "procedural"
    motion: str | None = None

    def __init__(self, size: tuple[int, int], *, exposure: float = 1.0, max_px: float = 1.0):
        from spikesim.scenes.photometry import check_exposure

        self.height, self.width = check_size(size)
        self.exposure = check_exposure(exposure)
        self.max_px = check_positive("max_px", max_px)
        self.speed: float | None = None
        self.key_interval_s = None

    def _set_speed(self, speed: float | None) -> None:
        """Largest content speed (px/s) → key interval ``max_px / speed`` seconds."""
        self.speed = speed
        self.key_interval_s = None if speed is None else self.max_px / speed

    @abstractmethod
    def _render(self, t: float) -> np.ndarray:
        """(H, W, 3) float32 radiance at ``t`` seconds before exposure scaling."""

    def _options(self) -> dict:
        return {}

    def radiance(self, t: float) -> np.ndarray:
        """Exact linear radiance (H, W, 3) float32 at time ``t`` seconds."""
        out = self._render(check_time(t))
        if self.exposure != 1.0:
            out = out * np.float32(self.exposure)
        return np.ascontiguousarray(out, dtype=np.float32)

    def describe(self) -> dict:
        return {
            "type": "procedural",
            "name": self.name,
            "motion": self.motion,
            "height": self.height,
            "width": self.width,
            "speed_px_s": self.speed,
            "max_px": self.max_px,
            "key_interval_s": self.key_interval_s,
            "exposure": self.exposure,
            **self._options(),
        }

    def as_video(self, fps: float, n_frames: int, **kwargs):
        """Render this scene as a video of ``n_frames`` at ``fps`` (see ``video.as_video``)."""
        return as_video(self, fps, n_frames, **kwargs)

    def __repr__(self) -> str:
        return (
            f"procedural({self.name!r}, motion={self.motion!r}, "
            f"size=({self.height}, {self.width}), speed={self.speed!r})"
        )
