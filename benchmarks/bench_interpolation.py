"""Speed against error of flow-based frame interpolation, scored on exact procedural scenes.

For each procedural scene × speed (slow / medium / fast, px/s) × video frame
rate, the scene is rendered as a video (linear float frames, ``as_video``),
then turned back into a continuous scene by :class:`spikesim.scenes.VideoScene`
with each flow method and each ``max_px``.  Its radiance at ``--samples``
times strictly inside every frame pair (what the simulator integrates: key
frames and linear blends between them) is compared with the exact radiance:

* PSNR in linear light (peak 1.0, clamp to [0, 1], no crop), pooled MSE over
  all sampled times of a configuration;
* seconds per output key frame = (static test + flow + interpolation time) /
  (key frames made, counting each video frame once).  OpenCV runs with one
  thread (``cv2.setNumThreads(1)``) so that timings on a shared machine are
  comparable.

Flow is computed once per pair and method and shared across ``max_px``
values (``shared_flows``); its time is charged to every ``max_px`` row.
Method ``none`` (plain linear blending between video frames) is the baseline.

End to end (``--e2e``, needs ``spikesim.simulate``): spike streams of the exact
scene and of its interpolated video (default flow, ``max_px = 1``, and plain
blending) are simulated with the same seed; TFP images (41-readout window,
rate 0.6) of the video streams are compared with those of the exact stream and
with the exact radiance seen through the Bayer mask.

Default run: 128×128 frames, 3 scenes × 3 speeds × 3 fps × 7 methods × 4
``max_px``, 2 frame pairs each, 8 samples per pair — a few minutes on 2 cores.

Usage::

    .venv/bin/python benchmarks/bench_interpolation.py            # full table + e2e
    .venv/bin/python benchmarks/bench_interpolation.py --quick    # smoke run
    .venv/bin/python benchmarks/bench_interpolation.py --crop-first   # crop vs full frame
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import sys
import time
from pathlib import Path

import machine
import numpy as np

RESULTS = Path(__file__).resolve().parent / "results"
SPEEDS = {"slow": 60.0, "medium": 240.0, "fast": 960.0}
SCENES = ["astronaut:pan", "chelsea:rotation", "sprites"]
METHODS = ["none", "dis-fast", "dis", "farneback", "deepflow", "rlof", "dualtvl1"]
FPS = [24.0, 60.0, 120.0]
MAX_PX = [4.0, 2.0, 1.0, 0.5]


def psnr_from_mse(mse: float) -> float:
    return float("inf") if mse <= 0 else float(10 * np.log10(1.0 / mse))


def _scene(spec: str, size: int, speed: float):
    import spikesim as ss

    name, _, motion = spec.partition(":")
    return ss.scenes.procedural(name, motion=motion or None, size=(size, size), speed=speed)


def run_block(args: tuple) -> list[dict]:
    """All (method, max_px) rows of one scene × speed × fps block (runs in a spawned worker)."""
    spec, speed_name, fps, methods, max_pxs, size, pairs, samples = args
    import cv2

    cv2.setNumThreads(1)
    from spikesim import motion
    from spikesim.scenes.video import as_video

    # warm-up: compile (or load) the numba splatting kernel outside the timings
    w = np.zeros((8, 8, 2), np.float32)
    ones = np.ones((8, 8), bool)
    motion.interpolate(np.zeros((8, 8, 3), np.float32), np.zeros((8, 8, 3), np.float32),
                       motion.PairMotion(False, 0.0, w, w, ones, ones), 0.5)

    scene = _scene(spec, size, SPEEDS[speed_name])
    taus = (np.arange(samples) + 0.5) / samples
    times = [(k + tau) / fps for k in range(pairs) for tau in taus]
    exact = {t: np.clip(scene.radiance(t), 0, 1) for t in times}
    rows = []
    for method in methods:
        shared: dict = {}
        for max_px in max_pxs:
            try:
                v = as_video(scene, fps, pairs + 1, flow=method, max_px=max_px,
                             shared_flows=shared, max_intermediate=512)
                # flow is analysed once per pair (first max_px) and its time charged to all
                flow_s = sum(v.pair(i).seconds for i in range(pairs))
                sq = 0.0
                for t in times:
                    sq += float(np.mean((np.clip(v.radiance(t), 0, 1) - exact[t]) ** 2))
                n_keys = sum(v.n_intermediate(i) + 1 for i in range(pairs))
                total = flow_s + v.stats["interp_s"]
                rows.append({
                    "scene": spec, "speed": speed_name, "speed_px_s": SPEEDS[speed_name],
                    "px_per_frame": SPEEDS[speed_name] / fps, "fps": fps, "method": method,
                    "max_px": max_px, "psnr_db": psnr_from_mse(sq / len(times)),
                    "key_frames": n_keys, "intermediate_per_pair": (n_keys - pairs) / pairs,
                    "flow_ms_per_pair": 1e3 * flow_s / pairs,
                    "interp_ms_per_key": 1e3 * v.stats["interp_s"] / max(1, n_keys - pairs),
                    "ms_per_key_frame": 1e3 * total / n_keys, "error": None,
                })
            except Exception as exc:  # noqa: BLE001 - a failing method is a result, not a crash
                rows.append({"scene": spec, "speed": speed_name, "fps": fps, "method": method,
                             "max_px": max_px, "error": f"{type(exc).__name__}: {exc}"})
    return rows


def summarise(rows: list[dict]) -> list[dict]:
    """Mean PSNR and ms per key frame for each method × max_px.

    Means are taken over the configurations (scene × speed × fps) where *every*
    method succeeded, so a method that fails on a hard case is not flattered;
    ``failed`` counts its failures.
    """
    blocks = {(r["scene"], r["speed"], r["fps"]) for r in rows}
    bad = {(r["scene"], r["speed"], r["fps"]) for r in rows if r.get("error")}
    common = blocks - bad
    out = []
    for method in dict.fromkeys(r["method"] for r in rows):
        for max_px in dict.fromkeys(r["max_px"] for r in rows):
            mine = [r for r in rows if r["method"] == method and r["max_px"] == max_px]
            sel = [r for r in mine if (r["scene"], r["speed"], r["fps"]) in common]
            if not sel:
                continue
            out.append({
                "method": method, "max_px": max_px,
                "mean_psnr_db": float(np.mean([r["psnr_db"] for r in sel])),
                "min_psnr_db": float(np.min([r["psnr_db"] for r in sel])),
                "mean_ms_per_key_frame": float(np.mean([r["ms_per_key_frame"] for r in sel])),
                "mean_flow_ms_per_pair": float(np.mean([r["flow_ms_per_pair"] for r in sel])),
                "mean_key_frames_per_pair": float(np.mean([1 + r["intermediate_per_pair"]
                                                           for r in sel])),
                "n": len(sel),
                "failed": sum(1 for r in mine if r.get("error")),
            })
    return out


def by_speed(rows: list[dict], method: str, max_px: float) -> list[dict]:
    """Mean PSNR per speed class and frame rate for one method and max_px (all scenes)."""
    out = []
    for speed in SPEEDS:
        for fps in sorted({r["fps"] for r in rows}):
            sel = [r for r in rows if r.get("error") is None and r["method"] == method
                   and r["max_px"] == max_px and r["speed"] == speed and r["fps"] == fps]
            if sel:
                out.append({"method": method, "max_px": max_px, "speed": speed, "fps": fps,
                            "px_per_frame": SPEEDS[speed] / fps,
                            "mean_psnr_db": float(np.mean([r["psnr_db"] for r in sel])),
                            "mean_ms_per_key_frame": float(np.mean([r["ms_per_key_frame"]
                                                                    for r in sel]))})
    return out


def end_to_end(size: int, n_readouts: int, seed: int = 0) -> list[dict]:
    """Spike streams of exact scene vs interpolated video (same seed), compared via TFP."""
    import spikesim as ss
    from spikesim import cfa
    from spikesim.estimate import tfp
    from spikesim.scenes.video import as_video

    sensor = ss.Sensor(height=size, width=size, cfa="RGGB", clock_hz=20_000.0)
    out = []
    for spec, speed_name, fps in [("astronaut:pan", "medium", 60.0), ("sprites", "medium", 60.0),
                                  ("chelsea:rotation", "fast", 120.0)]:
        scene = _scene(spec, size, SPEEDS[speed_name])
        dur = n_readouts / sensor.clock_hz
        n_frames = int(np.ceil(dur * fps)) + 2
        centres = np.linspace(60, n_readouts - 60, 6).astype(int)
        ref = ss.simulate(scene, sensor, n_readouts=n_readouts, seed=seed).unpack()
        truth = [cfa.mosaic(np.clip(scene.radiance((c + 0.5) / sensor.clock_hz), 0, 1), "RGGB")
                 for c in centres]
        tfp_ref = [np.clip(tfp(ref, c, window=41, rate=0.6), 0, 1) for c in centres]
        for method, max_px in (("dis", 1.0), ("none", 1.0)):
            vid = as_video(scene, fps, n_frames, flow=method, max_px=max_px)
            t0 = time.perf_counter()
            got = ss.simulate(vid, sensor, n_readouts=n_readouts, seed=seed).unpack()
            sim_s = time.perf_counter() - t0
            tfp_v = [np.clip(tfp(got, c, window=41, rate=0.6), 0, 1) for c in centres]
            row = {
                "scene": spec, "speed": speed_name, "fps": fps, "method": method,
                "max_px": max_px, "n_readouts": n_readouts, "size": size,
                "spike_mismatch_frac": float(np.mean(got != ref)),
                "psnr_tfp_video_vs_tfp_exact_db": float(np.mean(
                    [psnr_from_mse(np.mean((a - b) ** 2)) for a, b in zip(tfp_v, tfp_ref,
                                                                          strict=True)])),
                "psnr_tfp_exact_vs_truth_db": float(np.mean(
                    [psnr_from_mse(np.mean((a - b) ** 2)) for a, b in zip(tfp_ref, truth,
                                                                          strict=True)])),
                "psnr_tfp_video_vs_truth_db": float(np.mean(
                    [psnr_from_mse(np.mean((a - b) ** 2)) for a, b in zip(tfp_v, truth,
                                                                          strict=True)])),
                "simulate_s": sim_s,
            }
            out.append(row)
            print(f"  e2e {spec:18s} {method:5s} mismatch {row['spike_mismatch_frac']:.4f}  "
                  f"TFP(video) vs TFP(exact) {row['psnr_tfp_video_vs_tfp_exact_db']:.2f} dB  "
                  f"TFP vs truth: exact {row['psnr_tfp_exact_vs_truth_db']:.2f} / video "
                  f"{row['psnr_tfp_video_vs_truth_db']:.2f} dB", flush=True)
    return out


def write_markdown(path: Path, meta: dict, rows: list[dict], summary: list[dict],
                   e2e: list[dict]) -> None:
    lines = ["# Interpolation: speed against error", "",
             f"Machine: {meta['machine']}. Command: `{meta['command']}`. "
             f"Frames {meta['size']}×{meta['size']}, {meta['pairs']} frame pairs per "
             f"configuration, {meta['samples']} sample times per pair; PSNR in linear light "
             "(peak 1, clamp, no crop) against the exact procedural radiance. Time per key "
             "frame includes flow (shared across max_px), static test and interpolation; "
             "OpenCV single-threaded. Wall time of the run: "
             f"{meta['wall_s']:.0f} s.", "",
             "## Summary (mean over scenes, speeds and frame rates)", "",
             f"Means over the {summary[0]['n'] if summary else 0} configurations where every "
             "method succeeded; `failed` counts a method's failed configurations.", "",
             "| method | max_px | mean PSNR dB | min PSNR dB | ms / key frame | flow ms / pair "
             "| key frames / pair | failed |", "|---|---|---|---|---|---|---|---|"]
    for s in summary:
        lines.append(f"| {s['method']} | {s['max_px']:g} | {s['mean_psnr_db']:.2f} | "
                     f"{s['min_psnr_db']:.2f} | {s['mean_ms_per_key_frame']:.2f} | "
                     f"{s['mean_flow_ms_per_pair']:.1f} | {s['mean_key_frames_per_pair']:.1f} | "
                     f"{s['failed']} |")
    for method in ("dis", "none"):
        lines += ["", f"## {method}, max_px = 1, by speed and frame rate (mean over scenes)", "",
                  "| speed | fps | px / frame | PSNR dB | ms / key frame |",
                  "|---|---|---|---|---|"]
        for b in by_speed(rows, method, 1.0):
            lines.append(f"| {b['speed']} | {b['fps']:g} | {b['px_per_frame']:.2f} | "
                         f"{b['mean_psnr_db']:.2f} | {b['mean_ms_per_key_frame']:.2f} |")
    lines += ["", "## All configurations", "",
              "| scene | speed | px/frame | fps | method | max_px | PSNR dB | key frames/pair "
              "| ms / key frame |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if r.get("error"):
            lines.append(f"| {r['scene']} | {r['speed']} | | {r['fps']:g} | {r['method']} | "
                         f"{r['max_px']:g} | error: {r['error'][:60]} | | |")
            continue
        lines.append(f"| {r['scene']} | {r['speed']} | {r['px_per_frame']:.2f} | {r['fps']:g} | "
                     f"{r['method']} | {r['max_px']:g} | {r['psnr_db']:.2f} | "
                     f"{1 + r['intermediate_per_pair']:.1f} | {r['ms_per_key_frame']:.2f} |")
    if e2e:
        lines += ["", "## End to end: spikes from the interpolated video vs the exact scene", "",
                  "Same sensor (RGGB, 20 kHz, noise-free) and seed. TFP: 41 readouts, rate 0.6, "
                  "6 centres; truth = exact radiance through the Bayer mask.", "",
                  "| scene | fps | method | spikes differing | TFP(video) vs TFP(exact) dB | "
                  "TFP(exact) vs truth dB | TFP(video) vs truth dB |",
                  "|---|---|---|---|---|---|---|"]
        for r in e2e:
            lines.append(f"| {r['scene']} ({r['speed']}) | {r['fps']:g} | {r['method']} | "
                         f"{100 * r['spike_mismatch_frac']:.2f} % | "
                         f"{r['psnr_tfp_video_vs_tfp_exact_db']:.2f} | "
                         f"{r['psnr_tfp_exact_vs_truth_db']:.2f} | "
                         f"{r['psnr_tfp_video_vs_truth_db']:.2f} |")
    path.write_text("\n".join(lines) + "\n")


def plot(path: Path, rows: list[dict], summary: list[dict]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(13, 5))
    ax = axes[0]
    markers = dict(zip(MAX_PX, "o^sD", strict=True))
    for method in dict.fromkeys(s["method"] for s in summary):
        sel = sorted((s for s in summary if s["method"] == method), key=lambda s: -s["max_px"])
        xs = [s["mean_ms_per_key_frame"] for s in sel]
        ys = [s["mean_psnr_db"] for s in sel]
        line = ax.plot(xs, ys, "-", label=method)[0]
        for s, x, y in zip(sel, xs, ys, strict=True):
            ax.plot(x, y, markers.get(s["max_px"], "o"), color=line.get_color())
    ax.set_xscale("log")
    ax.set_xlabel("ms per output key frame (log)")
    ax.set_ylabel("mean PSNR, linear light (dB)")
    ax.set_title("speed against error (markers: max_px 4 o, 2 ^, 1 s, 0.5 D)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    ax = axes[1]
    ok = [r for r in rows if r.get("error") is None and r["method"] in ("dis", "none")]
    colours = dict(zip(SPEEDS, ("tab:blue", "tab:orange", "tab:red"), strict=True))
    for method, style in (("dis", "-"), ("none", ":")):
        for speed in SPEEDS:
            sel = [r for r in ok if r["method"] == method and r["speed"] == speed]
            pxs = sorted(dict.fromkeys(r["max_px"] for r in sel), reverse=True)
            ys = [np.mean([r["psnr_db"] for r in sel if r["max_px"] == p]) for p in pxs]
            ax.plot(pxs, ys, style, marker="o", color=colours[speed], label=f"{method}, {speed}")
    ax.set_xscale("log", base=2)
    ax.invert_xaxis()
    ax.set_xlabel("max_px (px between key frames)")
    ax.set_ylabel("mean PSNR over scenes and fps (dB)")
    ax.set_title("DIS vs plain blending by speed")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


CROP_SCENES = [("astronaut:pan", 240.0), ("astronaut:pan", 960.0), ("chelsea:rotation", 480.0),
               ("sprites", 480.0), ("sprites", 960.0)]


def crop_first(size=(720, 1280), crop=256, fps=24.0, pairs=2, samples=4, margins=(48, 0),
               seed=0) -> list[dict]:
    """Crop-first against full-frame interpolation on exact scenes (720p -> 256 crops).

    For each scene and speed, a ``size`` video at ``fps`` is interpolated once
    over the full frame and once per margin over a random ``crop`` x ``crop``
    box plus that margin; both are scored (PSNR, linear light) inside the box
    against the exact radiance at ``samples`` times inside each of ``pairs``
    frame pairs. Seconds = flow + warping (one OpenCV thread).
    """
    import cv2

    cv2.setNumThreads(1)
    from spikesim.scenes.video import as_video

    rng = np.random.default_rng(seed)
    taus = (np.arange(samples) + 0.5) / samples
    times = [(k + tau) / fps for k in range(pairs) for tau in taus]
    rows = []
    for spec, speed in CROP_SCENES:
        name, _, motion = spec.partition(":")
        import spikesim as ss

        scene = ss.scenes.procedural(name, motion=motion or None, size=size, speed=speed)
        top = int(rng.integers(0, size[0] - crop + 1))
        left = int(rng.integers(0, size[1] - crop + 1))
        box = (top, left, crop, crop)
        exact = {t: np.clip(scene.radiance(t)[top : top + crop, left : left + crop], 0, 1)
                 for t in times}
        variants = [("full frame", as_video(scene, fps, pairs + 1))]
        variants += [(f"crop-first, margin {m}", as_video(scene, fps, pairs + 1, crop=box,
                                                          margin=m)) for m in margins]
        for label, v in variants:
            sq = 0.0
            for t in times:
                img = v.radiance(t)
                if v.crop is None:
                    img = img[top : top + crop, left : left + crop]
                sq += float(np.mean((np.clip(img, 0, 1) - exact[t]) ** 2))
            rows.append({
                "scene": spec, "speed_px_s": speed, "px_per_frame": speed / fps, "box": box,
                "variant": label, "psnr_db": psnr_from_mse(sq / len(times)),
                "key_frames_per_pair": float(np.mean([v.n_intermediate(i) + 1
                                                      for i in range(pairs)])),
                "flow_s_per_pair": v.stats["flow_s"] / pairs,
                "warp_s_per_key": v.stats["interp_s"] / max(1, v.stats["key_frames"]),
            })
            print(json.dumps(rows[-1]), flush=True)
    return rows


def crop_markdown(rows: list[dict], meta: dict) -> str:
    lines = [
        "# Crop-first interpolation against full-frame interpolation",
        "",
        f"{meta['size'][1]}x{meta['size'][0]} video at {meta['fps']:g} fps rendered from exact "
        f"procedural scenes; a random {meta['crop']}x{meta['crop']} box per scene; PSNR in the "
        f"box (linear light, peak 1) against the exact radiance at {meta['samples']} times inside "
        f"each of {meta['pairs']} frame pairs. Flow DIS medium, max_px 1, one OpenCV thread.",
        f"Machine: {meta['machine']}. Command: `{meta['command']}`.",
        "",
        "| scene | px/frame | variant | PSNR dB | vs full frame dB | keys/pair | flow s/pair |"
        " warp ms/key |",
        "|---|---:|---|---:|---:|---:|---:|---:|",
    ]
    full = {(r["scene"], r["speed_px_s"]): r["psnr_db"] for r in rows
            if r["variant"] == "full frame"}
    for r in rows:
        d = r["psnr_db"] - full[(r["scene"], r["speed_px_s"])]
        lines.append(f"| {r['scene']} | {r['px_per_frame']:.0f} | {r['variant']} | "
                     f"{r['psnr_db']:.2f} | {d:+.2f} | {r['key_frames_per_pair']:.0f} | "
                     f"{r['flow_s_per_pair']:.3f} | {1e3 * r['warp_s_per_key']:.1f} |")
    worst = {}
    for r in rows:
        if r["variant"] != "full frame":
            d = r["psnr_db"] - full[(r["scene"], r["speed_px_s"])]
            worst[r["variant"]] = min(worst.get(r["variant"], np.inf), d)
    lines += ["", "Worst difference to full-frame interpolation: "
              + "; ".join(f"{k}: {v:+.2f} dB" for k, v in worst.items()) + ".", ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--crop-first", action="store_true",
                   help="only the crop-first vs full-frame comparison (720p -> 256x256 crops); "
                        "writes interpolation_crop.{json,md}")
    p.add_argument("--size", type=int, default=128)
    p.add_argument("--scenes", nargs="+", default=SCENES)
    p.add_argument("--speeds", nargs="+", default=list(SPEEDS), choices=list(SPEEDS))
    p.add_argument("--fps", nargs="+", type=float, default=FPS)
    p.add_argument("--methods", nargs="+", default=METHODS)
    p.add_argument("--max-px", nargs="+", type=float, default=MAX_PX)
    p.add_argument("--pairs", type=int, default=2)
    p.add_argument("--samples", type=int, default=8)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--e2e-readouts", type=int, default=2000)
    p.add_argument("--no-e2e", action="store_true")
    p.add_argument("--quick", action="store_true", help="tiny smoke run (not saved as results)")
    p.add_argument("--out", type=Path, default=RESULTS)
    args = p.parse_args(argv)
    if args.crop_first:
        t0 = time.perf_counter()
        rows = crop_first()
        meta = {"size": [720, 1280], "crop": 256, "fps": 24.0, "pairs": 2, "samples": 4,
                "machine": machine.describe(),
                "command": "python benchmarks/bench_interpolation.py --crop-first",
                "wall_s": time.perf_counter() - t0}
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "interpolation_crop.json").write_text(json.dumps(
            {"meta": meta, "rows": rows}, indent=1))
        (args.out / "interpolation_crop.md").write_text(crop_markdown(rows, meta))
        print(crop_markdown(rows, meta))
        return 0
    if args.quick:
        args.size, args.scenes, args.speeds, args.fps = 64, SCENES[:1], ["medium"], [60.0]
        args.methods, args.max_px, args.pairs, args.e2e_readouts = ["none", "dis"], [1.0], 1, 300
    from tqdm import tqdm

    blocks = [(s, sp, f, args.methods, args.max_px, args.size, args.pairs, args.samples)
              for s in args.scenes for sp in args.speeds for f in args.fps]
    t0 = time.perf_counter()
    rows: list[dict] = []
    ctx = mp.get_context("spawn")
    with ctx.Pool(args.workers) as pool:
        for block in tqdm(pool.imap_unordered(run_block, blocks), total=len(blocks),
                          desc="scene x speed x fps"):
            rows.extend(block)
    rows.sort(key=lambda r: (r["scene"], list(SPEEDS).index(r["speed"]), r["fps"],
                             args.methods.index(r["method"]), -r["max_px"]))
    summary = summarise(rows)
    print(f"\n{'method':10s} {'max_px':>6s} {'mean dB':>8s} {'min dB':>7s} {'ms/key':>8s} "
          f"{'flow ms':>8s} {'keys/pair':>9s}")
    for s in summary:
        print(f"{s['method']:10s} {s['max_px']:6g} {s['mean_psnr_db']:8.2f} "
              f"{s['min_psnr_db']:7.2f} {s['mean_ms_per_key_frame']:8.2f} "
              f"{s['mean_flow_ms_per_pair']:8.1f} {s['mean_key_frames_per_pair']:9.1f}")
    for r in rows:
        if r.get("error"):
            print("error:", r["scene"], r["speed"], r["fps"], r["method"], r["error"])
    e2e: list[dict] = []
    if not args.no_e2e:
        try:
            import spikesim as ss

            ss.simulate  # noqa: B018 - presence check
            e2e = end_to_end(args.size, args.e2e_readouts)
        except (ImportError, AttributeError) as exc:
            print(f"end-to-end comparison skipped: {exc}")
    wall = time.perf_counter() - t0
    meta = {
        "machine": machine.describe(),
        "python": sys.version.split()[0], "command": "python benchmarks/bench_interpolation.py "
        + " ".join(argv if argv is not None else sys.argv[1:]),
        "size": args.size, "pairs": args.pairs, "samples": args.samples, "wall_s": wall,
        "speeds_px_s": SPEEDS, "date": time.strftime("%Y-%m-%d %H:%M:%S"),
    }
    print(f"wall time {wall:.0f} s")
    if args.quick:
        return 0
    args.out.mkdir(parents=True, exist_ok=True)
    speeds = by_speed(rows, "dis", 1.0) + by_speed(rows, "none", 1.0)
    (args.out / "interpolation.json").write_text(json.dumps(
        {"meta": meta, "summary": summary, "by_speed": speeds, "rows": rows,
         "end_to_end": e2e}, indent=1))
    write_markdown(args.out / "interpolation.md", meta, rows, summary, e2e)
    plot(args.out / "interpolation.png", rows, summary)
    print(f"wrote {args.out}/interpolation.{{json,md,png}}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
