"""Dataset manifests (TOML): what to simulate, validated before any work starts.

A manifest has four parts (see ``docs/dataset.md`` and the built-in manifests in
``spikesim/dataset/manifests/``):

``[dataset]``
    ``name``, ``seed`` (global), ``size = [H, W]``, ``window`` (readouts per sample,
    centred on its ground-truth readout; default 39), ``samples_per_sequence``
    (default 1), ``compression`` (default the HDF5 writer's), ``clean_twin``.
``[sensor]``
    ``preset`` plus any :class:`spikesim.Sensor` field as an override (the size
    always comes from ``[dataset].size``).
``[[noise]]``
    One or more noise variants; each sequence draws one (by ``weight``) and then
    its parameters: ``mode = "none" | "paper" | "physical"``, the model's fields
    as constants or distributions (:mod:`spikesim.dataset.distributions`),
    ``label`` (e.g. ``"GN"``).
``[[sources]]``
    ``kind = "procedural"`` (``scenes``, ``motions``, ``speed``, ``options``,
    ``count``), ``"reds"`` / ``"davis"`` (a dataset root; ``sequences`` = list
    or ``"all"``), ``"video"`` (a file or frame folder), or ``"python"``
    (``factory = "module:function"`` returning a scene; ``count``).  Each source
    has a ``split`` (default ``"train"``); video sources take ``fps`` and
    ``options`` for :func:`spikesim.scenes.video`.

Unknown keys, bad values and missing sources raise
:class:`~spikesim.errors.SpikeSimValueError` naming the key path.
"""

from __future__ import annotations

import functools
import importlib
import math
import os
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from spikesim.dataset.distributions import Distribution, parse_distribution
from spikesim.errors import SpikeSimFileError, SpikeSimTypeError, SpikeSimValueError, bad_value
from spikesim.noise import PaperNoise, PhysicalNoise
from spikesim.sensor import Sensor

__all__ = ["Manifest", "NoiseSpec", "SourceSpec", "ClipSpec", "VideoInfo", "load_manifest",
           "parse_manifest", "builtin_manifests", "builtin_manifest_path", "BUILTIN_PREFIX",
           "VIDEO_KINDS"]

BUILTIN_PREFIX = "builtin:"
_BUILTIN_DIR = Path(__file__).parent / "manifests"
_SOURCE_KINDS = ("procedural", "reds", "davis", "video", "python")
VIDEO_KINDS = ("reds", "davis", "video")
_VAR = re.compile(r"\$\{([A-Za-z_][A-Za-z0-9_]*)\}")
_NOISE_MODES = ("none", "paper", "physical")
_SPLIT_CHARS = set("abcdefghijklmnopqrstuvwxyz0123456789_-")


@dataclass(frozen=True)
class NoiseSpec:
    mode: str
    params: dict = field(default_factory=dict)  # name -> Distribution
    weight: float = 1.0
    label: str = ""


#: Most sequences a source's ``count`` (clips a video, for video sources) may ask for,
#: and most clips a video's ``per_second`` may give.
MAX_CLIPS = 10**6


@dataclass(frozen=True)
class VideoInfo:
    """One video of a video source, as found when the manifest was read."""

    name: str
    n_frames: int
    height: int
    width: int
    fps: float  # the rate the scene will use

    @property
    def duration_s(self) -> float:
        """Seconds from the first to the last frame."""
        return (self.n_frames - 1) / self.fps


@dataclass(frozen=True)
class ClipSpec:
    """How a video source cuts clips: how many, when, where (see docs/dataset.md)."""

    count: int | None = 1  # clips per video (None: per_second decides)
    per_second: float | None = None  # clips per second of video
    start_s: Distribution | None = None  # None: uniform over the whole video
    min_gap_s: float | None = None  # None: clips may overlap
    crop_size: tuple | None = None  # (h, w) stored pixels
    crop_position: object = "random"  # "random" | "center" | (y, x)

    def clips_of(self, video: VideoInfo) -> int:
        if self.count is not None:
            return self.count
        return max(1, round(self.per_second * video.duration_s))


