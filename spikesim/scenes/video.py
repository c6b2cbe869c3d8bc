"""Video as a scene: lazy frames, linear light, adaptive flow-interpolated key frames.

Frame ``i`` of the (selected part of the) video is the radiance at time
``i / fps`` seconds (frames are treated as instants).  Between frames ``i`` and
``i+1`` the scene inserts ``m_i`` intermediate key frames, equally spaced,
made by optical-flow interpolation (:mod:`spikesim.motion`), with
``m_i = ceil(D_i / max_px) − 1`` for the largest displacement ``D_i`` of the
pair, so that nothing moves more than ``max_px`` pixels between key frames;
a static pair gets none and no flow.  :meth:`VideoScene.key_times` lists the
frame times and those intermediate times; :meth:`VideoScene.radiance` returns
the key frame at a key time and the linear blend of the two neighbouring key
frames in between — exactly what the simulator integrates, so ground truth
and spikes agree.  After the last frame the last frame is held (key times
continue every ``1 / fps``).

Flow is computed once per frame pair and kept in a small LRU cache (pairs of
the current chunk); decoded frames and key frames are cached the same way.
"""

from __future__ import annotations

import math
import os
import time
from collections import OrderedDict

import cv2
import numpy as np

from spikesim.errors import bad_value
from spikesim.motion import DEFAULT_FLOW, PairMotion, analyse_pair, check_method, interpolate
from spikesim.motion import n_intermediate as _n_intermediate
from spikesim.scenes.analytic import check_positive, check_time
from spikesim.scenes.base import Scene
from spikesim.scenes.photometry import check_exposure, decode_frame
from spikesim.scenes.readers import FrameSource, SceneSource, VideoFileSource, open_source

__all__ = ["VideoScene", "video", "as_video", "DEFAULT_MAX_PX", "DEFAULT_FOLDER_FPS"]

#: Default largest displacement between key frames, pixels.
DEFAULT_MAX_PX = 1.0
#: Frame rate assumed for image folders when ``fps`` is not given (REDS and DAVIS are 24 fps).
DEFAULT_FOLDER_FPS = 24.0


class _LRU(OrderedDict):
    def __init__(self, size: int = 4):
        super().__init__()
        self.size = size

    def get_or(self, key, make):
        if key in self:
            self.move_to_end(key)
            return self[key]
        value = make()
        self[key] = value
        if len(self) > self.size:
            self.popitem(last=False)
        return value


def _check_box(name: str, value, n: int, allowed: str) -> tuple[int, ...] | None:
    if value is None:
        return None
    try:
        out = tuple(int(v) for v in value)
        ok = len(out) == n and all(int(v) == v for v in value)
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise bad_value(name, value, allowed)
    return out


