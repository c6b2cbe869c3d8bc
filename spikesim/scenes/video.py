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

**Crop first.**  With ``crop`` the scene decodes, analyses and warps only the
crop plus a ``margin`` of surrounding pixels (clipped to the frame), so motion
that enters the crop from outside is interpolated as it is in the full frame,
and cuts the crop out of the result afterwards; the key-frame count follows
the motion inside the crop only.  ``start_s`` may fall between frames: scene
time 0 is video time ``start_s`` exactly.  :meth:`VideoScene.motion_stats`
reports the measured motion inside the output (pixels per second: median,
95th percentile and maximum over the pairs analysed so far).

Flow is computed once per frame pair and kept in a small LRU cache (pairs of
the current chunk); decoded frames and key frames are cached the same way.
"""

from __future__ import annotations

import math
import os
import time
import warnings
from collections import OrderedDict

import numpy as np

from spikesim._validate import check_positive, check_time
from spikesim.errors import bad_value
from spikesim.motion import (
    DEFAULT_FLOW,
    PairMotion,
    analyse_pair,
    check_method,
    interpolate,
    sq_norm,
)
from spikesim.motion import n_intermediate as _n_intermediate
from spikesim.scenes.base import Scene
from spikesim.scenes.photometry import check_exposure, decode_frame
from spikesim.scenes.readers import FrameSource, SceneSource, VideoFileSource, open_frames
from spikesim.scenes.sources import resize_linear

__all__ = ["VideoScene", "video", "as_video", "AspectWarning", "VideoEndWarning",
           "aspect_change", "DEFAULT_MAX_PX", "DEFAULT_FOLDER_FPS", "DEFAULT_MARGIN"]

#: Default largest displacement between key frames, pixels.
DEFAULT_MAX_PX = 1.0
#: Pixels (stored) around a crop that flow and warping see by default.
DEFAULT_MARGIN = 48
#: Every ``_MOTION_STEP``-th pixel (each axis) of the output enters the motion statistics.
_MOTION_STEP = 2
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


class AspectWarning(UserWarning):
    """``resize`` changes the aspect ratio of the (cropped) frames: content is squashed."""


class VideoEndWarning(UserWarning):
    """More time is simulated than the video lasts: the rest holds its last frame."""


#: Relative change of the aspect ratio above which :class:`AspectWarning` is given.
ASPECT_TOLERANCE = 0.02


def aspect_change(size, frame) -> float:
    """Relative change of the aspect ratio when ``frame`` = (H, W) is resized to
    ``size`` (0: kept; squashed beyond :data:`ASPECT_TOLERANCE`)."""
    (h, w), (fh, fw) = size, frame
    return (h / w) / (fh / fw) - 1.0


def _warn_aspect(resize, frame) -> None:
    (h, w), (fh, fw) = resize, frame
    change = aspect_change(resize, frame)
    if abs(change) > ASPECT_TOLERANCE:
        warnings.warn(
            f"resize=({h}, {w}) squashes the {fh}x{fw} frames (aspect ratio changed by "
            f"{100 * change:+.0f} %); to keep the content's shape give a size of the "
            "frames' aspect, or crop a box of the target aspect first (crop= of "
            "spikesim.scenes.video, crop.size in a dataset manifest)", AspectWarning,
            stacklevel=4)


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
    margin : int, optional
        Stored pixels around ``crop`` that flow and warping also see (clipped
        to the frame; default :data:`DEFAULT_MARGIN`).  Motion of up to about
        this many pixels per frame pair across the crop border is interpolated
        as in the full frame.  Ignored without ``crop``.
    start_s, stop_s : float
        Time range of the video to use, seconds of video time; default the
        whole video.  Scene time 0 is video time ``start_s`` (which may fall
        between two frames); frames with ``start_s - 1/fps < i / fps <= stop_s``
        are kept.
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
        margin: int | None = None,
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
        if margin is None:
            margin = DEFAULT_MARGIN
        if isinstance(margin, bool) or not isinstance(margin, (int, np.integer)) or margin < 0:
            raise bad_value("margin", margin, "an integer >= 0 (stored pixels)")
        self.margin = int(margin)
        self._region, self._inner = self._work_boxes()
        start_s = check_time(start_s)
        if start_s < 0:
            raise bad_value("start_s", start_s, "a time >= 0 seconds")
        pos = start_s * self.fps
        first = math.floor(pos + 1e-9)
        # scene time t is at local frame position t * fps + offset
        self._offset = 0.0 if pos - first < 1e-9 else pos - first
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
            _warn_aspect(self.resize, self.crop[2:] if self.crop else
                         (source.height, source.width))
            self.height, self.width = self.resize
        elif self.crop is not None:
            self.height, self.width = self.crop[2], self.crop[3]
        else:
            self.height, self.width = source.height, source.width
        self.key_interval_s = 1.0 / self.fps
        self._warned_end = False
        self._frames = _LRU(max(3, cache_pairs + 1))
        self._pairs = _LRU(max(1, cache_pairs))
        self._keys = _LRU(8)
        self._counts: dict[int, int] = {}
        self._motion: dict[int, np.ndarray] = {}  # pair -> output px per frame interval
        self._shared = shared_flows
        self.stats = {"pairs": 0, "static_pairs": 0, "flow_s": 0.0, "interp_s": 0.0,
                      "key_frames": 0}

    def _work_boxes(self):
        """(region, inner): the stored box decoded and analysed (crop + margin,
        clipped; None = whole frame) and the crop inside it (None = all of it)."""
        if self.crop is None:
            return None, None
        top, left, ch, cw = self.crop
        m = self.margin
        r0, c0 = max(0, top - m), max(0, left - m)
        r1 = min(self.source.height, top + ch + m)
        c1 = min(self.source.width, left + cw + m)
        return (r0, c0, r1 - r0, c1 - c0), (top - r0, left - c0, ch, cw)

    @property
    def _scale(self) -> float:
        """Output pixels per analysed pixel (largest of the two axes)."""
        if self.crop is None or self.resize is None:
            return 1.0
        return max(self.resize[0] / self.crop[2], self.resize[1] / self.crop[3])

    # -- frames and pairs ---------------------------------------------------------------
    @property
    def is_static(self) -> bool:
        return False

    def frame(self, i: int) -> np.ndarray:
        """Linear radiance (H, W, 3) float32 of frame ``i`` (0-based, within the range)."""
        if not 0 <= i < self.n_frames:
            raise bad_value("frame index", i, f"0..{self.n_frames - 1}")
        if self._region is None:
            return self._work(i)
        return self._keys.get_or((i, -1), lambda: self._output(self._work(i)))

    def _work(self, i: int) -> np.ndarray:
        """Frame ``i`` as analysed: the whole (resized) frame, or crop + margin."""
        return self._frames.get_or(i, lambda: self._load(i))

    def _load(self, i: int) -> np.ndarray:
        raw = self.source.read(self._first + i)
        if self._region is not None:
            top, left, rh, rw = self._region
            raw = raw[top : top + rh, left : left + rw]
        img = decode_frame(raw, linear=self.linear, exposure=self.exposure,
                           name=f"frame {self._first + i} of {self.source.name}")
        if self._region is None:
            img = self._resized(img)
        img = np.ascontiguousarray(img, np.float32)
        img.setflags(write=False)
        return img

    def _resized(self, img: np.ndarray) -> np.ndarray:
        return img if self.resize is None else resize_linear(img, self.resize)

    def _output(self, work: np.ndarray) -> np.ndarray:
        """The output image of an analysed one: the crop cut out of crop + margin, resized."""
        if self._inner is None:
            return work
        top, left, ch, cw = self._inner
        out = np.ascontiguousarray(self._resized(work[top : top + ch, left : left + cw]),
                                   np.float32)
        out.setflags(write=False)
        return out

    def _inside(self, a: np.ndarray | None) -> np.ndarray | None:
        """The crop part of an analysed-size array."""
        if a is None or self._inner is None:
            return a
        top, left, ch, cw = self._inner
        return a[top : top + ch, left : left + cw]

    def _displacement(self, p: PairMotion) -> float:
        """Largest consistent displacement inside the output, output pixels."""
        if p.static:
            return 0.0
        if self._inner is None:
            return p.max_disp
        mags = [np.sqrt(sq_norm(self._inside(f))) for f in (p.fwd, p.bwd)]
        ok = [m[self._inside(v)] for m, v in zip(mags, (p.valid0, p.valid1), strict=True)]
        ok = [m for m in ok if m.size]
        disp = max(float(m.max()) for m in ok) if ok else max(float(m.max()) for m in mags)
        return disp * self._scale

    def _record_motion(self, i: int, p: PairMotion) -> None:
        step = _MOTION_STEP
        h, w = self.height, self.width
        if p.static:
            n = ((h + step - 1) // step) * ((w + step - 1) // step)
            self._motion[i] = np.zeros(n, np.float32)
            return
        fwd = self._inside(p.fwd)[::step, ::step]
        self._motion[i] = (np.sqrt(sq_norm(fwd)) * self._scale).ravel().astype(np.float32)

    def motion_stats(self) -> dict:
        """Measured motion inside the output over the frame pairs analysed so far.

        Forward-flow magnitudes (every second pixel of each axis, output pixels)
        times ``fps``: ``median_px_per_s``, ``p95_px_per_s`` and ``max_px_per_s``
        (pixels per second of video time), and ``pairs`` (how many pairs).
        Static pairs count as no motion.  Divide by the sensor's clock rate for
        pixels per readout.
        """
        if not self._motion:
            return {"pairs": 0, "median_px_per_s": 0.0, "p95_px_per_s": 0.0,
                    "max_px_per_s": 0.0}
        mags = np.concatenate([self._motion[k] for k in sorted(self._motion)]) * self.fps
        return {"pairs": len(self._motion), "median_px_per_s": float(np.median(mags)),
                "p95_px_per_s": float(np.percentile(mags, 95)),
                "max_px_per_s": float(mags.max())}

    def pair(self, i: int) -> PairMotion:
        """Motion between frames ``i`` and ``i + 1`` (computed once, cached)."""
        def make() -> PairMotion:
            if self._shared is not None and i in self._shared:
                p = self._shared[i]
            else:
                p = analyse_pair(self._work(i), self._work(i + 1), self.flow, self.static_tol)
                self.stats["pairs"] += 1
                self.stats["static_pairs"] += int(p.static)
                self.stats["flow_s"] += p.seconds
                if self._shared is not None:
                    self._shared[i] = p
            self._counts[i] = 0 if p.static else _n_intermediate(
                self._displacement(p), self.max_px, self.max_intermediate)
            if i not in self._motion:
                self._record_motion(i, p)
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
            out = interpolate(self._work(i), self._work(i + 1), self.pair(i), j / (m + 1),
                              occlusion=self.occlusion, roi=self._inner)
            out = np.ascontiguousarray(self._resized(out), np.float32)
            self.stats["interp_s"] += time.perf_counter() - t0
            self.stats["key_frames"] += 1
            out.setflags(write=False)
            return out

        return self._keys.get_or((i, j), make)

    # -- scene protocol -----------------------------------------------------------------
    def key_times(self, start_s: float, stop_s: float) -> np.ndarray:
        """Frame times and adaptive intermediate times bracketing ``[start_s, stop_s]``.

        Times are scene times (video time minus ``start_s``); when ``start_s``
        falls between frames, t = 0 is a key time too (the blend there lies on
        the straight line between its neighbours, so the grid stays global)."""
        start_s, stop_s = check_time(start_s), check_time(stop_s)
        off = self._offset
        last = self.n_frames - 1
        if not self._warned_end:  # a caller that did not give the whole length first
            self._warn_end(stop_s, stacklevel=3)
        i0 = min(max(0, math.floor(start_s * self.fps + off)), last)
        i1 = max(i0, math.ceil(stop_s * self.fps + off))
        pos = []
        for i in range(i0, min(i1, last)):
            m = self.n_intermediate(i)
            pos.extend(i + j / (m + 1) for j in range(m + 1))
        pos.extend(range(min(i1, last), i1 + 1))
        t = (np.asarray(pos, np.float64) - off) / self.fps
        if off:
            t = t[t > 0]
            if i0 == 0:
                t = np.concatenate([[0.0], t])
        lo = max(0, int(np.searchsorted(t, start_s, side="right")) - 1)
        hi = int(np.searchsorted(t, stop_s, side="left")) + 1
        return t[lo:hi]

    @property
    def duration_s(self) -> float:
        """Scene time of the last frame, seconds (the selected range's length)."""
        return (self.n_frames - 1 - self._offset) / self.fps

    def check_duration(self, duration_s: float) -> None:
        """Warn (:class:`VideoEndWarning`) when ``duration_s`` seconds of scene time,
        the whole length a simulation asks for, run more than one frame interval past
        the last frame (the simulator calls this before its first chunk, so the
        warning names the length asked for, not the chunk that first went past)."""
        self._warn_end(check_time(duration_s), stacklevel=4)

    def _warn_end(self, stop_s: float, stacklevel: int) -> None:
        length_s = self.duration_s
        if stop_s > length_s + 1.0 / self.fps:
            self._warned_end = True
            warnings.warn(f"the video ends at {length_s:.4g} s ({self.n_frames} frames at "
                          f"{self.fps:g} fps) and {stop_s:.4g} s are asked for: the rest holds "
                          "its last frame (ask for fewer readouts, or a longer clip)",
                          VideoEndWarning, stacklevel=stacklevel)

    def radiance(self, t: float) -> np.ndarray:
        """Key frame at a key time, linear blend of the neighbouring key frames between."""
        pos = check_time(t) * self.fps + self._offset
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
            "margin": self.margin if self.crop else None,
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
    return VideoScene(open_frames(path, layout=layout, sequence=sequence), fps, **options)


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