@dataclass(frozen=True)
class SourceSpec:
    index: int
    kind: str
    split: str = "train"
    count: int = 1
    scenes: tuple = ()
    motions: tuple = ()
    speed: Distribution | None = None
    options: dict = field(default_factory=dict)  # name -> Distribution
    path: str | None = None
    sequences: tuple = ()
    fps: float | None = None
    factory: str | None = None
    noise: tuple = ()  # labels of the [[noise]] variants this source draws from (all if empty)
    clips: ClipSpec | None = None  # video kinds
    videos: tuple = ()  # VideoInfo per sequence (video kinds)


@dataclass(frozen=True)
class Manifest:
    name: str
    seed: int
    size: tuple
    window: int
    samples_per_sequence: int
    compression: str | None
    clean_twin: bool
    sensor: Sensor  # geometry applied, noise None (drawn per sequence)
    noises: tuple
    sources: tuple
    origin: str = ""

    @property
    def n_readouts(self) -> int:
        """Readouts per sequence: back-to-back windows, one per sample."""
        return self.window * self.samples_per_sequence

    @property
    def gt_readouts(self) -> list[int]:
        """Ground-truth readout of each sample: the centre of its window."""
        return [k * self.window + self.window // 2 for k in range(self.samples_per_sequence)]


def _take(table: dict, path: str, allowed: dict) -> dict:
    """Check keys of ``table`` against ``allowed`` (key -> required?)."""
    if not isinstance(table, dict):
        raise bad_value(path, table, "a table")
    unknown = sorted(set(table) - set(allowed))
    if unknown:
        raise bad_value(f"{path}.{unknown[0]}", table[unknown[0]],
                        f"a known key (allowed: {sorted(allowed)})")
    for key, required in allowed.items():
        if required and key not in table:
            raise SpikeSimValueError(f"{path}.{key} is missing (required)")
    return table


def _int(path: str, v, low: int, high: int | None = None) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or v < low or (high is not None and v > high):
        raise bad_value(path, v, f"an integer in [{low}, {high if high is not None else '∞'}]")
    return int(v)


def _str_list(path: str, v) -> tuple:
    if isinstance(v, str):
        return (v,)
    if not isinstance(v, list) or not v or not all(isinstance(s, str) for s in v):
        raise bad_value(path, v, "a string or a non-empty list of strings")
    return tuple(v)


def _parse_noise(i: int, t: dict) -> NoiseSpec:
    path = f"noise[{i}]"
    mode = t.get("mode", "none")
    if mode not in _NOISE_MODES:
        raise bad_value(f"{path}.mode", mode, f"one of {_NOISE_MODES}")
    fields = {"paper": PaperNoise, "physical": PhysicalNoise}.get(mode)
    names = {} if fields is None else {f: False for f in fields.__dataclass_fields__}
    _take(t, path, {"mode": False, "weight": False, "label": False, **names})
    limits = {"sigma_g": (0, 255), "sigma_p": (0, 255)}
    params = {}
    for key in names:
        if key in t:
            kind = "any" if key in ("shot_noise",) else "number"
            lo, hi = limits.get(key, (0, None))
            params[key] = parse_distribution(f"{path}.{key}", t[key], kind, lo, hi)
    weight = parse_distribution(f"{path}.weight", t.get("weight", 1.0), "number", 0, None)
    if weight.args[0] <= 0:
        raise bad_value(f"{path}.weight", t.get("weight"), "a number > 0")
    label = t.get("label", mode.upper() if mode != "none" else "clean")
    if not isinstance(label, str):
        raise bad_value(f"{path}.label", label, "a string")
    spec = NoiseSpec(mode, params, float(weight.args[0]), label)
    _check_noise_draws(path, spec)
    return spec


def _check_noise_draws(path: str, spec: NoiseSpec) -> None:
    """Every corner of the parameter ranges must build a valid noise model."""
    if spec.mode == "none":
        return
    cls = PaperNoise if spec.mode == "paper" else PhysicalNoise
    for pick in (0, 1):
        kw = {}
        for k, d in spec.params.items():
            lo, hi = d.bounds() if d.law != "fixed" else (d.args[0], d.args[0])
            kw[k] = (lo, hi)[pick] if lo is not None else d.args[0]
            if k == "fpn_seed":
                kw[k] = int(kw[k])
        try:
            cls(**kw)
        except SpikeSimValueError as exc:
            raise SpikeSimValueError(f"{path}: {exc}") from None


def _parse_source(i: int, t: dict, base: Path, clip_s: float = 0.0,
                  labels: tuple = ()) -> SourceSpec:
    path = f"sources[{i}]"
    kind = t.get("kind")
    if kind not in _SOURCE_KINDS:
        raise bad_value(f"{path}.kind", kind, f"one of {_SOURCE_KINDS}")
    common = {"kind": True, "split": False, "noise": False}
    noise = _str_list(f"{path}.noise", t["noise"]) if "noise" in t else ()
    for label in noise:
        if label not in labels:
            raise bad_value(f"{path}.noise", label,
                            f"a [[noise]] label among {sorted(set(labels))}")
    split = t.get("split", "train")
    if not isinstance(split, str) or not split or not set(split) <= _SPLIT_CHARS:
        raise bad_value(f"{path}.split", split, "a lower-case name like 'train' or 'eval'")
    if kind == "procedural":
        from spikesim.scenes import list_motions, list_scenes

        _take(t, path, {**common, "scenes": True, "motions": False, "speed": False,
                        "options": False, "count": True})
        scenes = _str_list(f"{path}.scenes", t["scenes"])
        known = list_scenes()
        for s in scenes:
            if s not in known:
                raise bad_value(f"{path}.scenes", s, f"a scene among {sorted(known)}")
        motions = _str_list(f"{path}.motions", t["motions"]) if "motions" in t else ()
        for m in motions:
            if m not in list_motions():
                raise bad_value(f"{path}.motions", m, f"a motion among {sorted(list_motions())}")
        speed = (parse_distribution(f"{path}.speed", t["speed"], "number", 0, 1e6)
                 if "speed" in t else None)
        options = t.get("options", {})
        if not isinstance(options, dict):
            raise bad_value(f"{path}.options", options, "a table of scene keywords")
        opts = {k: parse_distribution(f"{path}.options.{k}", v, "any") for k, v in options.items()}
        _try_procedural(path, scenes, motions, speed, opts)
        return SourceSpec(i, kind, split, _int(f"{path}.count", t["count"], 1, MAX_CLIPS), scenes,
                          motions, speed, opts, noise=noise)
    if kind == "python":
        _take(t, path, {**common, "factory": True, "count": True, "options": False})
        factory = t["factory"]
        if not isinstance(factory, str) or factory.count(":") != 1:
            raise bad_value(f"{path}.factory", factory, "'module:function'")
        resolve_factory(factory, f"{path}.factory")
        options = t.get("options", {})
        opts = {k: parse_distribution(f"{path}.options.{k}", v, "any") for k, v in options.items()}
        return SourceSpec(i, kind, split, _int(f"{path}.count", t["count"], 1, MAX_CLIPS),
                          options=opts, factory=factory, noise=noise)
    _take(t, path, {**common, "path": True, "sequences": False, "sequences_file": False,
                    "fps": False, "options": False, "count": False, "per_second": False,
                    "start_s": False, "min_gap_s": False, "crop": False})
    root = Path(t["path"]).expanduser()
    if not root.is_absolute():
        root = base / root
    if not root.exists():
        raise bad_value(f"{path}.path", str(root), "an existing file or folder")
    if root.suffix.lower() in (".h5", ".hdf5", ".dat"):
        raise bad_value(f"{path}.path", str(root),
                        "a video file or a folder of frames (a spike file is not a video source)")
    fps = t.get("fps")
    if fps is not None and (isinstance(fps, bool) or not isinstance(fps, (int, float)) or fps <= 0):
        raise bad_value(f"{path}.fps", fps, "a frame rate > 0 (frames per second)")
    wanted = t.get("sequences", "all")
    if "sequences_file" in t:
        if "sequences" in t:
            raise bad_value(f"{path}.sequences_file", t["sequences_file"],
                            "no 'sequences' beside it (give one of the two)")
        wanted = _names_from_file(f"{path}.sequences_file", root, t["sequences_file"])
    sequences = _video_sequences(kind, root, wanted, f"{path}.sequences")
    options = t.get("options", {})
    if not isinstance(options, dict):
        raise bad_value(f"{path}.options", options, "a table of spikesim.scenes.video keywords")
    opts = {k: parse_distribution(f"{path}.options.{k}", v, "any") for k, v in options.items()}
    for key in ("crop", "start_s", "stop_s", "resize"):
        if key in opts:
            raise bad_value(f"{path}.options.{key}", options[key],
                            f"no {key} here: the source's own keys set it (crop = {{size = ...}}, "
                            "start_s)")
    videos = tuple(_video_info(kind, root, seq, fps, f"{path}.sequences") for seq in sequences)
    _check_video_options(f"{path}.options", kind, root, videos[0], opts, options)
    clips = _parse_clips(path, t, videos, clip_s)
    return SourceSpec(i, kind, split, sum(clips.clips_of(v) for v in videos), options=opts,
                      path=str(root), sequences=sequences, fps=None if fps is None else float(fps),
                      noise=noise, clips=clips, videos=videos)


def _names_from_file(path: str, root: Path, name) -> list:
    if not isinstance(name, str):
        raise bad_value(path, name, "a text file of sequence names, relative to the source path")
    file = root / name if root.is_dir() else Path(name)
    if not file.is_file():
        raise bad_value(path, str(file), "an existing text file of sequence names (one a line)")
    names = [ln.strip() for ln in file.read_text().splitlines() if ln.strip()]
    if not names:
        raise bad_value(path, str(file), "a file naming at least one sequence")
    return names


def _video_info(kind: str, root: Path, seq: str, fps, path: str) -> VideoInfo:
    """Frame count, size and rate of one video (headers only, nothing decoded)."""
    from spikesim.errors import SpikeSimError
    from spikesim.scenes.readers import VideoFileSource, open_frames
    from spikesim.scenes.video import DEFAULT_FOLDER_FPS

    try:
        src = open_frames(root, layout={"reds": "reds", "davis": "davis"}.get(kind, "auto"),
                          sequence=None if kind == "video" else seq)
    except SpikeSimError as exc:
        raise SpikeSimValueError(f"{path}: video {seq!r}: {exc}") from None
    rate = fps or src.native_fps or DEFAULT_FOLDER_FPS
    if isinstance(src, VideoFileSource):
        src.close()
    if src.n_frames < 2:
        raise bad_value(path, seq, f"a video of at least 2 frames ({src.n_frames} found)")
    return VideoInfo(seq, int(src.n_frames), int(src.height), int(src.width), float(rate))


#: Keywords of :class:`~spikesim.scenes.video.VideoScene` that a source's own keys
#: set (``fps``, ``crop``, ``start_s``; ``resize`` is ``[dataset].size``), or that a
#: manifest cannot give (``shared_flows``), so never in its ``options``.
_VIDEO_SET_BY_SOURCE = ("self", "source", "fps", "resize", "crop", "start_s", "stop_s",
                        "shared_flows")


def _check_video_options(path: str, kind: str, root: Path, video: VideoInfo, opts: dict,
                         raw: dict) -> None:
    """Refuse, before any work, ``options`` the build's
    :func:`spikesim.scenes.video` would refuse: unknown keywords, and any value
    a key can draw (both ends of a range, every choice) that the scene rejects,
    tried on the source's first video (headers only, nothing decoded)."""
    import inspect

    from spikesim.errors import SpikeSimError
    from spikesim.scenes.readers import VideoFileSource, open_frames
    from spikesim.scenes.video import VideoScene

    known = sorted(set(inspect.signature(VideoScene.__init__).parameters)
                   - set(_VIDEO_SET_BY_SOURCE))
    for key in opts:
        if key not in known:
            raise bad_value(f"{path}.{key}", raw[key], f"a keyword of spikesim.scenes.video "
                            f"among {known}")
    if not opts:
        return
    src = open_frames(root, layout={"reds": "reds", "davis": "davis"}.get(kind, "auto"),
                      sequence=None if kind == "video" else video.name)
    try:
        first = {k: d.args[0] for k, d in opts.items()}
        for key, d in opts.items():
            values = d.args if d.law in ("choice", "uniform", "loguniform") else d.args[:1]
            for v in values:
                try:
                    VideoScene(src, video.fps, **{**first, key: v})
                except (SpikeSimError, TypeError, ValueError) as exc:
                    raise SpikeSimValueError(f"{path}.{key}={v!r} is invalid for video "
                                             f"{video.name!r}: {exc}") from None
    finally:
        if isinstance(src, VideoFileSource):
            src.close()


def _parse_clips(path: str, t: dict, videos: tuple, clip_s: float) -> ClipSpec:
    """Clip keys of a video source, checked against every video of it."""
    if "count" in t and "per_second" in t:
        raise bad_value(f"{path}.per_second", t["per_second"],
                        "no 'count' beside it (one of the two)")
    count = _int(f"{path}.count", t["count"], 1, MAX_CLIPS) if "count" in t else None
    per_second = None
    if "per_second" in t:
        v = t["per_second"]
        if (isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)
                or not v > 0):
            raise bad_value(f"{path}.per_second", v, "a finite number > 0 (clips per second of "
                            "video)")
        per_second = float(v)
    elif count is None:
        count = 1
    start = (parse_distribution(f"{path}.start_s", t["start_s"], "number", 0, None)
             if "start_s" in t else None)
    gap = None
    if "min_gap_s" in t:
        gap = parse_distribution(f"{path}.min_gap_s", t["min_gap_s"], "number", 0, None)
        if gap.law != "fixed":
            raise bad_value(f"{path}.min_gap_s", t["min_gap_s"], "a number of seconds >= 0")
        gap = float(gap.args[0])
        if start is not None and start.law != "uniform":
            raise bad_value(f"{path}.start_s", t["start_s"],
                            "{uniform = [a, b]} (or nothing) when min_gap_s is given")
    size, position = None, "random"
    if "crop" in t:
        crop = _take(t["crop"], f"{path}.crop", {"size": True, "position": False})
        s = crop["size"]
        if not (isinstance(s, list) and len(s) == 2):
            raise bad_value(f"{path}.crop.size", s, "[height, width] in stored pixels")
        size = (_int(f"{path}.crop.size[0]", s[0], 2, 100_000),
                _int(f"{path}.crop.size[1]", s[1], 2, 100_000))
        position = crop.get("position", "random")
        if isinstance(position, list) and len(position) == 2:
            position = (_int(f"{path}.crop.position[0]", position[0], 0, 100_000),
                        _int(f"{path}.crop.position[1]", position[1], 0, 100_000))
        elif position not in ("random", "center"):
            raise bad_value(f"{path}.crop.position", position, '"random", "center" or [top, left]')
    clips = ClipSpec(count, per_second, start, gap, size, position)
    for v in videos:
        _check_clips_fit(path, clips, v, clip_s)
    return clips


