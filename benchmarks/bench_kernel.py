"""Kernel throughput: pixel-readouts per second at 1000×1000 Bayer.

For each noise mode (off, paper GN/GPN, physical) and each scene kind (static:
one key frame; moving: a new key frame every 16 readouts, radiance linear in
between, i.e. 1 px of motion per 16 readouts) this measures
``spikesim.simulate_chunks`` (the numba kernel plus its driver, output
discarded chunk by chunk) and the vectorised NumPy float64
reference ``spikesim.reference`` on the same input in the same run, checks
that their bits are identical over the readouts the reference computed, and
records the peak resident memory of a fresh process streaming a long run.

Run::

    .venv/bin/python benchmarks/bench_kernel.py            # full size (3–9 min, 2 cores)
    .venv/bin/python benchmarks/bench_kernel.py --quick    # small smoke run
    .venv/bin/python benchmarks/bench_kernel.py --ratios-only [--size 500]
        # only physical (per-spike and per-readout shot noise) / paper GN σ=10,
        # same run, static and moving: kernel_ratios.{json,md}

Writes ``benchmarks/results/kernel.json``, ``kernel.md`` and ``kernel.png``
(throughput per case against the design targets).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import platform
import resource
import sys
import time
from pathlib import Path

import machine
import numba
import numpy as np

import spikesim as ss
from spikesim import rng
from spikesim._simd import prefer_wide_vectors
from spikesim.reference import reference_simulate

RESULTS = Path(__file__).parent / "results"
KEY_EVERY = 16  # readouts between key frames of the moving scene
#: Radiance scale of the dim scene of :func:`physical_vs_paper`: about 0.03
#: spikes per readout, the mean of a real 250×250 capture.
DIM = 0.18

NOISES = {
    "off": None,
    "paper GN σ=10": ss.noise.PaperNoise(sigma_g=10.0),
    "paper GPN σg=σp=2.5": ss.noise.PaperNoise(sigma_g=2.5, sigma_p=2.5),
    "physical (defaults)": ss.noise.PhysicalNoise(),
}


def make_scene(kind: str, size: int, n_readouts: int, clock: float):
    from skimage import data, transform

    img = transform.resize(data.astronaut() / 255.0, (size, size), anti_aliasing=True)
    img = (img**2.2).astype(np.float32)  # roughly linear light
    if kind == "static":
        return ss.scenes.Static(img)
    return Shifting(img, KEY_EVERY / clock)


class Shifting(ss.scenes.Scene):
    """Moves 1 px per key interval (key frames from a small cycle, so that the
    benchmark measures the simulator, not the making of test images)."""

    def __init__(self, img, interval_s, cycle=4):
        self.key_interval_s = interval_s
        self.height, self.width = img.shape[:2]
        self._frames = [np.ascontiguousarray(np.roll(img, k, axis=1)) for k in range(cycle)]

    def radiance(self, t):
        return self._frames[round(t / self.key_interval_s) % len(self._frames)]

    def describe(self):
        return {"type": "benchmark-shift", "key_interval_s": self.key_interval_s}


def time_kernel(scene, sensor, n, seed=0, repeats=3):
    ss.simulate(scene, sensor, 32, seed=seed, gt_readouts=[])  # compile / warm caches
    best = float("inf")
    first = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        for chunk in ss.simulate_chunks(scene, sensor, n, seed=seed, gt_readouts=[],
                                        chunk_readouts=512):
            if first is None:
                first = chunk.packed
        best = min(best, time.perf_counter() - t0)
    return best, first


@numba.njit(error_model="numpy")
def _draw_row(key, y, width, n, deviates, z, bits, keys):
    """Row ``y`` of :func:`_draw_only`, compiled for the widest vectors as the
    kernel's paper-noise step is (``spikesim._simd.prefer_wide_vectors``)."""
    prefer_wide_vectors()
    acc = np.uint64(0)
    for x0 in range(0, width, 64):
        rng.pixel_keys_into(np.uint64(y * width + x0), keys)
        for k in range(n):
            rk = rng.readout_key(key, k)
            if deviates:
                rng.normals_into(rk, keys, z, bits)
                acc ^= np.uint64(z[k & 63] > 0.0)
            else:
                for i in range(64):
                    bits[i] = rng.mix64(rk ^ keys[i])
            acc ^= bits[k & 63]
    return acc


