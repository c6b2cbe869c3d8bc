"""``spikesim simulate``: one stream from a built-in scene or a video, to HDF5 or .dat."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

from spikesim.commands._io_common import parse_crop
from spikesim.errors import SpikeSimError, SpikeSimFileError, SpikeSimValueError, bad_value
from spikesim.workload import RunawayWorkWarning


def load_sensor(spec: str, overrides: dict, options: dict | None = None):
    """The sensor of a ``--sensor`` option: a preset name, or a sensor ``.json`` file
    (:meth:`spikesim.Sensor.to_json`), with ``--set``/``--size`` overrides applied
    (``cfa=mono`` or ``none``: monochrome; ``noise.FIELD``: a field of the sensor's
    noise model, e.g. ``noise.electrons_per_threshold``).  Errors name the option
    that gave a value: ``--set FIELD=...``, or ``options[FIELD]`` (``{"height":
    "--size"}``)."""
    if overrides.get("cfa") in ("mono", "none"):
        overrides = dict(overrides, cfa=None)
    noise_fields = {k.split(".", 1)[1]: v for k, v in overrides.items()
                    if k.startswith("noise.")}
    base = {k: v for k, v in overrides.items() if not k.startswith("noise.")}
    try:
        sensor = _base_sensor(spec, base)
    except SpikeSimError as exc:
        from spikesim.cli_guard import as_option

        named = name_keys(exc, [k for k in base if k not in (options or {})], "--set")
        if named is exc:
            named = as_option(exc, {"preset": "--sensor", "sensor override": "--set",
                                    **(options or {})})
        if named is exc and "noise" in base:  # a field inside --set noise={...}
            named = type(exc)(f"--set noise: {exc}")
        raise named from None
    if not noise_fields:
        return sensor
    if sensor.noise is None:
        name, value = next(iter(noise_fields.items()))
        raise bad_value(f"--set noise.{name}", value, "a sensor with a noise model (this one "
                        "has none): a noisy preset, or also --set 'noise={\"type\": \"physical\"}'")
    try:
        return sensor.replace(noise=sensor.noise.replace(**noise_fields))
    except SpikeSimError as exc:
        from spikesim.cli_guard import as_option

        named = as_option(exc, {k: f"--set noise.{k}" for k in noise_fields})
        raise (named if named is not exc else type(exc)(f"--set noise.FIELD: {exc}")) from None


def name_keys(exc: SpikeSimError, keys, option: str) -> SpikeSimError:
    """``exc`` with the key its message starts with (``clock_hz=-5 is invalid``,
    ``noise.type='x' is invalid``) named as the option that gave it (``--set
    clock_hz=-5 is invalid``); ``exc`` itself when it names none of ``keys``."""
    text = str(exc)
    for key in sorted(keys, key=len, reverse=True):
        if text.startswith((f"{key}=", f"{key}.", f"{key} ")):
            return type(exc)(f"{option} {text}")
    return exc


def _base_sensor(spec: str, overrides: dict):
    """:func:`load_sensor` before its ``noise.FIELD`` overrides."""
    import spikesim as ss

    path = Path(spec)
    if path.suffix.lower() == ".json":
        if not path.is_file():
            raise SpikeSimFileError(f"no such sensor JSON file: {spec!r}")
        try:
            sensor = ss.Sensor.from_json(path.read_text())
        except SpikeSimError as exc:
            raise type(exc)(f"sensor file {spec!r}: {exc}") from None
        except (UnicodeDecodeError, ValueError) as exc:
            raise SpikeSimValueError(f"sensor file {spec!r} is not a sensor JSON "
                                     f"({type(exc).__name__}: {exc})") from None
        return sensor.replace(**overrides)
    return ss.Sensor.preset(spec, **overrides)


def register(sub) -> None:
    p = sub.add_parser("simulate", help="simulate one stream to FILE.h5 or FILE.dat")
    p.add_argument("scene", help="built-in scene name (see `spikesim scenes`) or a video path")
    p.add_argument("--motion", default=None, help="motion of a picture scene (pan, zoom, ...)")
    p.add_argument("--speed", type=float, default=None,
                   help="largest content speed of a built-in scene, pixels per second")
    p.add_argument("--scene-set", action="append", default=[], metavar="KEY=VALUE",
                   help="a built-in scene's own option, e.g. --scene-set level=0.3 or "
                        "--scene-set exposure=2 (`spikesim scenes` lists the scenes)")
    p.add_argument("--sensor", default="ideal",
                   help="sensor preset (see `spikesim presets`) or a sensor .json file (e.g. "
                        "the sensor.json `spikesim analyze calibrate` writes)")
    p.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE",
                   help="override a sensor field, e.g. --set clock_hz=40000 --set cfa=mono "
                        "--set 'noise={\"type\":\"paper\",\"sigma_g\":5}', or a field of its "
                        "noise model: --set noise.electrons_per_threshold=300")
    p.add_argument("--size", default=None, help="HxW frame size (default: the preset's)")
    p.add_argument("--fps", type=float, default=None, help="frame rate of a video source")
    p.add_argument("--crop", type=parse_crop, default=None, metavar="TOP,LEFT,HEIGHT,WIDTH",
                   help="a video's box to keep, in stored pixels (as crop= of "
                        "spikesim.scenes.video); resized to --size, or kept at its size "
                        "without --size")
    p.add_argument("--start-s", type=float, default=None, metavar="SECONDS",
                   help="a video's time that becomes scene time 0 (default 0)")
    p.add_argument("--stop-s", type=float, default=None, metavar="SECONDS",
                   help="a video's last time used (default: its end)")
    p.add_argument("--readouts", type=int, required=True)
    p.add_argument("--gt", default=None, metavar="WHEN",
                   help="readouts with ground truth (.h5 only): middle (default), all, none, "
                        "or readout indices I,J,K (0-based)")
    p.add_argument("--gt-every", type=int, default=None, metavar="N",
                   help="ground truth at the middle of every N readouts: N//2, N+N//2, ... "
                        "(.h5 only)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--clean-twin", action="store_true", help="also store the noise-free twin")
    p.add_argument("--out", required=True, help="FILE.h5 or FILE.dat")
    p.add_argument("--force", action="store_true",
                   help="run even when the output looks larger than the free disk space, "
                        "the run larger than the free memory, or the scene needs an "
                        "unusually large number of key frames")
    p.set_defaults(func=run)


def parse_overrides(items: list[str], option: str = "--set") -> dict:
    """``--set FIELD=VALUE`` items as a dict: VALUE is JSON, or else a plain string; a
    VALUE that starts like a JSON object, list or string must be valid JSON."""
    out = {}
    for item in items:
        if "=" not in item:
            raise bad_value(option, item, "FIELD=VALUE")
        key, value = item.split("=", 1)
        try:
            out[key] = json.loads(value)
        except json.JSONDecodeError as exc:
            if value.lstrip()[:1] in ('{', '[', '"'):
                raise bad_value(
                    f"{option} {key}", value,
                    f"valid JSON; it is not (character {exc.pos + 1}: {exc.msg}), "
                    'e.g. --set \'noise={"type":"paper","sigma_g":5}\'') from None
            out[key] = value
    return out


def gt_readouts(gt: str | None, every: int | None, n_readouts: int):
    """The ``gt_readouts`` of :func:`spikesim.simulate_chunks` for ``--gt`` and
    ``--gt-every`` (None: the default, the middle readout)."""
    from spikesim._validate import check_int

    if gt is not None and every is not None:
        raise bad_value("--gt-every", every, f"no --gt-every with --gt {gt} (give one of them)")
    if every is not None:
        step = check_int("--gt-every", every, 1, n_readouts, unit="readouts (at most --readouts)")
        return list(range(step // 2, n_readouts, step))
    if gt is None or gt.strip().lower() == "middle":
        return None
    word = gt.strip().lower()
    if word in ("all", "none"):
        return "all" if word == "all" else []
    parts = [p.strip() for p in gt.split(",")]
    if not all(p.isdigit() for p in parts):
        raise bad_value("--gt", gt, "middle, all, none, or readout indices I,J,K (e.g. 19,58,97)")
    out = [int(p) for p in parts]
    for i in out:
        check_int("--gt", i, 0, n_readouts - 1, unit="a readout index below --readouts")
    return out


def _video_scene(args, size: tuple[int, int]):
    """The video of ``SCENE`` with ``--fps``, ``--crop``, ``--start-s``/``--stop-s``,
    resized to ``size`` (the sensor's); errors and the squashed-aspect warning name the
    options."""
    import spikesim as ss
    from spikesim._validate import check_real
    from spikesim.cli_guard import as_option
    from spikesim.scenes.video import AspectWarning, aspect_change

    start = 0.0 if args.start_s is None else check_real("--start-s", args.start_s, 0,
                                                        unit="seconds of video")
    if args.stop_s is not None:
        check_real("--stop-s", args.stop_s, start, low_open=True,
                   unit=f"seconds of video (after --start-s {start:g})")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", AspectWarning)
        try:
            scene = ss.scenes.video(args.scene, fps=args.fps, resize=size, crop=args.crop,
                                    start_s=start, stop_s=args.stop_s)
        except SpikeSimValueError as exc:
            if str(exc).startswith("video=") and (args.start_s, args.stop_s) != (None, None):
                raise SpikeSimValueError(f"--start-s/--stop-s: {exc}") from None
            raise as_option(exc, {"crop": "--crop", "fps": "--fps", "video": "SCENE"}) from None
    for w in caught:
        if not issubclass(w.category, AspectWarning):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
            continue
        stored = tuple(args.crop[2:]) if args.crop else (scene.source.height,
                                                         scene.source.width)
        what = "--crop box" if args.crop else "frames"
        given = (f"--size {size[0]}x{size[1]}" if args.size else
                 f"the sensor size {size[0]}x{size[1]} (--sensor {args.sensor})")
        warnings.warn(f"{given} squashes the {stored[0]}x{stored[1]} {what} "
                      f"(aspect ratio changed by {100 * aspect_change(size, stored):+.0f} %); "
                      "to keep the content's shape give a --size of their aspect, or --crop "
                      "a box of the --size aspect first", AspectWarning, stacklevel=2)
    return scene


def run(args) -> int:
    import spikesim as ss
    from spikesim import io
    from spikesim._validate import check_int, check_real
    from spikesim.cli_guard import as_option, parse_size
    from spikesim.workload import check_free_space, check_memory, require_reasonable_key_frames

    check_int("--readouts", args.readouts, 1, 2**53, unit="readouts")
    check_int("--seed", args.seed, 0, 2**64 - 1)
    if args.fps is not None:
        check_real("--fps", args.fps, 0, low_open=True, unit="video frames per second")
    out = Path(args.out)
    if out.suffix.lower() not in (".h5", ".hdf5", ".dat"):
        raise bad_value("--out", args.out, "a path ending in .h5, .hdf5 or .dat")
    gt = gt_readouts(args.gt, args.gt_every, args.readouts)
    if gt is not None and out.suffix.lower() == ".dat":
        raise bad_value("--gt-every" if args.gt_every is not None else "--gt",
                        args.gt_every if args.gt_every is not None else args.gt,
                        "no ground truth with a .dat output (it stores spike bits only): "
                        "write FILE.h5 to keep it")
    is_video = Path(args.scene).exists()
    if not is_video:
        for option, value in (("--crop", args.crop), ("--start-s", args.start_s),
                              ("--stop-s", args.stop_s)):
            if value is not None:
                raise bad_value(option, value if option != "--crop" else ",".join(
                    map(str, value)), "none for a built-in scene (it applies to a video "
                    "file or frame folder)")
    overrides = parse_overrides(args.set)
    size_option = None
    if args.size:
        h, w = parse_size(args.size)
        overrides.update(height=h, width=w)
        size_option = "--size"
    elif is_video and args.crop is not None:  # the crop at its stored size
        overrides.update(height=args.crop[2], width=args.crop[3])
        size_option = "--crop"
    sensor = load_sensor(args.sensor, overrides,
                         {"height": size_option, "width": size_option} if size_option else None)
    if not args.force:
        check_memory(sensor.height, sensor.width, size_option or "sensor size")
    scene_options = parse_overrides(args.scene_set, "--scene-set")
    if is_video:
        if args.speed is not None or scene_options:
            raise bad_value("--speed/--scene-set", args.speed or args.scene_set,
                            "none for a video (they set a built-in scene's motion and look; "
                            "a video takes --crop, --start-s, --stop-s and --fps)")
        scene = _video_scene(args, sensor.shape)
    elif "/" in args.scene or Path(args.scene).suffix:  # a path, not a scene's name
        raise SpikeSimFileError(f"SCENE {args.scene!r}: no such video file or frame folder "
                                "(built-in scene names: spikesim scenes)")
    else:
        for key, option in (("motion", "--motion"), ("speed", "--speed"), ("size", "--size"),
                            ("name", "SCENE")):
            if key in scene_options:  # procedural()'s own arguments, not the scene's options
                raise bad_value(f"--scene-set {key}", scene_options[key], "a scene's own "
                                f"option (`spikesim scenes`); give {option} instead")
        try:
            scene = ss.scenes.procedural(args.scene, motion=args.motion, size=sensor.shape,
                                         speed=args.speed, **scene_options)
        except SpikeSimValueError as exc:  # name the command-line option
            named = name_keys(exc, scene_options, "--scene-set")
            raise (named if named is not exc else
                   as_option(exc, {"options": "--scene-set", "speed": "--speed",
                                   "motion": "--motion", "name": "SCENE"})) from None
    packed_bytes = args.readouts * sensor.height * ((sensor.width + 7) // 8)
    n_gt = 1 if gt is None else args.readouts if gt == "all" else len(gt)
    gt_bytes = 0 if out.suffix.lower() == ".dat" else n_gt * sensor.height * sensor.width * 12
    if not args.force:
        check_free_space(out, packed_bytes * (2 if args.clean_twin else 1) + gt_bytes)
        require_reasonable_key_frames(scene, args.readouts / sensor.clock_hz)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RunawayWorkWarning)  # checked above (or --force)
        run_ = ss.simulate_chunks(scene, sensor, args.readouts, seed=args.seed,
                                  clean_twin=args.clean_twin, gt_readouts=gt, progress=True)
    if out.suffix.lower() == ".dat":
        if sensor.cfa is not None:
            print("note: .dat stores bits only; the CFA pattern is not recorded")
        with io.DatWriter(out, sensor.height, sensor.width, flip=True) as writer:
            for chunk in run_:
                writer.write_packed(chunk.packed)
    else:
        io.write_h5(out, run_)
    noise = sensor.noise.to_dict()["type"] if sensor.noise is not None else "none"
    print(f"wrote {out} ({args.readouts} readout{'' if args.readouts == 1 else 's'}, "
          f"{sensor.height}x{sensor.width}, "
          f"cfa={sensor.cfa or 'mono'}, reset={sensor.reset}, noise={noise}, "
          f"sensor={args.sensor}{' with --set' if args.set else ''})")
    return 0
