"""Command line ``spikejdd``: a thin layer over :mod:`spikejdd.evaluate`.

``spikejdd evaluate --data DIR --methods a,b,c [--out STEM] [--device D] [--threads N]``
``spikejdd evaluate --sweep [--methods ...] [--size 64x96] [--out STEM]``
``spikejdd methods``
``spikejdd train --data DIR [--config run.json] [--model lite] [--steps N] ...``
``spikejdd reconstruct INPUT --methods sjdd,tfp+malvar2004 --out DIR`` (HDF5 or ``.dat``;
sRGB PNGs per method and a side-by-side panel per readout)

Method names: anything :meth:`spikejdd.registry.Registry.get` resolves —
registered names, pipelines, ``package.module:function``, ``sjdd@path/best.pt``,
entry points of the group ``spikejdd.methods``.
"""

from __future__ import annotations

import argparse
import os
import shlex
import sys

from spikesim.cli_guard import (
    OneLineParser,
    as_option,
    check_cli_numbers,
    debug_requested,
    parse_size,
    run_guarded,
)
from spikesim.errors import SpikeSimError, SpikeSimValueError, bad_value

__all__ = ["main", "build_parser"]


def _size(text: str) -> tuple[int, int]:
    try:
        return parse_size(text, "--size", "64x96")
    except SpikeSimValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(prog="spikejdd", description="Spike-camera JDD reconstruction.")
    p.add_argument("--debug", action="store_true",
                   help="show Python tracebacks instead of one-line errors (anywhere on the "
                        "line; or set SPIKESIM_DEBUG=1)")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    ev = sub.add_parser("evaluate", help="score methods (PSNR/SSIM) and time them")
    ev.add_argument("--data", help="spikesim HDF5 file, folder or dataset root")
    ev.add_argument("--split", help="split folder of a dataset root (e.g. eval)")
    ev.add_argument("--sweep", action="store_true",
                    help="Table-1-shaped sweep on sets simulated on the fly")
    ev.add_argument("--methods", default=None,
                    help="comma-separated methods: names, pipelines, package.module:function, "
                         "sjdd@path/to/best.pt (default: the standard pipelines)")
    ev.add_argument("--context", type=int, default=None,
                    help="readouts given to each method (default 41, or the most that fit "
                         "around --per-sequence GT readouts of shorter sequences)")
    ev.add_argument("--per-sequence", type=int, default=1,
                    help="GT frames per sequence, spread evenly over its GT readouts "
                         "(default 1: the first that fits; a large N scores them all)")
    ev.add_argument("--repeats", type=int, default=3, help="timed calls per frame (median)")
    ev.add_argument("--size", type=_size, default=(64, 96), help="sweep frame size HxW")
    ev.add_argument("--frames-per-scene", type=int, default=2)
    ev.add_argument("--seed", type=int, default=0)
    ev.add_argument("--out", default="evaluation",
                    help="output path stem (.json/.md/.png), or a folder to hold evaluation.*")
    ev.add_argument("--quiet", action="store_true", help="no progress bars")
    _runtime_options(ev)
    _ensemble_option(ev)
    ev.add_argument("--panels", type=int, default=6,
                    help="image panels (GT and every method, same crop) in the report")
    sub.add_parser("methods", help="list reconstruction methods")
    dm = sub.add_parser("demo", help="the main job on built-in scenes: build a small dataset, "
                                     "preview it, reconstruct it and write report.md")
    dm.add_argument("--out", default="demo_out", help="output folder (default: demo_out)")
    dm.add_argument("--size", type=int, default=None, help="frame side in pixels (default 256)")
    dm.add_argument("--limit", type=int, default=None, help="only the first N sequences")
    dm.add_argument("--methods", default=None,
                    help="comma-separated methods (default: four classical pipelines and "
                         "SJDD-Net: sjdd@sjdd-lite on a CPU, sjdd on CUDA)")
    _runtime_options(dm)
    _train_parser(sub)
    _reconstruct_parser(sub)
    return p


def _runtime_options(p) -> None:
    p.add_argument("--device", default=None,
                   help="torch device for learned methods: cpu (default), cuda, cuda:N")
    p.add_argument("--threads", type=int, default=None,
                   help="torch threads per process (default 1 on the CPU: measured faster, "
                        "benchmarks/results/threads.md)")


def _ensemble_option(p) -> None:
    p.add_argument("--ensemble", type=int, choices=(1, 2, 4), default=None,
                   help="forward passes of learned methods averaged over geometric views "
                        "(default: the method's own, 2 for sjdd; 1 is twice as fast)")