class VideoScene(Scene):
    """A frame source as a scene (see the module docstring).

    Parameters
    ----------
    source : FrameSource
        Lazy frames (:mod:`spikesim.scenes.readers`).
    fps : float, optional
        Frame rate in frames per second (> 0).  Default: the file's own rate,
        or :data:`DEFAULT_FOLDER_FPS` for image folders.
    resize : (H, W), optional
        Output size in pixels (after cropping), resampled in linear light
        (area averaging when shrinking, bicubic when enlarging).  Default: no resize.
    crop : (top, left, height, width), optional
        Region of the stored frame to keep, in stored pixels.  Default: all.
    start_s, stop_s : float
        Time range of the video to use, seconds of video time (frames with
        ``start_s <= i / fps <= stop_s``); default the whole video.  Scene time
        0 is the first frame kept.
    linear : bool
        Frames already hold linear light (default ``False``: decode sRGB).
    exposure : float
        Dimensionless scale of the decoded radiance (default 1).
    max_px : float
        Largest displacement between consecutive key frames, pixels (default 1).
    flow : str
        Optical-flow method, a key of :data:`spikesim.motion.FLOW_METHODS`.
    occlusion : bool
        Visibility-weighted blending (default ``True``).
    static_tol : float
        Pairs whose 8-bit sRGB luma differs by at most this many code values
        everywhere are static (default 1).
    max_intermediate : int
        Cap on intermediate key frames per pair (default 64).
    cache_pairs : int
        Frame pairs whose flow is kept in memory (default 8; about 18 bytes
        per pixel per pair).
    shared_flows : dict, optional
        A dict (frame index → :class:`~spikesim.motion.PairMotion`) kept by the
        caller and shared between scenes over the *same frames and flow
        method*, e.g. to try several ``max_px`` without recomputing flow.
    """

    def __init__(
        self,
        source: FrameSource,
        fps: float | None = None,
        *,
        resize: tuple[int, int] | None = None,
        crop: tuple[int, int, int, int] | None = None,
        start_s: float = 0.0,
        stop_s: float | None = None,
        linear: bool | None = None,
        exposure: float = 1.0,
        max_px: float = DEFAULT_MAX_PX,
        flow: str = DEFAULT_FLOW,
        occlusion: bool = True,
        static_tol: float = 1.0,
        max_intermediate: int = 64,
        cache_pairs: int = 8,
        shared_flows: dict | None = None,
    ):
        self.source = source
        if fps is None:
            if source.native_fps:
                fps = source.native_fps
            elif isinstance(source, VideoFileSource):
                raise bad_value("fps", fps, f"a frame rate > 0: {source.name} states none")
            else:
                fps = DEFAULT_FOLDER_FPS
        self.fps = check_positive("fps", fps)
        self.linear = bool(source.linear) if linear is None else bool(linear)
        self.exposure = check_exposure(exposure)
        self.max_px = check_positive("max_px", max_px)
        self.flow = check_method(flow)
        self.occlusion = bool(occlusion)
        self.static_tol = float(static_tol)
        if not math.isfinite(self.static_tol) or self.static_tol < 0:
            raise bad_value("static_tol", static_tol, "a finite number >= 0 (8-bit code values)")
        if not isinstance(max_intermediate, int) or max_intermediate < 0:
            raise bad_value("max_intermediate", max_intermediate, "an integer >= 0")
        self.max_intermediate = max_intermediate
        self.crop = _check_box("crop", crop, 4, "(top, left, height, width) integers")
        if self.crop is not None:
            top, left, ch, cw = self.crop
            if top < 0 or left < 0 or ch < 1 or cw < 1 or top + ch > source.height or (
                    left + cw > source.width):
                raise bad_value("crop", crop, f"a box inside the {source.height}x{source.width} "
                                "frame with height, width >= 1")
        self.resize = _check_box("resize", resize, 2, "(H, W) integers >= 1")
        if self.resize is not None and min(self.resize) < 1:
            raise bad_value("resize", resize, "(H, W) integers >= 1")
        start_s = check_time(start_s)
        first = max(0, math.ceil(start_s * self.fps - 1e-9))
        last = source.n_frames - 1
        if stop_s is not None:
            last = min(last, math.floor(check_time(stop_s) * self.fps + 1e-9))
        self.start_s, self.stop_s = start_s, stop_s
        self._first = first
        self.n_frames = last - first + 1
        if self.n_frames < 2:
            raise bad_value(
                "video", source.name,
                f"at least 2 frames in the selected range (got {max(self.n_frames, 0)})")
        if self.resize is not None:
            self.height, self.width = self.resize
        elif self.crop is not None:
            self.height, self.width = self.crop[2], self.crop[3]
        else:
            self.height, self.width = source.height, source.width
        self.key_interval_s = 1.0 / self.fps
        self._frames = _LRU(max(3, cache_pairs + 1))
        self._pairs = _LRU(max(1, cache_pairs))
        self._keys = _LRU(8)
        self._counts: dict[int, int] = {}
        self._shared = shared_flows
        self.stats = {"pairs": 0, "static_pairs": 0, "flow_s": 0.0, "interp_s": 0.0,
                      "key_frames": 0}

    # -- frames and pairs ---------------------------------------------------------------
    @property
    def is_static(self) -> bool:
        return False

    def frame(self, i: int) -> np.ndarray:
        """Linear radiance (H, W, 3) float32 of frame ``i`` (0-based, within the range)."""
        if not 0 <= i < self.n_frames:
            raise bad_value("frame index", i, f"0..{self.n_frames - 1}")
        return self._frames.get_or(i, lambda: self._load(i))

    def _load(self, i: int) -> np.ndarray:
        raw = self.source.read(self._first + i)
        if self.crop is not None:
            top, left, ch, cw = self.crop
            raw = raw[top : top + ch, left : left + cw]
        img = decode_frame(raw, linear=self.linear, exposure=self.exposure,
                           name=f"frame {self._first + i} of {self.source.name}")
        if self.resize is not None and img.shape[:2] != tuple(self.resize):
            h, w = self.resize
            shrink = h < img.shape[0] or w < img.shape[1]
            img = cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA if shrink
                             else cv2.INTER_CUBIC)
            img = np.clip(img, 0.0, None)
        img = np.ascontiguousarray(img, np.float32)
        img.setflags(write=False)
        return img

    def pair(self, i: int) -> PairMotion:
        """Motion between frames ``i`` and ``i + 1`` (computed once, cached)."""
        def make() -> PairMotion:
            if self._shared is not None and i in self._shared:
                p = self._shared[i]
            else:
                p = analyse_pair(self.frame(i), self.frame(i + 1), self.flow, self.static_tol)
                self.stats["pairs"] += 1
                self.stats["static_pairs"] += int(p.static)
                self.stats["flow_s"] += p.seconds
                if self._shared is not None:
                    self._shared[i] = p
            self._counts[i] = 0 if p.static else _n_intermediate(
                p.max_disp, self.max_px, self.max_intermediate)
            return p

        return self._pairs.get_or(i, make)

    def n_intermediate(self, i: int) -> int:
        """Number of intermediate key frames between frames ``i`` and ``i + 1``."""
        if not 0 <= i < self.n_frames - 1:
            raise bad_value("pair index", i, f"0..{self.n_frames - 2}")
        if i not in self._counts:
            self.pair(i)
        return self._counts[i]

    def key_frame(self, i: int, j: int) -> np.ndarray:
        """Key frame ``j`` (0 = frame ``i``, ``m+1`` = frame ``i+1``) of pair ``i``."""
        m = self.n_intermediate(i)
        if j == 0:
            return self.frame(i)
        if j == m + 1:
            return self.frame(i + 1)

        def make() -> np.ndarray:
            t0 = time.perf_counter()
            out = interpolate(self.frame(i), self.frame(i + 1), self.pair(i), j / (m + 1),
                              occlusion=self.occlusion)
            self.stats["interp_s"] += time.perf_counter() - t0
            self.stats["key_frames"] += 1
            out.setflags(write=False)
            return out

        return self._keys.get_or((i, j), make)

    # -- scene protocol -----------------------------------------------------------------
    def key_times(self, start_s: float, stop_s: float) -> np.ndarray:
        """Frame times and adaptive intermediate times bracketing ``[start_s, stop_s]``."""
        start_s, stop_s = check_time(start_s), check_time(stop_s)
        last = self.n_frames - 1
        i0 = min(max(0, math.floor(start_s * self.fps)), last)
        i1 = max(i0, math.ceil(stop_s * self.fps))
        times = []
        for i in range(i0, min(i1, last)):
            m = self.n_intermediate(i)
            times.extend((i + j / (m + 1)) / self.fps for j in range(m + 1))
        times.extend(k / self.fps for k in range(min(i1, last), i1 + 1))
        t = np.asarray(times, np.float64)
        lo = max(0, int(np.searchsorted(t, start_s, side="right")) - 1)
        hi = int(np.searchsorted(t, stop_s, side="left")) + 1
        return t[lo:hi]

    def radiance(self, t: float) -> np.ndarray:
        """Key frame at a key time, linear blend of the neighbouring key frames between."""
        pos = check_time(t) * self.fps
        if pos <= 0:
            return self.frame(0)
        if pos >= self.n_frames - 1:
            return self.frame(self.n_frames - 1)
        i = min(int(math.floor(pos)), self.n_frames - 2)
        m = self.n_intermediate(i)
        q = (pos - i) * (m + 1)
        j = min(int(math.floor(q)), m)
        frac = q - j
        if frac < 1e-6:
            return self.key_frame(i, j)
        if frac > 1 - 1e-6:
            return self.key_frame(i, j + 1)
        a, b = self.key_frame(i, j), self.key_frame(i, j + 1)
        return ((1 - frac) * a + frac * b).astype(np.float32)

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        for name in ("_frames", "_pairs", "_keys"):  # caches are not shipped to workers
            state[name] = _LRU(state[name].size)
        return state

    def describe(self) -> dict:
        src = self.source
        out = {
            "type": "video",
            "source": src.name,
            "height": self.height,
            "width": self.width,
            "fps": self.fps,
            "n_frames": self.n_frames,
            "first_frame": self._first,
            "start_s": self.start_s,
            "stop_s": self.stop_s,
            "crop": list(self.crop) if self.crop else None,
            "resize": list(self.resize) if self.resize else None,
            "linear": self.linear,
            "exposure": self.exposure,
            "max_px": self.max_px,
            "flow": self.flow,
            "occlusion": self.occlusion,
            "static_tol": self.static_tol,
            "max_intermediate": self.max_intermediate,
        }
        if isinstance(src, SceneSource):
            out["rendered_from"] = src.scene.describe()
            out["srgb8"] = src.srgb8
        return out

    def __repr__(self) -> str:
        return (f"VideoScene({self.source.name!r}, fps={self.fps}, {self.n_frames} frames, "
                f"{self.height}x{self.width}, flow={self.flow!r}, max_px={self.max_px})")


