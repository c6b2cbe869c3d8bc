"""Dataset generation throughput: serial, 2 local processes, 2-worker Dask LocalCluster.

Builds the same manifest (default: ``builtin:sjdd-train-small`` limited to 12
sequences) three times into temporary folders and reports sequences per
minute, pixel-readouts per second, and where the worker time went (scene
rendering, optical flow, kernel, writing; summed over sequences).

Run::

    .venv/bin/python benchmarks/bench_dataset.py [--manifest builtin:NAME] [--limit N]
    .venv/bin/python benchmarks/bench_dataset.py --realistic [--repeats 3] [--count 12]
    .venv/bin/python benchmarks/bench_dataset.py --realistic --baseline DIR [--repeats 3]

Writes ``benchmarks/results/dataset.json`` and ``dataset.md``; ``--realistic``
(720p REDS-shaped video -> 256x256 clips with paper noise, serial and 2
workers, each against its ``--dry-run`` estimate) writes
``dataset_realistic.json`` and ``dataset_realistic.md``; ``--baseline DIR``
(a folder with another version's ``spikesim`` package) times the realistic
builds of both versions in fresh processes, alternating, and writes
``dataset_realistic_ab.{json,md}``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
from pathlib import Path

from spikesim.dataset import build_dataset, load_manifest

RESULTS = Path(__file__).parent / "results"

#: 1-minute load average when the benchmark started (other jobs on the shared cores).
LOAD_AT_START = os.getloadavg()[0]


def _texture(h: int, w: int, seed: int):
    """Smooth random 8-bit texture (structure at several scales: flow finds it)."""
    import cv2
    import numpy as np

    rng = np.random.default_rng(seed)
    acc = np.zeros((h, w, 3), np.float32)
    for cell, amp in ((6, 0.45), (30, 0.35), (150, 0.2)):
        small = rng.random((h // cell + 2, w // cell + 2, 3)).astype(np.float32)
        acc += amp * cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)
    return np.clip(acc * 255, 0, 255).astype(np.uint8)


def make_reds(root: Path, videos: int = 2, frames: int = 12, px_per_frame=(12, 6)) -> Path:
    """REDS-shaped ``root/<video>/%08d.png``: 1280x720 frames of a panning texture."""
    import cv2

    for v in range(videos):
        step = px_per_frame[v % len(px_per_frame)]
        big = _texture(720, 1280 + step * frames, v)
        folder = root / f"{v:03d}"
        folder.mkdir(parents=True, exist_ok=True)
        for i in range(frames):
            x = step * (frames - i)
            cv2.imwrite(str(folder / f"{i:08d}.png"), big[:, x : x + 1280],
                        [cv2.IMWRITE_PNG_COMPRESSION, 1])
    return root


def realistic_manifest(root: Path, count: int) -> dict:
    """720p REDS-shaped root -> ``count`` random 256x256 clips per video, GN or GPN noise."""
    return {
        "dataset": {"name": "realistic", "seed": 0, "size": [256, 256], "window": 39,
                    "samples_per_sequence": 3},
        "sensor": {"preset": "ideal"},
        "noise": [{"mode": "paper", "label": "GN", "sigma_g": {"uniform": [0, 15]}},
                  {"mode": "paper", "label": "GPN", "sigma_g": {"uniform": [0, 5]},
                   "sigma_p": {"uniform": [0, 5]}}],
        "sources": [{"kind": "reds", "path": str(root), "count": count,
                     "crop": {"size": [256, 256], "position": "random"}}]}


def one_build(root: str, out: str, workers: int, count: int, limit: int | None) -> None:
    """One build in this (fresh) process; prints its seconds and stage split as JSON."""
    from spikesim.dataset import parse_manifest

    s = build_dataset(parse_manifest(realistic_manifest(Path(root), count)), out,
                      workers=workers, progress=False, limit=limit)
    print(json.dumps({"seconds": s.seconds, "done": s.done, "failed": s.failed,
                      "stage_seconds_per_seq": {k: v / max(s.done, 1) for k, v in
                                                s.seconds_by_stage().items()}}))


def compare(baseline: Path, repeats: int, count: int, out: Path) -> None:
    """The realistic case with the spikesim package in ``baseline`` and with this one.

    Every build runs in a fresh process, as ``spikesim dataset`` would (start-up,
    kernel loading and imports included), the two packages alternating within
    each repeat, so a change of the machine's load hits both alike.
    """
    import shutil
    import statistics
    import subprocess
    import sys

    here = str(Path(__file__).resolve().parents[1])
    variants = {"baseline": str(baseline.resolve()), "this": here}
    rows = []
    with tempfile.TemporaryDirectory(prefix="spikesim-bench-ab-") as tmp:
        root = make_reds(Path(tmp) / "REDS")

        def build(variant: str, workers: int, limit: int | None = None) -> dict:
            env = {**os.environ, "PYTHONPATH": variants[variant]}
            target = Path(tmp) / "out"
            shutil.rmtree(target, ignore_errors=True)
            args = [sys.executable, __file__, "--one-build", str(root), str(target),
                    str(workers), "--count", str(count)]
            if limit is not None:
                args += ["--limit", str(limit)]
            res = subprocess.run(args, env=env, capture_output=True, text=True, check=True)
            return json.loads(res.stdout.strip().splitlines()[-1])

        for variant in variants:  # loads (or, for a fresh copy, compiles) its kernels
            build(variant, 1, limit=2)
        for rep in range(repeats):
            for workers in (1, 2):
                for variant in variants:
                    r = build(variant, workers)
                    rows.append({"repeat": rep, "workers": workers, "variant": variant,
                                 "load": os.getloadavg()[0], **r,
                                 "sequences_per_min": 60.0 * r["done"] / r["seconds"]})
                    print(json.dumps(rows[-1]), flush=True)
    ratios = {w: [b["seconds"] / a["seconds"] for a, b in
                  zip([r for r in rows if r["workers"] == w and r["variant"] == "this"],
                      [r for r in rows if r["workers"] == w and r["variant"] == "baseline"],
                      strict=True)] for w in (1, 2)}
    lines = ["# Dataset generation, realistic case: this version against a baseline", "",
             f"The realistic case (`--realistic`, {2 * count} clips); every build in a fresh "
             "process like `spikesim dataset` (start-up and kernel loading included), the two "
             f"versions alternating. Load average at the start {LOAD_AT_START:.1f} (other jobs "
             f"share the cores). Command: `python benchmarks/bench_dataset.py --realistic "
             f"--baseline {baseline} --repeats {repeats} --count {count}`.", "",
             "| workers | baseline seq/min | this seq/min | speed-up (same repeat) |",
             "|---|---:|---:|---:|"]
    for w in (1, 2):
        med = {v: statistics.median(r["sequences_per_min"] for r in rows
                                    if r["workers"] == w and r["variant"] == v)
               for v in variants}
        lines.append(f"| {w} | {med['baseline']:.0f} | {med['this']:.0f} | "
                     f"{statistics.median(ratios[w]):.2f} [{min(ratios[w]):.2f}, "
                     f"{max(ratios[w]):.2f}] |")
    lines.append("")
    save(out, "dataset_realistic_ab", {"baseline": str(baseline), "rows": rows,
                                       "speedup": ratios, "load_at_start": LOAD_AT_START},
         "\n".join(lines))


def realistic(repeats: int, count: int, out: Path, videos: int = 2) -> None:
    """720p REDS-shaped video -> 256x256 clips with paper noise, serial and 2 workers."""
    import statistics

    from spikesim.dataset import estimate_dataset, parse_manifest

    rows = []
    with tempfile.TemporaryDirectory(prefix="spikesim-bench-reds-") as tmp:
        root = make_reds(Path(tmp) / "REDS", videos=videos)
        manifest = parse_manifest(realistic_manifest(root, count))
        # one untimed build loads the kernels and fills the OS file cache
        build_dataset(manifest, Path(tmp) / "warm", limit=2, progress=False)
        for rep in range(repeats):
            for label, kw in (("serial", {"workers": 1}), ("2 local processes", {"workers": 2})):
                est = estimate_dataset(manifest, calibration_tasks=3, **kw)
                s = build_dataset(manifest, Path(tmp) / f"{rep}-{kw['workers']}", progress=False,
                                  **kw)
                rows.append({"repeat": rep, "executor": label, "sequences": s.done,
                             "failed": s.failed, "seconds": s.seconds,
                             "sequences_per_min": 60.0 * s.done / s.seconds,
                             "estimated_seconds": est["estimated_seconds"],
                             "estimate_ratio": est["estimated_seconds"] / s.seconds,
                             "startup_seconds_estimated": est["startup_seconds"],
                             "stage_seconds_per_seq": {k: v / max(s.done, 1) for k, v in
                                                       s.seconds_by_stage().items()}})
                print(json.dumps(rows[-1]), flush=True)
    summary = {}
    for label in ("serial", "2 local processes"):
        mine = [r for r in rows if r["executor"] == label]
        rates = [r["sequences_per_min"] for r in mine]
        summary[label] = {
            "sequences_per_min_median": statistics.median(rates),
            "sequences_per_min_range": [min(rates), max(rates)],
            "estimate_ratio_range": [min(r["estimate_ratio"] for r in mine),
                                     max(r["estimate_ratio"] for r in mine)],
            "startup_seconds_median": statistics.median(r["startup_seconds_estimated"]
                                                        for r in mine),
            "stage_seconds_per_seq_median": {
                k: statistics.median(r["stage_seconds_per_seq"][k] for r in mine)
                for k in mine[0]["stage_seconds_per_seq"]}}
    speedups = [b["sequences_per_min"] / a["sequences_per_min"] for a, b in
                zip(rows[0::2], rows[1::2], strict=True)]
    result = {"machine": f"{platform.machine()}, {os.cpu_count()} cores, load average "
                         f"{LOAD_AT_START:.1f} at the start (other jobs share the cores)",
              "videos": videos, "sequences": videos * count, "rows": rows, "summary": summary,
              "speedup_2_workers": speedups,
              "command": f"python benchmarks/bench_dataset.py --realistic --repeats {repeats} "
                         f"--count {count}" + (f" --videos {videos}" if videos != 2 else "")}
    save(out, "dataset_realistic", result, realistic_markdown(result))


def save(out: Path, name: str, result: dict, markdown: str) -> None:
    """Write ``out/NAME.json`` and ``out/NAME.md`` and print the Markdown."""
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{name}.json").write_text(json.dumps(result, indent=2))
    (out / f"{name}.md").write_text(markdown)
    print(markdown)


def realistic_markdown(r) -> str:
    lines = [
        "# Dataset generation, realistic case: 720p video -> 256x256 clips, paper noise",
        "",
        f"REDS-shaped folder of {r.get('videos', 2)} videos (1280x720 PNG, 24 fps, 12 frames, "
        f"a texture panning 12 or 6 px per frame); {r['sequences']} clips "
        f"({r['sequences'] // r.get('videos', 2)} per video), "
        "random 256x256 crops and start times, GN or GPN noise, 3 windows of 39 readouts "
        "(117 readouts at 20 kHz, 7.7e6 pixel-readouts per clip).",
        f"Machine: {r['machine']}. Command: `{r['command']}`. Medians over the repeats, range "
        "in brackets; stage times are per sequence inside the workers (scene = decoding and "
        "cropping, flow = optical flow, warp = interpolated key frames, kernel = simulation, "
        "write = HDF5). Estimate = `--dry-run` seconds / real seconds of the same run; "
        "start-up = the dry run's measured start-up of the executor (spawning the workers, "
        "imports, kernel loading), included in the wall time of every build.",
        "",
        "| executor | sequences/min | estimate / real | start-up s | scene s | flow s | warp s |"
        " kernel s | write s |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for label, s in r["summary"].items():
        st = s["stage_seconds_per_seq_median"]
        lo, hi = s["sequences_per_min_range"]
        elo, ehi = s["estimate_ratio_range"]
        lines.append(f"| {label} | {s['sequences_per_min_median']:.0f} [{lo:.0f}, {hi:.0f}] | "
                     f"{elo:.2f}..{ehi:.2f} | {s['startup_seconds_median']:.1f} | "
                     f"{st['scene']:.3f} | {st['flow']:.3f} | "
                     f"{st['warp']:.3f} | {st['kernel']:.3f} | {st['write']:.3f} |")
    sp = r["speedup_2_workers"]
    lines += ["", "2 workers / serial in the same repeat: "
              + ", ".join(f"{x:.2f}" for x in sp) + ".", ""]
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--manifest", default="builtin:sjdd-train-small")
    ap.add_argument("--limit", type=int, default=48)
    ap.add_argument("--out", default=str(RESULTS))
    ap.add_argument("--realistic", action="store_true",
                    help="720p REDS-shaped video -> 256x256 clips, paper noise, serial and 2 "
                         "workers (writes dataset_realistic.{json,md})")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--count", type=int, default=12, help="clips per video (--realistic)")
    ap.add_argument("--videos", type=int, default=2, help="videos in the folder (--realistic)")
    ap.add_argument("--baseline", default=None, metavar="DIR",
                    help="with --realistic: a folder holding another spikesim package to "
                         "compare with, build by build in fresh processes (writes "
                         "dataset_realistic_ab.{json,md}); copy the package with its "
                         "__pycache__ so that its numba cache is reused")
    ap.add_argument("--one-build", nargs=3, default=None, metavar=("ROOT", "OUT", "WORKERS"),
                    help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.one_build:
        root, target, workers = args.one_build
        one_build(root, target, int(workers), args.count,
                  args.limit if "--limit" in (argv or sys.argv) else None)
        return
    if args.realistic and args.baseline:
        compare(Path(args.baseline), args.repeats, args.count, Path(args.out))
        return
    if args.realistic:
        realistic(args.repeats, args.count, Path(args.out), args.videos)
        return
    manifest = load_manifest(args.manifest)
    configs = [("serial", {"workers": 1}), ("2 local processes", {"workers": 2}),
               ("Dask LocalCluster, 2 workers", {"dask_local": 2})]
    rows = []
    for label, kw in configs:
        with tempfile.TemporaryDirectory(prefix="spikesim-bench-") as tmp:
            s = build_dataset(manifest, tmp, limit=args.limit, progress=False, **kw)
        stages = s.seconds_by_stage()
        rows.append({
            "executor": label, "sequences": s.done, "failed": s.failed, "seconds": s.seconds,
            "sequences_per_min": 60.0 * s.done / s.seconds,
            "px_readouts_per_s": s.px_readouts / s.seconds,
            "mib": s.bytes / 2**20,
            "stage_seconds": stages,
        })
        print(json.dumps(rows[-1]), flush=True)
    result = {
        "machine": f"{platform.machine()}, {os.cpu_count()} cores ({platform.platform()})",
        "manifest": args.manifest, "limit": args.limit, "size": list(manifest.size),
        "readouts_per_sequence": manifest.n_readouts, "rows": rows,
        "command": f"python benchmarks/bench_dataset.py --manifest {args.manifest} "
                   f"--limit {args.limit}",
    }
    save(Path(args.out), "dataset", result, to_markdown(result))


def to_markdown(r) -> str:
    lines = [
        f"# Dataset generation: {r['manifest']} (first {r['limit']} sequences, "
        f"{r['size'][0]}×{r['size'][1]}, {r['readouts_per_sequence']} readouts each)",
        "",
        f"Machine: {r['machine']}. Command: `{r['command']}`.",
        "Stage times are summed over sequences inside the workers (scene = rendering /",
        "interpolation of key frames, flow = optical flow of video sources, kernel = simulation",
        "driver and numba kernel, write = HDF5 writing).",
        "",
        "| executor | sequences | wall s | sequences/min | px·readouts/s | MiB |"
        " scene s | flow s | warp s | kernel s | write s |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for row in r["rows"]:
        st = row["stage_seconds"]
        lines.append(
            f"| {row['executor']} | {row['sequences']} | {row['seconds']:.1f} | "
            f"{row['sequences_per_min']:.1f} | {row['px_readouts_per_s']:.3g} | {row['mib']:.1f} | "
            f"{st['scene']:.1f} | {st['flow']:.1f} | {st['warp']:.1f} | {st['kernel']:.1f} | "
            f"{st['write']:.1f} |")
    lines += ["", "Each spawned process (pool or Dask worker) pays its own start-up (interpreter,",
              "imports, numba cache load) once; parallel executors win only when the sequences",
              "take longer than that.", ""]
    return "\n".join(lines)


if __name__ == "__main__":
    main()