def _check_clips_fit(path: str, c: ClipSpec, v: VideoInfo, clip_s: float) -> None:
    where = (f"video {v.name!r} ({v.n_frames} frames at {v.fps:g} fps, {v.height}x{v.width}; "
             f"each clip lasts {clip_s:.4g} s)")
    latest = v.duration_s - clip_s
    if c.per_second is not None and c.per_second * v.duration_s > MAX_CLIPS + 0.5:
        # capped as count is: planning takes time per clip (minutes at 10**7)
        raise bad_value(f"{path}.per_second", c.per_second,
                        f"at most {MAX_CLIPS:,} clips a video (as count): "
                        f"{c.per_second * v.duration_s:,.0f} for {where}")
    if latest < 0:
        raise SpikeSimValueError(
            f"{path}: {where} is shorter than one clip (dataset.window × "
            "dataset.samples_per_sequence readouts at the sensor's clock_hz): use fewer "
            "samples_per_sequence, a shorter window or a faster clock")
    if c.start_s is not None:
        lo, hi = c.start_s.bounds() if c.start_s.law != "fixed" else (c.start_s.args[0],) * 2
        if hi > latest + 1e-9:
            raise bad_value(f"{path}.start_s", hi, f"start times <= {latest:.4g} s for {where}")
    if c.min_gap_s is not None:
        lo, hi = c.start_s.args if c.start_s is not None else (0.0, latest)
        n = c.clips_of(v)
        if n * (clip_s + c.min_gap_s) > hi - lo + clip_s + c.min_gap_s + 1e-9:
            raise bad_value(f"{path}.min_gap_s", c.min_gap_s,
                            f"room for {n} clips {c.min_gap_s:g} s apart in "
                            f"[{lo:.4g}, {hi:.4g} + clip] s for {where}")
    if c.crop_size is not None:
        h, w = c.crop_size
        if h > v.height or w > v.width:
            raise bad_value(f"{path}.crop.size", list(c.crop_size), f"at most the frame of {where}")
        if isinstance(c.crop_position, tuple):
            y, x = c.crop_position
            if y + h > v.height or x + w > v.width:
                raise bad_value(f"{path}.crop.position", list(c.crop_position),
                                f"a crop inside the frame of {where}")