def _methods(text: str | None) -> list[str]:
    """``--methods``: the comma-separated names; [] when the option is not given
    (the command's default), an error when it is given but names none."""
    if text is None:
        return []
    names = [m.strip() for m in text.split(",") if m.strip()]
    if not names:
        raise bad_value("--methods", text, "at least one method name, comma-separated "
                                           "(`spikejdd methods` lists them); leave --methods "
                                           "out for the default")
    return names


def _train_parser(sub) -> None:
    # defaults live in spikejdd.train.TrainConfig (not imported here: torch loads lazily)
    tr = sub.add_parser("train", help="train SJDD-Net on spikesim HDF5 data")
    tr.add_argument("--data", help="training HDF5 file or folder")
    tr.add_argument("--config", help="JSON file of TrainConfig keys (flags given override it)")
    tr.add_argument("--out", help="run folder (default runs/sjdd)")
    tr.add_argument("--eval-data", help="evaluation HDF5 file or folder (default: --data)")
    tr.add_argument("--split", help="split folder of a --data dataset root (e.g. train)")
    tr.add_argument("--eval-split", help="split folder of an --eval-data dataset root")
    tr.add_argument("--model", help="preset: default (published widths), lite, published")
    tr.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE",
                    help="override a model field, e.g. --set stages=2 (JSON values)")
    for name, typ, default in (
            ("steps", int, 10_000), ("batch_size", int, 8), ("crop", int, 64), ("lr", float, 5e-4),
            ("lr_step", int, None), ("lr_step_epochs", int, 50), ("epoch_steps", int, 240),
            ("gamma", float, 0.8), ("noise_weight", float, 0.0),
            ("eval_every", int, 500), ("eval_frames", int, 12), ("checkpoint_every", int, 500),
            ("seed", int, 0), ("workers", int, 0), ("time_limit_min", float, None),
            ("threads", int, None)):
        tr.add_argument("--" + name.replace("_", "-"), type=typ, dest=name,
                        help=f"default {default}")
    tr.add_argument("--device", help="auto (default), cpu, cuda, cuda:1")
    tr.add_argument("--no-amp", action="store_true", help="no mixed precision on CUDA")
    tr.add_argument("--no-flips", action="store_true", help="no random flips")
    tr.add_argument("--resume", help="checkpoint to resume from, or 'auto' (<out>/last.pt)")
    tr.add_argument("--init", help="weights to start from (a shipped name such as sjdd-lite, or "
                                   "a checkpoint), with a fresh schedule; ignored on resume")
    tr.add_argument("--online", action="store_true",
                    help="simulate every sample in the data loader (no --data needed)")
    tr.add_argument("--device-sim", action="store_true",
                    help="with --online: render and simulate each batch on the training device "
                         "(spikesim's torch backend; no loader processes, no numba)")
    tr.add_argument("--clip", action="append", default=[], dest="clips", metavar="PATH",
                    help="a video file or frame folder some --online samples are cut from "
                         "(repeatable)")
    tr.add_argument("--validation", choices=("auto", "files", "sweep"),
                    help="files (--eval-data/--data) or the held-out sweep (default: sweep when "
                         "--online)")
    tr.add_argument("--channels-last", action="store_true", help="channels_last memory format")
    tr.add_argument("--synthesize", type=int, metavar="N",
                    help="first write N procedural sequences into --data (when it has none)")
    tr.add_argument("--quiet", action="store_true",
                    help="no progress bar (a line per validation is still printed)")


