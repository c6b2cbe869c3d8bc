"""A scene given by explicit key frames at arbitrary times (linear in between)."""

from __future__ import annotations

import numpy as np

from spikesim.errors import bad_value
from spikesim.scenes.base import Scene
from spikesim.scenes.static import validate_radiance

__all__ = ["Keyframes"]


class Keyframes(Scene):
    """Radiance linear in time between images given at ``times_s``; held outside.

    Parameters
    ----------
    times_s : sequence of float
        Strictly increasing times in seconds (any values, not tied to the clock).
    images : sequence of (H, W) or (H, W, 3) arrays
        Linear radiance at each time, relative units.
    """

    def __init__(self, times_s, images):
        t = np.asarray(times_s, dtype=np.float64).ravel()
        if t.size == 0 or not np.all(np.isfinite(t)):
            raise bad_value("times_s", times_s, "one or more finite times in seconds")
        if t.size > 1 and not np.all(np.diff(t) > 0):
            raise bad_value("times_s", t.tolist()[:8], "strictly increasing times (in order)")
        if len(images) != t.size:
            raise bad_value("images", f"{len(images)} images", f"one per time ({t.size})")
        frames = [validate_radiance(im, f"images[{i}]") for i, im in enumerate(images)]
        shapes = {f.shape for f in frames}
        if len(shapes) != 1:
            raise bad_value("images shapes", sorted(shapes), "one common (H, W, 3) shape")
        self._t = t
        self._frames = np.stack(frames)
        self._frames.setflags(write=False)
        self.height, self.width = frames[0].shape[:2]

    @property
    def is_static(self) -> bool:
        return self._t.size == 1

    def key_times(self, start_s: float, stop_s: float) -> np.ndarray:
        t = self._t
        lo = max(0, int(np.searchsorted(t, start_s, side="right")) - 1)
        hi = min(t.size, int(np.searchsorted(t, stop_s, side="left")) + 1)
        return t[lo:hi].copy()

    def radiance(self, t: float) -> np.ndarray:
        times = self._t
        if t <= times[0]:
            return self._frames[0]
        if t >= times[-1]:
            return self._frames[-1]
        j = int(np.searchsorted(times, t, side="right")) - 1
        f = (t - times[j]) / (times[j + 1] - times[j])
        a = self._frames[j].astype(np.float64)
        return (a + (self._frames[j + 1] - a) * f).astype(np.float32)

    def describe(self) -> dict:
        return {"type": "keyframes", "height": self.height, "width": self.width,
                "times_s": self._t.tolist()}