def _try_procedural(path: str, scenes, motions, speed, opts) -> None:
    """Build every (scene, motion) once at a tiny size so bad combinations fail now."""
    from spikesim.errors import SpikeSimError
    from spikesim.scenes import procedural

    kw = {k: d.args[0] for k, d in opts.items()}
    if speed is not None:
        kw["speed"] = speed.args[0]
    from spikesim.scenes.sources import IMAGES

    for scene in scenes:
        for motion in (motions or (None,)) if scene in IMAGES else (None,):
            try:
                procedural(scene, motion=motion, size=(16, 16), **kw)
            except (SpikeSimError, TypeError) as exc:
                raise SpikeSimValueError(
                    f"{path}: scene {scene!r} with motion={motion!r} and {kw}: {exc}") from None


def _video_sequences(kind: str, root: Path, wanted, path: str) -> tuple:
    if kind == "video":
        return (root.stem if root.is_file() else root.name,)
    folder = root / "JPEGImages" / "480p" if kind == "davis" else root
    if not folder.is_dir():
        raise bad_value(path.replace(".sequences", ".path"), str(root),
                        f"a {kind.upper()} root (missing {folder})")
    available = sorted(p.name for p in folder.iterdir() if p.is_dir())
    if wanted == "all":
        if not available:
            raise bad_value(path, "all", f"at least one sequence folder in {folder}")
        return tuple(available)
    names = _str_list(path, wanted)
    for n in names:
        if n not in available:
            raise bad_value(path, n, f"a sequence folder of {folder} ({len(available)} found)")
    return names


