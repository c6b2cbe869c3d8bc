"""The scene protocol every light source implements.

A scene is a function of time giving **linear-light radiance**, relative units,
nominally 0..1 per channel (docs/model.md).  The simulator asks a scene for

* ``height``, ``width``: image size in pixels;
* ``radiance(t)``: (H, W, 3) float32 radiance at time ``t`` seconds;
* ``key_times(start_s, stop_s)``: the times (seconds, sorted) at which the
  simulator samples ``radiance`` and between which it interpolates linearly.
  The grid must be *global* (it may not depend on ``start_s``/``stop_s`` other
  than by selecting from it), so that chunked simulation gives the same bits as
  one pass; the returned times must bracket the interval: the last key time
  ``<= start_s`` (if any) and the first ``>= stop_s`` (if any) are included;
* ``describe()``: a JSON-able dict that records what the scene is;
* optionally ``grey(t)``: the radiance at ``t`` as one (H, W) float32 channel
  when all three channels are equal (a grey scene), else ``None``.  The
  simulator then samples that channel directly instead of a three-channel
  copy (same bits, a third of the memory traffic).

:class:`Scene` gives a default ``key_times`` on a uniform grid of
``key_interval_s`` seconds; a static scene returns a single key at t = 0.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod

import numpy as np

from spikesim.errors import bad_value

__all__ = ["Scene", "uniform_key_times"]


def uniform_key_times(start_s: float, stop_s: float, interval_s: float) -> np.ndarray:
    """Key times ``k * interval_s`` (k ≥ 0 integer) bracketing ``[start_s, stop_s]``."""
    if not interval_s > 0:
        raise bad_value("key_interval_s", interval_s, "> 0 seconds")
    first = max(0, math.floor(start_s / interval_s))
    last = max(first, math.ceil(stop_s / interval_s))
    return np.arange(first, last + 1, dtype=np.float64) * interval_s


class Scene(ABC):
    """Base class of scenes; subclasses set ``height``, ``width`` and
    ``key_interval_s`` and implement ``radiance`` and ``describe``, and may
    offer ``grey`` (the protocol: this module's docstring)."""

    height: int
    width: int
    #: Spacing of key frames in seconds for the default ``key_times``; ``None``
    #: means the scene does not change with time (one key frame).
    key_interval_s: float | None = None

    @property
    def is_static(self) -> bool:
        return self.key_interval_s is None

    @abstractmethod
    def radiance(self, t: float) -> np.ndarray:
        """(H, W, 3) float32 linear radiance at time ``t`` seconds."""

    @abstractmethod
    def describe(self) -> dict:
        """A JSON-able record of what the scene is."""

    def grey(self, t: float) -> np.ndarray | None:
        """(H, W) float32 radiance at ``t`` when the three channels are equal,
        else ``None`` (the default: the simulator uses :meth:`radiance`)."""
        return None

    def key_times(self, start_s: float, stop_s: float) -> np.ndarray:
        if self.key_interval_s is None:
            return np.zeros(1, np.float64)
        return uniform_key_times(start_s, stop_s, self.key_interval_s)
