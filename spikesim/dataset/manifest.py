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
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from spikesim.dataset.distributions import Distribution, parse_distribution
from spikesim.errors import SpikeSimFileError, SpikeSimTypeError, SpikeSimValueError, bad_value
from spikesim.noise import PaperNoise, PhysicalNoise
from spikesim.sensor import Sensor

__all__ = ["Manifest", "NoiseSpec", "SourceSpec", "load_manifest", "parse_manifest",
           "builtin_manifests", "BUILTIN_PREFIX"]

BUILTIN_PREFIX = "builtin:"
_BUILTIN_DIR = Path(__file__).parent / "manifests"
_SOURCE_KINDS = ("procedural", "reds", "davis", "video", "python")
_NOISE_MODES = ("none", "paper", "physical")
_SPLIT_CHARS = set("abcdefghijklmnopqrstuvwxyz0123456789_-")


@dataclass(frozen=True)
class NoiseSpec:
    mode: str
    params: dict = field(default_factory=dict)  # name -> Distribution
    weight: float = 1.0
    label: str = ""


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


def _parse_source(i: int, t: dict, base: Path) -> SourceSpec:
    path = f"sources[{i}]"
    kind = t.get("kind")
    if kind not in _SOURCE_KINDS:
        raise bad_value(f"{path}.kind", kind, f"one of {_SOURCE_KINDS}")
    common = {"kind": True, "split": False}
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
        return SourceSpec(i, kind, split, _int(f"{path}.count", t["count"], 1, 10**6), scenes,
                          motions, speed, opts)
    if kind == "python":
        _take(t, path, {**common, "factory": True, "count": True, "options": False})
        factory = t["factory"]
        if not isinstance(factory, str) or factory.count(":") != 1:
            raise bad_value(f"{path}.factory", factory, "'module:function'")
        resolve_factory(factory, f"{path}.factory")
        options = t.get("options", {})
        opts = {k: parse_distribution(f"{path}.options.{k}", v, "any") for k, v in options.items()}
        return SourceSpec(i, kind, split, _int(f"{path}.count", t["count"], 1, 10**6),
                          options=opts, factory=factory)
    _take(t, path, {**common, "path": True, "sequences": False, "fps": False, "options": False})
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
    sequences = _video_sequences(kind, root, t.get("sequences", "all"), f"{path}.sequences")
    options = t.get("options", {})
    if not isinstance(options, dict):
        raise bad_value(f"{path}.options", options, "a table of spikesim.scenes.video keywords")
    opts = {k: parse_distribution(f"{path}.options.{k}", v, "any") for k, v in options.items()}
    return SourceSpec(i, kind, split, len(sequences), options=opts, path=str(root),
                      sequences=sequences, fps=None if fps is None else float(fps))


def _try_procedural(path: str, scenes, motions, speed, opts) -> None:
    """Build every (scene, motion) once at a tiny size so bad combinations fail now."""
    from spikesim.errors import SpikeSimError
    from spikesim.scenes import procedural

    kw = {k: d.args[0] for k, d in opts.items()}
    if speed is not None:
        kw["speed"] = speed.args[0]
    for scene in scenes:
        for motion in motions or (None,):
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
    source_specs = tuple(_parse_source(i, t, base) for i, t in enumerate(sources))
    return Manifest(name, seed, size, window, samples, compression, clean, sensor, noise_specs,
                    source_specs, origin)


def load_manifest(path_or_name: str | Path) -> Manifest:
    """Load a manifest file, or a built-in one as ``"builtin:NAME"``."""
    text_path = str(path_or_name)
    if text_path.startswith(BUILTIN_PREFIX):
        name = text_path[len(BUILTIN_PREFIX):]
        if name not in builtin_manifests():
            raise bad_value("manifest", text_path, f"one of builtin:{sorted(builtin_manifests())}")
        path = _BUILTIN_DIR / f"{name}.toml"
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
    return parse_manifest(data, origin=text_path, base=path.parent)


def builtin_manifests() -> dict[str, str]:
    """Built-in manifests with their one-line descriptions."""
    out = {}
    for p in sorted(_BUILTIN_DIR.glob("*.toml")):
        data = tomllib.loads(p.read_text())
        out[p.stem] = data.get("dataset", {}).get("description", "")
    return out