_SCENE_PROTOCOL = ("radiance", "key_times", "height", "width", "describe")


def resolve_factory(spec: str, path: str = "factory"):
    """Import ``module:function`` and return it wrapped so that what it returns is checked.

    The wrapper raises :class:`SpikeSimTypeError` naming the factory when the
    result is not a scene (an object with ``radiance``, ``key_times``,
    ``height``, ``width`` and ``describe``).
    """
    module, _, func = spec.partition(":")
    try:
        obj = getattr(importlib.import_module(module), func)
    except (ImportError, AttributeError) as exc:
        raise bad_value(path, spec, f"an importable 'module:function' ({exc})") from None
    if not callable(obj):
        raise bad_value(path, spec, "a callable")

    @functools.wraps(obj)
    def checked_factory(*args, **kwargs):
        scene = obj(*args, **kwargs)
        missing = [a for a in _SCENE_PROTOCOL if not hasattr(scene, a)]
        if missing:
            raise SpikeSimTypeError(
                f"factory {spec!r} returned {type(scene).__name__}, not a scene (missing "
                f"{', '.join(missing)}): return e.g. spikesim.scenes.Static(image)"
            )
        return scene

    return checked_factory


def parse_manifest(data: dict, origin: str = "", base: Path | None = None) -> Manifest:
    """Validate a manifest given as a dict (the parsed TOML)."""
    base = base or Path.cwd()
    _take(data, "manifest", {"dataset": True, "sensor": False, "noise": False, "sources": True})
    ds = _take(data["dataset"], "dataset", {
        "name": True, "seed": False, "size": True, "window": False,
        "samples_per_sequence": False, "compression": False, "clean_twin": False,
        "description": False})
    name = ds["name"]
    if not isinstance(name, str) or not name:
        raise bad_value("dataset.name", name, "a non-empty string")
    seed = _int("dataset.seed", ds.get("seed", 0), 0, 2**63 - 1)
    size = ds["size"]
    if not (isinstance(size, list) and len(size) == 2):
        raise bad_value("dataset.size", size, "[height, width] in pixels")
    size = (_int("dataset.size[0]", size[0], 2, 8192), _int("dataset.size[1]", size[1], 2, 8192))
    window = _int("dataset.window", ds.get("window", 39), 1, 100_000)
    samples = _int("dataset.samples_per_sequence", ds.get("samples_per_sequence", 1), 1, 100_000)
    compression = ds.get("compression")
    if compression is not None:
        from spikesim.io import COMPRESSIONS

        if not isinstance(compression, str) or compression.split(":")[0] not in COMPRESSIONS:
            raise bad_value("dataset.compression", compression, f"one of {COMPRESSIONS}")
    clean = ds.get("clean_twin", False)
    if not isinstance(clean, bool):
        raise bad_value("dataset.clean_twin", clean, "true or false")

    sensor_t = dict(data.get("sensor", {}))
    if not isinstance(sensor_t, dict):
        raise bad_value("sensor", sensor_t, "a table")
    preset = sensor_t.pop("preset", "ideal")
    if "noise" in sensor_t:
        raise bad_value("sensor.noise", sensor_t["noise"], "no noise here: use [[noise]] tables")
    try:
        sensor = Sensor.preset(preset, height=size[0], width=size[1], **sensor_t).replace(
            noise=None)
    except SpikeSimValueError as exc:
        raise SpikeSimValueError(f"sensor: {exc}") from None

    noises = data.get("noise", [{"mode": "none"}])
    if not isinstance(noises, list) or not noises:
        raise bad_value("noise", noises, "one or more [[noise]] tables")
    noise_specs = tuple(_parse_noise(i, t) for i, t in enumerate(noises))
    sources = data["sources"]
    if not isinstance(sources, list) or not sources:
        raise bad_value("sources", sources, "one or more [[sources]] tables")
    clip_s = window * samples / sensor.clock_hz
    labels = tuple(n.label for n in noise_specs)
    source_specs = tuple(_parse_source(i, t, base, clip_s, labels) for i, t in enumerate(sources))
    return Manifest(name, seed, size, window, samples, compression, clean, sensor, noise_specs,
                    source_specs, origin)


