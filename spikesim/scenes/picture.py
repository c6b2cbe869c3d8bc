"""A bundled photograph moved along an analytic camera path (pan, rotation, ...).

Radiance at time ``t`` is the continuous spline field of the picture (see
:mod:`spikesim.scenes.analytic`) seen through the inverse of the path matrix
``M(rate · t)`` (:mod:`spikesim.scenes.paths`): output pixel ``x`` shows texture
point ``M⁻¹ x``.  Pixels are point samples of that field at their centres.
"""

from __future__ import annotations

import numpy as np

from spikesim._validate import check_positive
from spikesim.scenes.analytic import ProceduralScene, SplineTexture
from spikesim.scenes.paths import MOTIONS, make_path, peak_speed
from spikesim.scenes.sources import load_image

__all__ = ["MovingPicture"]


class MovingPicture(ProceduralScene):
    """Photograph ``image`` under camera ``motion`` at peak content ``speed`` (px/s).

    Parameters
    ----------
    image : str
        Name of a bundled picture (``spikesim.scenes.sources.IMAGES``).
    motion : str
        One of :data:`spikesim.scenes.paths.MOTIONS`.
    size : (H, W)
        Output size in pixels; the picture is cover-resized to it.
    speed : float
        Largest content speed anywhere in the frame, pixels per second
        (ignored for ``"static"``).
    direction_deg : float
        Pan direction in degrees (0 = content moves right, 90 = down).
    max_px : float
        Largest displacement between key frames, pixels.
    exposure : float
        Scale of the linear radiance.
    """

    def __init__(
        self,
        image: str,
        motion: str = "pan",
        size: tuple[int, int] = (256, 256),
        speed: float | None = 500.0,
        *,
        direction_deg: float = 0.0,
        max_px: float = 1.0,
        exposure: float = 1.0,
    ):
        super().__init__(size, exposure=exposure, max_px=max_px)
        self.name = image
        self.motion = motion
        self.direction_deg = float(direction_deg)
        self._path, _ = make_path(motion, self.height, self.width, self.direction_deg)
        self._picture = load_image(image, (self.height, self.width))
        # (a still picture is its own radiance: no spline to prefilter)
        self._texture = None if motion == "static" else SplineTexture(self._picture)
        if motion == "static":
            self.rate = 0.0
            self._set_speed(None)
        else:
            speed = check_positive("speed", speed)
            self.rate = speed / peak_speed(motion, self.height, self.width, self.direction_deg)
            self._set_speed(speed)
        rows, cols = np.mgrid[0 : self.height, 0 : self.width].astype(np.float64)
        self._grid = np.stack([cols.ravel(), rows.ravel(), np.ones(rows.size)])

    def matrix(self, t: float) -> np.ndarray:
        """Forward 3×3 map texture → output at time ``t`` seconds."""
        return self._path(self.rate * t)

    def _render(self, t: float) -> np.ndarray:
        if self.motion == "static":
            return self._picture.copy()
        src = np.linalg.solve(self.matrix(t), self._grid)
        cols = (src[0] / src[2]).reshape(self.height, self.width)
        rows = (src[1] / src[2]).reshape(self.height, self.width)
        return self._texture.sample(rows, cols)

    def _options(self) -> dict:
        return {"image": self.name, "direction_deg": self.direction_deg, "rate": self.rate}

    @staticmethod
    def motions() -> dict[str, str]:
        return dict(MOTIONS)

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        del state["_path"]  # a closure; rebuilt on unpickling (spawned workers)
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._path, _ = make_path(self.motion, self.height, self.width, self.direction_deg)