@numba.njit(parallel=True, error_model="numpy")
def _draw_only(key, height, width, n, deviates, sink):
    """The random numbers of a paper-noise run and nothing else: per readout and
    64-pixel block the keyed 64-bit hashes (``deviates=False``) or the normal
    deviates made from them (``rng.normals_into``), rows in parallel."""
    for y in numba.prange(height):
        sink[y] = _draw_row(key, y, width, n, deviates, np.empty(64), np.empty(64, np.uint64),
                            np.empty(64, np.uint64))


def time_draws(size, n, deviates, repeats=3):
    """Pixel-readouts/s of :func:`_draw_only` (a ceiling for any kernel that
    draws one normal deviate per pixel and readout this way)."""
    sink = np.empty(size, np.uint64)
    key = rng.stream_key(0, rng.STREAM_PAPER)
    _draw_only(key, 2, size, 2, deviates, sink)  # compile
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        _draw_only(key, size, size, n, deviates, sink)
        best = min(best, time.perf_counter() - t0)
    return size * size * n / best


def _time_call(scene, sensor, n, **kw):
    t0 = time.perf_counter()
    ss.simulate(scene, sensor, n, gt_readouts=[], **kw)
    return time.perf_counter() - t0


def _warm(scene, sensors, n):
    """One untimed ``n``-readout call of each sensor on the scene.  Warmed
    with short calls only, paper GN's first 1024-readout call at 1000×1000
    took 1.43 s against 1.14–1.17 s for the next three (moving scene), so
    the first round's ratio (1.06 against 0.88–0.89) set the range's top."""
    for sensor in sensors:
        _time_call(scene, sensor, n)