def load_manifest(path_or_name: str | Path, variables: dict | None = None) -> Manifest:
    """Load a manifest file, or a built-in one as ``"builtin:NAME"``.

    ``${NAME}`` in any string of the manifest is replaced by ``variables[NAME]``
    (``spikesim dataset --set NAME=VALUE``) or else the environment variable
    ``NAME``; one that is set in neither is an error naming it, and so is a
    name in ``variables`` the manifest does not use (a typo such as ``DAVS``).
    """
    text_path = str(path_or_name)
    if text_path.startswith(BUILTIN_PREFIX):
        path = builtin_manifest_path(text_path[len(BUILTIN_PREFIX):])
    else:
        path = Path(text_path)
    if not path.is_file():
        raise SpikeSimFileError(f"manifest {str(path)!r} does not exist")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError as exc:
        raise bad_value("manifest", str(path), f"a UTF-8 text file of TOML (byte {exc.start} "
                        "is not UTF-8: a binary file, or saved in another encoding?)") from None
    except tomllib.TOMLDecodeError as exc:
        raise bad_value("manifest", str(path), f"valid TOML ({exc})") from None
    variables = dict(variables or {})
    _check_variables(variables, _used_variables(data), text_path)
    data = _substitute(data, variables, text_path)
    return parse_manifest(data, origin=text_path, base=path.parent)