def _reconstruct_parser(sub) -> None:
    rc = sub.add_parser("reconstruct", help="reconstruct frames of an HDF5 or .dat stream")
    rc.add_argument("input", help="spikesim .h5 file, dataset folder or root, or .dat capture")
    rc.add_argument("--split", help="split folder of a dataset root")
    rc.add_argument("--method", "--methods", dest="method", default="sjdd",
                    help="comma-separated methods (default sjdd); several give side-by-side "
                         "panels")
    rc.add_argument("--out", required=True, help="output folder for PNGs")
    rc.add_argument("--weights", help="sjdd weights: a shipped name or a checkpoint path")
    rc.add_argument("--centers", help="readouts to reconstruct, e.g. 19,59 or 19:200:20 or "
                                      "30,100:180:40 (default: GT readouts for .h5, the "
                                      "middle for .dat)")
    rc.add_argument("--context", type=int, default=41, help="readouts given to the method")
    rc.add_argument("--cfa", help=".dat: Bayer pattern of a colour sensor (RGGB, BGGR, GRBG, "
                                  "GBRG; default mono, as a .dat records none)")
    rc.add_argument("--height", type=int, help=".dat frame height (default: guessed from the "
                                               "file size among known sensors, with a warning)")
    rc.add_argument("--width", type=int, help=".dat stored width (default: guessed, as --height)")
    rc.add_argument("--partial", choices=("error", "drop"), default="error",
                    help=".dat whose size is not whole frames: error (default), or drop the "
                         "last partial frame")
    rc.add_argument("--head-columns", type=int, default=0, help=".dat head columns to drop")
    rc.add_argument("--no-flip", action="store_true",
                    help=".dat stored top-down (default: upside down, PKU convention)")
    rc.add_argument("--rate", type=float, help="full_scale_rate (default: file's, or 0.6)")
    _runtime_options(rc)
    _ensemble_option(rc)
    rc.add_argument("--quiet", action="store_true", help="no progress bar")


def _evaluate(args) -> int:
    from spikejdd import evaluate
    from spikejdd.pipelines import standard_pipelines
    from spikejdd.registry import get_method

    methods = _methods(args.methods) or standard_pipelines()
    if args.sweep == bool(args.data):
        print("spikejdd evaluate: error: give exactly one of --data DIR or --sweep",
              file=sys.stderr)
        return 2
    for m in methods:  # every name checked before any work
        get_method(m)
    device = _configure(args)
    outputs: dict = {}
    if args.sweep:
        frames: list = []
        result = evaluate.sweep(methods, size=args.size, context=args.context or 41,
                                frames_per_scene=args.frames_per_scene, repeats=args.repeats,
                                seed=args.seed, progress=not args.quiet, outputs=outputs,
                                device=device, frames_out=frames, ensemble=args.ensemble,
                                keep_going=not getattr(args, "debug", False))
    else:
        from spikesim.io import resolve_dataset

        data = resolve_dataset(args.data, args.split)
        frames = evaluate.frames_from_dataset(data, args.context, args.per_sequence)
        result = evaluate.run(frames, methods, repeats=args.repeats, progress=not args.quiet,
                              outputs=outputs, device=device, ensemble=args.ensemble,
                              keep_going=not getattr(args, "debug", False))
    command = "spikejdd " + " ".join(shlex.quote(a) for a in args.argv)
    paths = evaluate.write_report(result, methods, args.out, command=command, frames=frames,
                                  outputs=outputs, panels=args.panels)
    for m in evaluate.succeeded(result, methods):
        e = result["summary"][m]["all"]
        used = f"  {evaluate._windows(e)} readouts" if e.get("windows") else ""
        print(f"{m:32s} PSNR[linear] {e['PSNR[linear]']:6.2f} dB  "
              f"SSIM-gauss11[linear] {e['SSIM-gauss11[linear]']:.4f}  "
              f"{e['ms_per_frame']:8.1f} ms/frame{used}")
    print("wrote " + ", ".join(str(p) for p in paths))
    for message in (result.get("failed") or {}).values():
        print(f"spikejdd evaluate: error: {message} (the other methods' results are in "
              f"{paths[1]}; --debug stops at it with the traceback)", file=sys.stderr)
    return 1 if result.get("failed") else 0


def _configure(args) -> str:
    """Validate ``--device`` and set torch's threads (default 1 on the CPU); returns the device.
    Torch is imported only when a learned method or an explicit setting needs it."""
    from spikejdd.runtime import check_device, set_threads

    if args.device is None and args.threads is None and "torch" not in sys.modules:
        return "cpu"
    device = check_device(args.device)
    set_threads(args.threads, device)
    return device


#: ``train`` flags that set the TrainConfig field of their name.
_TRAIN_FIELDS = ("data", "out", "eval_data", "model", "steps", "batch_size", "crop", "lr",
                 "lr_step", "gamma", "noise_weight", "eval_every", "eval_frames",
                 "checkpoint_every", "seed", "workers", "time_limit_min", "device", "resume",
                 "init", "threads", "lr_step_epochs", "epoch_steps", "validation")