def _time_stream(scene, sensor, n):
    """Seconds to stream ``n`` readouts in 512-readout chunks (recycled outputs):
    the kernel and its driver, without the page faults of a fresh whole-stream
    array, which dominate (and scatter) a fast noise-free ``simulate`` call."""
    t0 = time.perf_counter()
    chunks = sum(1 for _ in ss.simulate_chunks(scene, sensor, n, gt_readouts=[],
                                               chunk_readouts=512))  # each dropped at once
    assert chunks == -(-n // 512)
    return time.perf_counter() - t0


def _median_range(values):
    v = sorted(values)
    return {"median": v[len(v) // 2], "min": v[0], "max": v[-1]}


def reset_and_call_size(size, n_long, repeats=3):
    """Same-run ratios (median and range over ``repeats`` alternating rounds):
    subtract and zero reset against modulo (noise off, static and moving
    scene, ``n_long`` readouts streamed, :func:`_time_stream`); a 1-readout
    call against a 400-readout call (static, noise off, whole ``simulate``
    calls, RGGB and mono); mono's
    400-readout time against RGGB's (≥ 1 means mono is at least as fast)."""
    out = {}
    for kind in ("static", "moving"):
        sensors = {r: ss.Sensor(height=size, width=size, cfa="RGGB", reset=r)
                   for r in ("modulo", "subtract", "zero")}
        scene = make_scene(kind, size, n_long, sensors["modulo"].clock_hz)
        for sensor in sensors.values():
            ss.simulate(scene, sensor, 32, gt_readouts=[])  # compile / warm
        ratios = {"subtract": [], "zero": []}
        for _ in range(repeats):
            t = {r: _time_stream(scene, sensor, n_long) for r, sensor in sensors.items()}
            for r in ratios:
                ratios[r].append(t["modulo"] / t[r])
        out[f"{kind}: throughput / modulo's"] = {r: _median_range(v) for r, v in ratios.items()}
    scene = make_scene("static", size, 400, 20_000.0)
    sensors = {c or "mono": ss.Sensor(height=size, width=size, cfa=c) for c in ("RGGB", None)}
    for sensor in sensors.values():
        ss.simulate(scene, sensor, 32, gt_readouts=[])
    one = {k: [] for k in sensors}
    mono_vs_rggb = []
    for _ in range(repeats):
        t400 = {}
        for k, sensor in sensors.items():
            t1 = _time_call(scene, sensor, 1)
            t400[k] = _time_call(scene, sensor, 400)
            one[k].append(t1 / t400[k])
        mono_vs_rggb.append(t400["RGGB"] / t400["mono"])
    out["1-readout call / 400-readout call"] = {k: _median_range(v) for k, v in one.items()}
    out["mono throughput / RGGB's (400 readouts)"] = _median_range(mono_vs_rggb)
    return out


def physical_vs_paper(size, n, repeats=3):
    """Same-run throughput of physical mode (defaults: shot noise drawn per
    spike, and with the per-readout sampler) over paper GN σ = 10's, static
    and moving scene and the static one dimmed to about 0.03 spikes per
    readout, ``n`` readouts per call; median and range over
    ``repeats`` alternating rounds.  Also the mean firing rate of the physical
    stream (the event sampler's work is per spike)."""
    out = {}
    paper = ss.Sensor(height=size, width=size, cfa="RGGB", noise=NOISES["paper GN σ=10"])
    phys = ss.Sensor(height=size, width=size, cfa="RGGB", noise=NOISES["physical (defaults)"])
    dim = ss.scenes.Static(make_scene("static", size, n, paper.clock_hz).radiance(0.0) * DIM)
    for kind in ("static", "moving", f"static ×{DIM}"):
        scene = dim if kind.endswith(str(DIM)) else make_scene(kind, size, n, paper.clock_hz)
        rate = float(ss.simulate(scene, phys, 64, gt_readouts=[]).firing_rate().mean())
        ss.simulate(scene, phys, 32, gt_readouts=[], shot_sampler="readout")
        _warm(scene, (paper, phys), n)
        event, readout = [], []
        for _ in range(repeats):
            t_paper = _time_call(scene, paper, n)
            event.append(t_paper / _time_call(scene, phys, n))
            readout.append(t_paper / _time_call(scene, phys, n, shot_sampler="readout"))
        out[f"{kind}: physical throughput / paper GN's"] = {
            "per-spike shot noise": _median_range(event),
            "per-readout shot noise": _median_range(readout)}
        out[f"{kind}: physical spikes per readout"] = {"": _median_range([rate])}
    return out


#: Radiance scales of :func:`rate_sweep` (about 0.03 to 0.28 spikes per readout).
SWEEP = (0.18, 0.35, 0.6, 1.0, 1.7)


def rate_sweep(size, n, repeats=3):
    """Physical over paper GN σ = 10 throughput (median and range over
    ``repeats`` alternating rounds, ``n`` readouts per call) on the static
    scene scaled by each of :data:`SWEEP`, with the physical stream's mean
    spikes per readout: where physical mode's per-spike cost meets paper
    mode's per-readout cost."""
    paper = ss.Sensor(height=size, width=size, cfa="RGGB", noise=NOISES["paper GN σ=10"])
    phys = ss.Sensor(height=size, width=size, cfa="RGGB", noise=NOISES["physical (defaults)"])
    base = make_scene("static", size, n, paper.clock_hz).radiance(0.0)
    points = []
    for scale in SWEEP:
        scene = ss.scenes.Static(base * scale)
        rate = float(ss.simulate(scene, phys, 64, gt_readouts=[]).firing_rate().mean())
        _warm(scene, (paper, phys), n)
        ratios = []
        for _ in range(repeats):
            t_paper = _time_call(scene, paper, n)
            ratios.append(t_paper / _time_call(scene, phys, n))
        points.append({"scale": scale, "spikes_per_readout": rate, **_median_range(ratios)})
        print(json.dumps(points[-1]), flush=True)
    return points


def plot_sweep(points, title, path: Path) -> None:
    """Physical / paper throughput against spikes per readout, with parity,
    the benchmark scene's rate and a real capture's."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    x = [p["spikes_per_readout"] for p in points]
    y = [p["median"] for p in points]
    err = [[p["median"] - p["min"] for p in points], [p["max"] - p["median"] for p in points]]
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.errorbar(x, y, yerr=err, marker="o", capsize=3, label="physical / paper GN σ=10")
    ax.axhline(1.0, color="k", ls="--", lw=1, label="same cost")
    ax.axvline(0.033, color="tab:green", ls=":", label="real 250×250 capture (0.033)")
    ax.axvline(0.167, color="tab:red", ls=":", label="benchmark scene (0.167)")
    ax.set_xscale("log")
    ax.set_xlabel("physical stream's spikes per pixel and readout")
    ax.set_ylabel("throughput ratio (>1: physical faster)")
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def time_reference(scene, sensor, n, seed=0):
    t0 = time.perf_counter()
    packed = reference_simulate(scene, sensor, n, seed=seed)
    return time.perf_counter() - t0, packed


def _stream_rss(args):
    size, n, noise_name = args
    sensor = ss.Sensor(height=size, width=size, cfa="RGGB", noise=NOISES[noise_name])
    scene = make_scene("moving", size, n, sensor.clock_hz)
    total = 0
    for chunk in ss.simulate_chunks(scene, sensor, n, gt_readouts=[n // 2]):
        total += int(chunk.packed[:, 0, 0].sum())
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # MiB


def peak_rss_mib(size, n, noise_name):
    ctx = mp.get_context("spawn")
    with ctx.Pool(1) as pool:
        return pool.map(_stream_rss, [(size, n, noise_name)])[0]


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="small sizes (smoke test)")
    ap.add_argument("--out", default=str(RESULTS),
                    help="results folder (default benchmarks/results)")
    ap.add_argument("--rss-readouts", type=int, default=None,
                    help="readouts of the peak-RSS streaming step (default 40000; 2000 quick)")
    ap.add_argument("--size", type=int, default=None,
                    help="sensor side (default 1000; 256 quick): smaller under load")
    ap.add_argument("--ratios-only", action="store_true",
                    help="only the same-run physical / paper ratios (kernel_ratios.{json,md})")
    return ap


def main(argv=None):
    args = build_parser().parse_args(argv)
    command = machine.command_line(__file__, argv)
    size = args.size or (256 if args.quick else 1000)
    if args.ratios_only:
        return ratios_only(size, 256 if args.quick else 1024, Path(args.out), command)
    n_fast, n_noisy, n_phys, n_ref = (256, 64, 32, 4) if args.quick else (8192, 2048, 256, 12)
    rows = []
    for kind in ("static", "moving"):
        for noise_name, noise in NOISES.items():
            sensor = ss.Sensor(height=size, width=size, cfa="RGGB", noise=noise)
            n = n_fast if noise is None else (n_phys if noise_name.startswith("phys") else n_noisy)
            scene = make_scene(kind, size, n, sensor.clock_hz)
            t_k, first = time_kernel(scene, sensor, n)
            row = {
                "scene": kind,
                "noise": noise_name,
                "readouts": n,
                "kernel_px_readouts_per_s": size * size * n / t_k,
            }
            if noise is None or noise.kind == "paper":
                t_r, ref = time_reference(scene, sensor, n_ref)
                row["numpy_px_readouts_per_s"] = size * size * n_ref / t_r
                row["speedup"] = row["kernel_px_readouts_per_s"] / row["numpy_px_readouts_per_s"]
                row["bit_identical"] = bool(np.array_equal(first[:n_ref], ref))
            rows.append(row)
            print(json.dumps(row), flush=True)
    ratios = reset_and_call_size(size, 256 if args.quick else 2048)
    ratios.update(physical_vs_paper(size, 256 if args.quick else 1024))
    print(json.dumps({"same_run_ratios": ratios}), flush=True)
    draws = {"hashes": time_draws(size, n_noisy, False),
             "normal deviates": time_draws(size, n_noisy, True)}
    print(json.dumps({"draws_only_per_s": draws}), flush=True)
    n_long = args.rss_readouts or (2000 if args.quick else 40_000)
    rss = {name: peak_rss_mib(size, n_long, name) for name in ("off", "paper GN σ=10")}
    result = {
        "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores "
                   f"({platform.platform()}), numba threads {numba.get_num_threads()}",
        "python": sys.version.split()[0],
        "size": [size, size],
        "cfa": "RGGB",
        "rows": rows,
        "draws_only_per_s": draws,
        "same_run_ratios": ratios,
        "peak_rss_mib_streaming": {"readouts": n_long, **rss},
        "command": command,
    }
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    name = "kernel_quick" if args.quick else "kernel"
    (out / f"{name}.json").write_text(json.dumps(result, indent=2))
    (out / f"{name}.md").write_text(to_markdown(result))
    plot(result, out / f"{name}.png")
    print(to_markdown(result))


def ratios_only(size, n, out: Path, command: str) -> None:
    """:func:`physical_vs_paper` alone, written to ``kernel_ratios.{json,md}``."""
    load = os.getloadavg()[0]
    ratios = physical_vs_paper(size, n)
    sweep = rate_sweep(size, n)
    result = {"machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
                         f"numba threads {numba.get_num_threads()}, load average {load:.1f} "
                         "at the start",
              "size": [size, size], "cfa": "RGGB", "readouts_per_call": n,
              "same_run_ratios": ratios, "rate_sweep": sweep,
              "command": command}
    out.mkdir(parents=True, exist_ok=True)
    (out / "kernel_ratios.json").write_text(json.dumps(result, indent=2))
    lines = [f"# Physical against paper-mode noise, {size}×{size} RGGB", "",
             f"Machine: {result['machine']}. Command: `{result['command']}`;",
             f"{n} readouts per `simulate` call, 3 alternating rounds (median, range).", "",
             "| comparison | case | median | range |", "|---|---|---:|---|"]
    for what, cases in ratios.items():
        for case, v in cases.items():
            lines.append(f"| {what} | {case} | {v['median']:.3g} | "
                         f"{v['min']:.3g}–{v['max']:.3g} |")
    lines += ["", "The static scene scaled (`kernel_ratios.png`): physical throughput over",
              "paper GN's.", "", "| radiance scale | spikes per readout | median | range |",
              "|---:|---:|---:|---|"]
    for p in sweep:
        lines.append(f"| {p['scale']} | {p['spikes_per_readout']:.3f} | {p['median']:.3g} | "
                     f"{p['min']:.3g}–{p['max']:.3g} |")
    (out / "kernel_ratios.md").write_text("\n".join(lines) + "\n")
    plot_sweep(sweep, f"Physical against paper-mode noise, {size}×{size} RGGB, "
               f"{numba.get_num_threads()} threads", out / "kernel_ratios.png")
    print("\n".join(lines))


TARGETS = {"off": 1e10, "noisy": 3e9}  # px·readouts/s on the 2-core machine (the issue)


def plot(r, path: Path) -> None:
    """Horizontal bars of kernel throughput (log scale), one per case, with the
    targets and the rate of the normal deviates alone as vertical lines."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = r["rows"][::-1]
    labels = [f"{row['scene']}, {row['noise']}" for row in rows]
    rates = [row["kernel_px_readouts_per_s"] for row in rows]
    colours = ["tab:blue" if row["noise"] == "off" else "tab:orange" for row in rows]
    fig, ax = plt.subplots(figsize=(8, 4))
    ax.barh(labels, rates, color=colours)
    ax.set_xscale("log")
    ax.axvline(TARGETS["off"], color="tab:blue", ls="--", label="target, noise off")
    ax.axvline(TARGETS["noisy"], color="tab:orange", ls="--", label="target, per-readout noise")
    ax.axvline(r["draws_only_per_s"]["normal deviates"], color="k", ls=":",
               label="normal deviates alone")
    ax.set_xlabel("pixel-readouts per second")
    ax.set_title(f"Kernel throughput, {r['size'][0]}×{r['size'][1]} {r['cfa']}, "
                 f"{os.cpu_count()} cores", fontsize=10)
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def to_markdown(r) -> str:
    lines = [
        f"# Kernel throughput, {r['size'][0]}×{r['size'][1]} {r['cfa']}",
        "",
        f"Machine: {r['machine']}. Command: `{r['command']}`.",
        "Throughput of `simulate_chunks` (kernel + driver) in pixel-readouts/s; the NumPy",
        "column is the float64 reference `spikesim.reference` on the same input, same run.",
        "",
        "| scene | noise | readouts | kernel px·readouts/s | NumPy px·readouts/s | speed-up |"
        " bit-identical |",
        "|---|---|---:|---:|---:|---:|---|",
    ]
    for row in r["rows"]:
        npy = row.get("numpy_px_readouts_per_s")
        lines.append(
            f"| {row['scene']} | {row['noise']} | {row['readouts']} | "
            f"{row['kernel_px_readouts_per_s']:.3g} | "
            f"{'—' if npy is None else f'{npy:.3g}'} | "
            f"{'—' if npy is None else format(row['speedup'], '.0f') + '×'} | "
            f"{'—' if npy is None else ('yes' if row['bit_identical'] else 'NO')} |"
        )
    m = r["peak_rss_mib_streaming"]
    d = r["draws_only_per_s"]
    lines += ["", "Same-run ratios (median, range over 3 alternating rounds; the machine is shared",
              "with other jobs, so absolute times move and only these ratios compare):", "",
              "| comparison | case | median | range |", "|---|---|---:|---|"]
    for what, cases in r.get("same_run_ratios", {}).items():
        items = cases.items() if "median" not in cases else [("", cases)]
        for case, v in items:
            lines.append(f"| {what} | {case} | {v['median']:.3f} | "
                         f"{v['min']:.3f}–{v['max']:.3f} |")
    lines += [
        "",
        "Random numbers alone, same size and threads (no simulation: the draws of a paper-noise",
        "run, a ceiling for any kernel drawing one keyed normal per pixel and readout):",
        f"keyed 64-bit hashes {d['hashes']:.3g}/s, normal deviates {d['normal deviates']:.3g}/s.",
        "",
        f"Peak RSS of a fresh process streaming {m['readouts']} readouts (moving scene, output "
        f"discarded per chunk): noise off {m['off']:.0f} MiB, "
        f"paper GN {m['paper GN σ=10']:.0f} MiB.",
        "",
        "Physical mode has no NumPy column: its reference (`spikesim.reference_event`, a",
        "Python loop per spike) is too slow at this size; tests/spikesim/test_event_shot_noise.py",
        "checks the kernel against it bit for bit on small sensors.",
        "",
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    main()
