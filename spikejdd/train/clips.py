"""Video clips as training scenes, with their key frames cached per process.

A clip (a video file or a frame folder, opened by ``spikesim.scenes.video``)
becomes a scene through optical-flow key frames, which are costly; one
:class:`~spikesim.scenes.video.VideoScene` per clip is kept per process
(:func:`clip_scene`, an LRU of :data:`CACHE_CLIPS` clips) so its frames, flows
and interpolated key frames (the scene's own LRU caches) serve many samples.
:class:`ClipWindow` cuts a sample out of it: a crop box, a start on one of
the clip's frames and a playback ``rate`` (scene time ``t`` shows clip time
``t0 + rate·t``; ``rate = 0`` holds the frame still), so the same clip gives
static, slow and fast samples.
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np

from spikesim.errors import bad_value
from spikesim.scenes.base import Scene

__all__ = ["ClipWindow", "clip_scene", "draw_clip", "CACHE_CLIPS"]

#: Clips whose VideoScene (and key-frame caches) a process keeps.
CACHE_CLIPS = 4
#: Shorter side (pixels) clips are resized to when larger (flow cost).
MAX_SIDE = 256
_CACHE: OrderedDict = OrderedDict()


def clip_scene(path: str):
    """The cached :class:`~spikesim.scenes.video.VideoScene` of clip ``path``."""
    from spikesim.scenes.video import video

    if path in _CACHE:
        _CACHE.move_to_end(path)
        return _CACHE[path]
    scene = video(path)
    side = min(scene.height, scene.width)
    if side > MAX_SIDE:
        size = (round(scene.height * MAX_SIDE / side), round(scene.width * MAX_SIDE / side))
        scene = video(path, resize=size)
    _CACHE[path] = scene
    while len(_CACHE) > CACHE_CLIPS:
        _CACHE.popitem(last=False)
    return scene


class ClipWindow(Scene):
    """``base`` seen through ``box`` = (top, left, height, width) from clip time ``t0``
    (seconds, one of the clip's frame times) at playback ``rate`` (≥ 0)."""

    def __init__(self, base, box: tuple[int, int, int, int], t0: float, rate: float):
        top, left, h, w = (int(v) for v in box)
        if top < 0 or left < 0 or top + h > base.height or left + w > base.width:
            raise bad_value("box", box, f"a box inside the {base.height}x{base.width} clip")
        if not rate >= 0:
            raise bad_value("rate", rate, "a playback rate >= 0")
        self.base, self.box, self.t0, self.rate = base, (top, left, h, w), float(t0), float(rate)
        self.height, self.width = h, w
        self.key_interval_s = None if self.rate == 0 else base.key_interval_s / self.rate

    def key_times(self, start_s: float, stop_s: float) -> np.ndarray:
        if self.rate == 0:
            return np.zeros(1, np.float64)
        k = self.base.key_times(self.t0 + self.rate * start_s, self.t0 + self.rate * stop_s)
        return np.maximum((np.asarray(k, np.float64) - self.t0) / self.rate, 0.0)

    def radiance(self, t: float) -> np.ndarray:
        top, left, h, w = self.box
        full = self.base.radiance(self.t0 + self.rate * float(t))
        return np.ascontiguousarray(full[top:top + h, left:left + w], dtype=np.float32)

    def describe(self) -> dict:
        return {"type": "clip-window", "clip": self.base.describe(), "box": list(self.box),
                "t0": self.t0, "rate": self.rate}


def draw_clip(rng: np.random.Generator, clips, size: tuple[int, int]):
    """A :class:`ClipWindow` of a random clip and its description: still (rate 0), slowed
    (rate U(0, 1)) or sped up (rate 2^U(2, 6)) with the probabilities of the speed bins."""
    from spikejdd.train.scenes import draw_speed

    path = str(clips[int(rng.integers(len(clips)))])
    base = clip_scene(path)
    h, w = size
    if base.height < h or base.width < w:
        raise bad_value("clips", path, f"clips of at least {h}x{w} pixels")
    top = int(rng.integers(0, base.height - h + 1))
    left = int(rng.integers(0, base.width - w + 1))
    frame = int(rng.integers(0, max(1, base.n_frames - 1)))
    speed_bin, _ = draw_speed(rng)
    rate = {"static": 0.0, "slow": float(rng.uniform(0.0, 1.0))}.get(
        speed_bin, float(2.0 ** rng.uniform(2.0, 6.0)))
    scene = ClipWindow(base, (top, left, h, w), frame / base.fps, rate)
    return scene, {"kind": "clip", "content": [path], "motion": "video",
                   "speed_bin": speed_bin, "speed_px_s": float("nan"), "rate": rate}