def _used_variables(value) -> set[str]:
    """Every ``NAME`` of a ``${NAME}`` in the strings of a parsed manifest."""
    if isinstance(value, dict):
        return set().union(*(_used_variables(v) for v in value.values()))
    if isinstance(value, list):
        return set().union(*(_used_variables(v) for v in value))
    return set(_VAR.findall(value)) if isinstance(value, str) else set()


def _check_variables(variables: dict, used: set[str], origin: str) -> None:
    """A variable given (``--set NAME=VALUE``) that the manifest never uses is a typo."""
    unknown = sorted(set(variables) - used)
    if unknown:
        uses = (f"it uses {', '.join(sorted(used))}" if used
                else "it uses no ${NAME} variables")
        raise SpikeSimValueError(
            f"--set {unknown[0]}: manifest {origin} has no variable {unknown[0]} ({uses}); "
            "check the spelling or drop it")


def _substitute(value, variables: dict, origin: str, is_path: bool = False):
    """``${NAME}`` replaced in every string.  A source ``path`` that starts with a
    variable whose value is a relative path is resolved against the current
    directory (where the user typed ``--set`` or set the variable), not against
    the manifest's folder (a built-in manifest's is inside the package)."""
    if isinstance(value, dict):
        return {k: _substitute(v, variables, origin, k == "path") for k, v in value.items()}
    if isinstance(value, list):
        return [_substitute(v, variables, origin) for v in value]
    if not isinstance(value, str):
        return value

    def one(match):
        name = match.group(1)
        found = variables.get(name, os.environ.get(name))
        if found is None:
            raise SpikeSimValueError(
                f"manifest {origin} needs {name}: give --set {name}=VALUE (or set the "
                f"environment variable {name})")
        found = str(found)
        if is_path and match.start() == 0 and found:
            found = str(Path.cwd() / Path(found).expanduser())  # (an absolute one stays)
        return found

    return _VAR.sub(one, value)


def builtin_manifest_path(name: str) -> Path:
    """The TOML file of built-in manifest ``name`` (``spikesim manifests`` lists them)."""
    if name not in builtin_manifests():
        raise bad_value("manifest", f"{BUILTIN_PREFIX}{name}",
                        f"one of builtin:{sorted(builtin_manifests())}")
    return _BUILTIN_DIR / f"{name}.toml"


def builtin_manifests() -> dict[str, str]:
    """Built-in manifests with their one-line descriptions."""
    out = {}
    for p in sorted(_BUILTIN_DIR.glob("*.toml")):
        data = tomllib.loads(p.read_text())
        out[p.stem] = data.get("dataset", {}).get("description", "")
    return out