def _train(args) -> int:
    import json
    from pathlib import Path

    from spikejdd.train import TrainConfig, synthesize, train

    cfg = {}
    if args.config:
        try:
            cfg = json.loads(Path(args.config).read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise bad_value("--config", args.config, "an existing JSON file") from None
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise bad_value("--config", args.config, f"a JSON file of TrainConfig keys ({exc})") \
                from None
        if not isinstance(cfg, dict):
            raise bad_value("--config", args.config, "a JSON object of TrainConfig keys")
    for name in _TRAIN_FIELDS:
        v = getattr(args, name, None)
        if v is not None:
            cfg[name] = v
    overrides = dict(cfg.get("model_overrides", {}))
    for item in args.set:
        key, sep, value = item.partition("=")
        if not sep:
            print(f"spikejdd train: error: --set {item!r}: expected FIELD=VALUE", file=sys.stderr)
            return 2
        try:
            overrides[key.strip()] = json.loads(value)
        except json.JSONDecodeError:
            overrides[key.strip()] = value
    if overrides:
        cfg["model_overrides"] = overrides
    if args.no_amp:
        cfg["amp"] = False
    if args.no_flips:
        cfg["flips"] = False
    if args.quiet:
        cfg["progress"] = False
    if args.online:
        cfg["online"] = True
    if args.device_sim:
        cfg["device_sim"] = True
    if args.clips:
        cfg["clips"] = list(args.clips)
    if args.channels_last:
        cfg["channels_last"] = True
    if not cfg.get("data") and not cfg.get("online"):
        print("spikejdd train: error: give --data DIR or --online (or a --config with 'data')",
              file=sys.stderr)
        return 2
    if args.synthesize and cfg.get("data"):
        data = Path(cfg["data"])
        if not (data.is_dir() and any(data.glob("*.h5"))):
            synthesize(data, n_sequences=args.synthesize, progress=not args.quiet)
    from spikesim.io import resolve_dataset

    for key, split, flag in (("data", args.split, "--split"),
                             ("eval_data", args.eval_split, "--eval-split")):
        if cfg.get(key) and (split or Path(cfg[key]).exists()):  # a dataset root -> its split
            try:
                cfg[key] = str(resolve_dataset(cfg[key], split))
            except SpikeSimError as exc:  # name this option's split flag
                named = as_option(exc, {"split": flag})
                raise type(named)(str(named).replace("--split NAME", f"{flag} NAME")) from None
    flags = {name: "--" + name.replace("_", "-") for name in _TRAIN_FIELDS
             if getattr(args, name, None) is not None}
    if args.init:  # the weights resolver names its parameter ``weights``
        flags["weights"] = "--init"
    if args.clips:
        flags["clips"] = "--clip"
    if args.device_sim:
        flags["device_sim"] = "--device-sim"
    try:
        config = TrainConfig.from_dict(cfg)
        config.validate()
        if (config.validation_kind() == "files" and not config.eval_data
                and os.environ.get("RANK", "0") == "0"):
            print("spikejdd train: note: validating on the training data (--eval-data names "
                  "a held-out set)", file=sys.stderr)
        summary = train(config)
    except SpikeSimError as exc:  # name the flag the user gave, not the config field
        raise as_option(exc, flags) from None
    if os.environ.get("RANK", "0") != "0":
        return 0
    done, first = summary["steps_done"], summary["resumed_at_step"]
    this_call = (f" ({done - first} after resuming at step {first}, "
                 f"{summary['minutes_this_call']:.1f} min)" if first else "")
    steps = f"{done} step{'' if done == 1 else 's'}"
    print(f"trained {steps} in {summary['minutes']:.1f} min{this_call} (and "
          f"{summary['setup_minutes']:.1f} min of set-up); best eval PSNR "
          f"{summary['best_psnr']:.2f} dB; run folder {cfg.get('out', 'runs/sjdd')}")
    return 0


def _centers(text: str | None, default: list[int], n: int) -> list[int]:
    """``--centers``: readouts and ``start:stop[:step]`` ranges, comma-separated
    (``30,100:180:40``), in order, each once, each a readout of the ``n`` in the
    stream (checked here, before any work and any progress bar)."""
    if not text:
        return default
    centers: list[int] = []
    try:
        for item in (v.strip() for v in text.split(",")):
            if not item:
                continue
            parts = [int(v) for v in item.split(":")]
            if len(parts) > 3 or (len(parts) == 3 and parts[2] <= 0):
                raise ValueError
            centers += list(range(*parts)) if len(parts) > 1 else parts
    except ValueError:
        raise argparse.ArgumentTypeError(f"--centers {text!r}: expected readouts and "
                                         "start:stop[:step] ranges, e.g. 19,59 or "
                                         "30,100:180:40") from None
    centers = list(dict.fromkeys(centers))
    if not centers:
        raise bad_value("--centers", text, "at least one readout (start:stop:step with start < "
                                            "stop, or a list such as 19,59)")
    outside = [c for c in centers if not 0 <= c < n]
    if outside:
        shown = outside[0] if text.strip() == str(outside[0]) else text
        raise bad_value("--centers", shown,
                        f"readouts in [0, {n - 1}] (the stream has {n} readouts"
                        + (f"; {outside[0]} is outside)" if shown != outside[0] else ")"))
    return centers


def _reconstruct(args) -> int:
    """``spikejdd reconstruct``: on any failure, the PNGs this run wrote are
    removed again (and the output folder, when this run made it)."""
    import contextlib
    from pathlib import Path

    out = Path(args.out)
    made_folder = not out.exists()
    written: list = []
    used: dict = {}
    try:
        _reconstruct_into(args, written, used)
    except BaseException:
        for path in written:
            path.unlink(missing_ok=True)
        if made_folder:
            with contextlib.suppress(OSError):
                out.rmdir()  # only when empty
        raise
    for name, (window, given) in used.items():
        print(f"{name}: {window} readouts used (of {given} given)" if window is not None else
              f"{name}: {given} readouts given (the method does not say how many it uses)")
    print(f"wrote {len(written)} sRGB PNG(s) to {out}")
    return 0


def _reconstruct_into(args, written: list, used: dict) -> None:
    """Reconstruct ``args.input`` (every sequence of a dataset folder), appending
    each PNG written to ``written`` and each method's (window used, readouts given)
    to ``used``."""
    from pathlib import Path

    from tqdm import tqdm

    from spikejdd.evaluate import panel_image
    from spikejdd.registry import call_method, get_method
    from spikesim.estimate import window_bounds
    from spikesim.io import resolve_dataset
    from spikesim.srgb import linear_to_srgb8

    src = Path(args.input)
    out = Path(args.out)
    names = list(dict.fromkeys(_methods(args.method) or ["sjdd"]))  # each method once
    if args.weights and not any(m.lower() == "sjdd" for m in names):
        raise bad_value("--weights", args.weights, "used with sjdd in --methods (it names "
                                                    "SJDD-Net weights), or leave it out")
    if args.weights:  # --weights names the checkpoint of every sjdd in the list
        from spikejdd.models.pretrained import resolve_weights

        try:
            resolve_weights(args.weights)  # a missing file is refused before any work
        except SpikeSimValueError as exc:
            raise as_option(exc, {"weights": "--weights"}) from None
        names = [f"{m}@{args.weights}" if m.lower() == "sjdd" else m for m in names]
    methods = [get_method(m) for m in names]
    device = _configure(args)
    options = {"device": device}
    if args.ensemble is not None:
        options["ensemble"] = args.ensemble
    if src.suffix.lower() == ".dat":
        from spikejdd.capture import centred_window
        from spikesim.io import open_dat
        from spikesim.io.dat import HALF_SIZE

        if (args.height is None) != (args.width is None):
            raise SpikeSimValueError(HALF_SIZE)
        try:
            cap = open_dat(src, args.height, args.width, flip=not args.no_flip,
                           head_columns=args.head_columns, partial=args.partial, cfa=args.cfa)
        except SpikeSimValueError as exc:
            raise as_option(exc, {"head_columns": "--head-columns", "height": "--height",
                                  "width": "--width", "cfa": "--cfa"}) from None
        if args.cfa is None:
            print(f"spikejdd reconstruct: note: {src.name} records no colour filter: read as "
                  "monochrome (--cfa RGGB, or the sensor's pattern, for a Bayer capture)",
                  file=sys.stderr)
        n, cfa, rate = cap.n_readouts, cap.cfa, args.rate or 0.6
        centers = _centers(args.centers, [n // 2], n)

        def window(c, length):
            return centred_window(cap, c, length)[0]
    elif Path(src).is_dir():  # a dataset folder or root: every sequence of it
        from spikesim.io import open_dataset

        with open_dataset(src, args.split) as ds:
            files = [seq.path for seq in ds]
        for file in files:
            _reconstruct_into(argparse.Namespace(**{**vars(args), "input": str(file),
                                                    "split": None}), written, used)
        return
    else:
        from spikesim.cfa import normalize_cfa
        from spikesim.io import open_h5

        seq = open_h5(resolve_dataset(src, args.split))
        n = seq.n_readouts
        if args.cfa is not None and normalize_cfa(args.cfa) != normalize_cfa(seq.cfa):
            raise bad_value("--cfa", args.cfa, f"{seq.cfa or 'mono'}, the pattern {src.name} "
                            "records, or leave --cfa out (it is for .dat captures, which "
                            "record none)")
        cfa = seq.cfa
        rate = args.rate or float((seq.meta.get("sensor") or {}).get("full_scale_rate", 0.6))
        centers = _centers(args.centers, [int(g) for g in seq.gt_index] or [n // 2], n)

        def window(c, length):
            start, _ = window_bounds(n, c, length)
            return seq.read_window(start, length)

    out.mkdir(parents=True, exist_ok=True)
    length = min(args.context or 41, n)
    bar = tqdm(total=len(centers) * len(methods), desc="reconstruct", disable=args.quiet)
    for c in centers:
        start, _ = window_bounds(n, c, length)
        spikes = window(c, length)
        tiles = []
        for m in methods:
            bar.set_postfix_str(m.name)
            try:
                rgb = call_method(m, spikes, cfa, c - start, rate=rate, **options)
            except SpikeSimValueError as exc:
                if (cfa is None and args.cfa is None and src.suffix.lower() == ".dat"
                        and "cfa" in str(exc)):
                    exc.args = (f"{exc} (a .dat records no colour filter: give --cfa RGGB, "
                                "or the sensor's pattern, for a colour capture)",)
                raise
            used[m.name] = (m.window_for(length), length)
            tiles.append(rgb)
            img = linear_to_srgb8(rgb)
            path = out / f"{src.stem}_{_slug(m.name)}_{c:06d}.png"
            _write_png(path, img)
            written.append(path)
            bar.update()
        if len(methods) > 1:
            path = out / f"{src.stem}_panel_{c:06d}.png"
            panel = panel_image(tiles, [m.name for m in methods], crop=max(spikes.shape[1:]))
            _write_png(path, panel)
            written.append(path)
    bar.close()


def _slug(name: str) -> str:
    import re

    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("_")[:80]


def _write_png(path, rgb8) -> None:
    """Write an (H, W, 3) uint8 RGB image as PNG, atomically.  Encoded in memory and
    written by Python: OpenCV's imwrite crashes on some names (a lone surrogate)."""
    from pathlib import Path

    import cv2

    from spikesim.errors import SpikeSimFileError
    from spikesim.io.atomic import atomic_path

    ok, png = cv2.imencode(".png", rgb8[..., ::-1])
    if not ok:
        raise SpikeSimFileError(f"could not encode {str(path)!r} as PNG")
    with atomic_path(path) as tmp:
        Path(tmp).write_bytes(png.tobytes())


def _demo(args) -> int:
    from spikejdd.demo import run_demo
    from spikesim.commands.demo import print_sequences

    r = run_demo(args.out, size=args.size, limit=args.limit,
                 methods=_methods(args.methods) or None, device=args.device,
                 threads=args.threads, say_stages=True)
    print_sequences(r)
    rec = r["reconstruction"]
    if rec:
        print(f"\n{'method':24s} {'PSNR lin':>9s} {'SSIM lin':>9s} {'ms/frame':>9s}")
        for m in rec["methods"]:
            e = rec["summary"][m]["all"]
            print(f"{m:24s} {e['PSNR[linear]']:9.2f} {e['SSIM-gauss11[linear]']:9.4f} "
                  f"{e['ms_per_frame']:9.1f}")
    print(f"\nwrote {len(r['sequences'])} sequences and {args.out}/report.md")
    return 0


def _dispatch(parser, args) -> int:
    if args.command is None:
        parser.print_help()
        return 2
    check_cli_numbers(args)
    device = getattr(args, "device", None)
    if device is not None and str(device).strip().lower() != "auto":
        from spikejdd.runtime import check_device

        check_device(device, "--device")
    if args.command == "evaluate":
        return _evaluate(args)
    if args.command == "train":
        return _train(args)
    if args.command == "reconstruct":
        return _reconstruct(args)
    if args.command == "demo":
        return _demo(args)
    if args.command == "methods":
        from spikejdd import list_methods

        for name, desc in list_methods().items():
            print(f"{name:32s} {desc}")
        return 0
    parser.print_help()
    return 2


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    debug = debug_requested(argv)
    argv = [a for a in argv if a != "--debug"]
    parser = build_parser()
    args = parser.parse_args(argv)
    args.argv = argv  # recorded in reports as the command that made them
    args.debug = debug
    label = parser.command_parser(args).prog  # "spikejdd reconstruct", or "spikejdd"
    return run_guarded(label, lambda: _dispatch(parser, args), debug=debug)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