def video(
    path: str | os.PathLike,
    fps: float | None = None,
    *,
    sequence: str | None = None,
    layout: str = "auto",
    **options,
) -> VideoScene:
    """Open a video file or frame folder as a scene.

    ``layout`` and ``sequence`` select the reader (:mod:`spikesim.scenes.readers`:
    a video file, REDS ``<root>/<sequence>/%08d.png``, DAVIS
    ``<root>/JPEGImages/480p/<sequence>/%05d.jpg``, or any sorted image folder);
    the other keywords are those of :class:`VideoScene` (``resize``, ``crop``,
    ``start_s``, ``stop_s``, ``linear``, ``exposure``, ``max_px``, ``flow``, ...).
    Frames are decoded lazily.
    """
    if fps is not None:
        check_positive("fps", fps)
    return VideoScene(open_source(path, layout=layout, sequence=sequence), fps, **options)


def as_video(scene: Scene, fps: float, n_frames: int, *, srgb8: bool = False,
             **options) -> VideoScene:
    """Render ``scene`` as a video of ``n_frames`` frames at ``fps`` (frame i at t = i / fps).

    Frames are rendered lazily as linear float (``srgb8=True``: quantised to
    8-bit sRGB like a real video file and decoded back), and the result is a
    :class:`VideoScene` whose interpolation can be scored against
    ``scene.radiance`` between its frames.  ``options`` go to :class:`VideoScene`.
    """
    fps = check_positive("fps", fps)
    if not isinstance(n_frames, int) or n_frames < 2:
        raise bad_value("n_frames", n_frames, "an integer >= 2")
    return VideoScene(SceneSource(scene, fps, n_frames, srgb8=srgb8), fps, **options)
