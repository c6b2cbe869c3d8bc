"""``spikesim info PATH``: what a spike file holds (HDF5 file or folder, or PKU .dat)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from spikesim.commands._io_common import add_source_options, resolve_path, source_from_args

__all__ = ["register", "describe", "run"]


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "info", help="describe a spike file (.h5 file, dataset folder or root, or .dat)",
        description="Shape, readouts, duration, CFA, configuration, firing-rate statistics, "
                    "ground-truth readouts and the noise and motion labels (those spikejdd "
                    "evaluate groups by) of a spikesim HDF5 file, a dataset folder or a .dat.",
    )
    p.add_argument("path", help="a .h5 file, a dataset folder or root, or a .dat capture")
    p.add_argument("--all", action="store_true", help="describe every sequence of a folder")
    p.add_argument("--stats-readouts", type=int, default=4096,
                   help="readouts used for firing-rate statistics (default 4096)")
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    add_source_options(p)
    p.set_defaults(func=run)


def describe(src, stats_readouts: int = 4096) -> dict:
    """JSON-able description of one Sequence or DatFile; an HDF5 sequence's has its
    ``labels`` (noise and motion, :func:`spikesim.io.labels.sequence_labels`)."""
    from spikesim.io.dat import DatFile
    from spikesim.io.labels import sequence_labels
    from spikesim.io.source import firing_rate_stats

    meta = src.meta
    info = {
        "name": src.name, "path": str(src.path),
        "kind": "dat" if isinstance(src, DatFile) else "h5",
        "shape": [src.n_readouts, src.height, src.width], "readouts": src.n_readouts,
        "height": src.height, "width": src.width, "cfa": src.cfa or "mono",
        "clock_hz": src.clock_hz or None,
        "duration_s": src.duration_s if src.clock_hz else None,
        "gt_index": [int(i) for i in src.gt_index], "clean_twin": bool(src.has_clean),
        "firing_rate": firing_rate_stats(src, stats_readouts),
    }
    if isinstance(src, DatFile):
        info.update(flip=src.flip, head_columns=src.head_columns,
                    stored_width=src.stored_width, size_guess=src.guess_message)
    else:
        info.update(seed=meta.get("seed"), sensor=meta.get("sensor"), scene=meta.get("scene"),
                    format_version=src.format_version,
                    spikesim_version=meta.get("spikesim_version"),
                    clip=(meta.get("dataset") or {}).get("clip"),
                    labels=sequence_labels(meta))  # what `spikejdd evaluate` groups by
    return info


def clip_line(clip: dict) -> str:
    """One line on the video clip a dataset sequence was made from: video, start time,
    crop box and the motion measured inside the crop (pixels per readout)."""
    crop = clip.get("crop")
    where = (f"crop top {crop[0]} left {crop[1]}, {crop[2]}x{crop[3]} px" if crop
             else "whole frame")
    motion = clip.get("motion_px_per_readout") or {}
    return (f"video {clip.get('video')} from {clip.get('start_s', 0.0):.6g} s, {where}; "
            f"motion median {motion.get('median', 0.0):.3g}, p95 {motion.get('p95', 0.0):.3g} "
            f"px/readout ({motion.get('pairs', 0)} frame pairs)")


def _text(info: dict) -> str:
    fr = info["firing_rate"]
    dur = f"{info['duration_s']:.6g} s" if info["duration_s"] is not None else "unknown (no clock)"
    gt = info["gt_index"]
    gts = ", ".join(map(str, gt[:12])) + (f", ... ({len(gt)} in all)" if len(gt) > 12 else "")
    lines = [
        f"{info['name']}  ({info['kind']}: {info['path']})",
        f"  shape      {info['readouts']} readouts x {info['height']} x {info['width']} (T, H, W)",
        f"  duration   {dur}" + (f" at {info['clock_hz']:g} Hz" if info["clock_hz"] else ""),
        f"  cfa        {info['cfa']}",
        f"  firing     mean {fr['mean']:.4f}, p01 {fr['p01']:.4f}, p99 {fr['p99']:.4f}, "
        f"max {fr['max']:.4f} spikes/readout; silent pixels {fr['silent_fraction']:.2%} "
        f"(first {fr['readouts']} readouts)",
        f"  gt readouts {gts or 'none'}",
    ]
    if info["kind"] == "dat":
        lines.append(f"  stored     width {info['stored_width']}, head columns dropped "
                     f"{info['head_columns']}, flip {info['flip']}")
        if info["size_guess"]:
            lines.append(f"  size       {info['size_guess']}")
    else:
        lines.append(f"  clean twin {'yes' if info['clean_twin'] else 'no'}; seed {info['seed']}; "
                     f"format version {info['format_version']}")
        labels = info["labels"]
        lines.append(f"  labels     noise {labels['noise']}, motion {labels['motion']} "
                     "(the groups of spikejdd evaluate)")
        if info.get("clip"):
            lines.append(f"  clip       {clip_line(info['clip'])}")
        for key in ("sensor", "scene"):
            if info.get(key) is not None:
                lines.append(f"  {key:<10} {json.dumps(info[key], sort_keys=True)}")
    return "\n".join(lines)


def run(args) -> int:
    from spikesim._validate import check_int
    from spikesim.io.index import open_dataset
    from spikesim.io.source import is_dat

    check_int("--stats-readouts", args.stats_readouts, 1, unit="readouts")
    path = args.path if is_dat(args.path) else resolve_path(args.path, args.split)
    note = None
    if args.all and not is_dat(args.path):
        sources = list(open_dataset(path))
    else:
        sources = [source_from_args(args, path)]
        if not is_dat(args.path) and Path(path).is_dir():
            names = list(open_dataset(path).names)
            name = getattr(sources[0], "name", None)
            if len(names) > 1 and name in names:
                note = (f"(sequence {names.index(name) + 1} of {len(names)} in {path}: "
                        "--sequence picks another, --all describes every one)")
    infos = [describe(s, args.stats_readouts) for s in sources]
    if args.json:
        print(json.dumps(infos if len(infos) > 1 else infos[0], indent=1, default=str))
        if note:
            print(note, file=sys.stderr)
    else:
        print("\n\n".join(_text(i) for i in infos))
        if note:
            print(note)
    return 0
