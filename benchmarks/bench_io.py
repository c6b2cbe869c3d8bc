"""I/O benchmark: HDF5 write/read throughput and size per compression, window-read latency,
chunk-shape study, and .dat decode speed against ``np.unpackbits``.

Data: a 1000x1000 RGGB stream of 2,000 readouts from the simulator (preset
``color-1000x1000-20k``, procedural ``astronaut`` panning), once noise-free and
once with paper-mode Gaussian noise σ_g = 10 DN, simulated once into memory so
that only I/O is timed.

Usage::

    python benchmarks/bench_io.py                 # full run (a few minutes on 2 cores)
    python benchmarks/bench_io.py --readouts 300  # quick run

Writes ``benchmarks/results/io.json`` and ``benchmarks/results/io.md``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import shutil
import tempfile
import time
from pathlib import Path

import h5py
import machine
import numpy as np

import spikesim as ss
from spikesim.io import h5 as h5mod
from spikesim.io import open_h5, read_dat, write_dat, write_h5
from spikesim.io._compression import have_hdf5plugin

RESULTS = Path(__file__).resolve().parent / "results"


def simulate(n: int, sigma_g: float, size: int) -> ss.SpikeStream:
    sensor = ss.Sensor.preset("color-1000x1000-20k")
    if size != 1000:
        sensor = sensor.replace(height=size, width=size)
    if sigma_g:
        sensor = sensor.replace(noise=ss.noise.PaperNoise(sigma_g=sigma_g))
    scene = ss.scenes.procedural("astronaut", motion="pan", size=(size, size))
    return ss.simulate(scene, sensor, n_readouts=n, seed=0, gt_readouts=[n // 2], progress=True)


def timed(fn, repeat: int = 1):
    best, out = float("inf"), None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return best, out


def window_latency(path: Path, n: int, h: int, w: int, reps: int, seed: int = 0) -> dict:
    """Median and p90 time to read a random 39 x 256 x 256 window (fresh handle each batch)."""
    rng = np.random.default_rng(seed)
    seq = open_h5(path)
    times = []
    for _ in range(reps):
        start = int(rng.integers(0, n - 39 + 1))
        top, left = int(rng.integers(0, h - 256 + 1)), int(rng.integers(0, w - 256 + 1))
        t = time.perf_counter()
        seq.read_window(start, 39, (top, left, 256, 256))
        times.append(time.perf_counter() - t)
    seq.close()
    return {"median_ms": 1e3 * float(np.median(times)),
            "p90_ms": 1e3 * float(np.percentile(times, 90))}


def bench_compression(stream, label: str, tmp: Path, options: list[str], reps: int) -> list[dict]:
    n, h, w = stream.n_readouts, stream.height, stream.width
    raw_bytes = stream.packed.nbytes
    rows = []
    for comp in options:
        path = tmp / f"{label}-{comp.replace(':', '')}.h5"
        t_write, _ = timed(lambda p=path, c=comp: write_h5(p, stream, compression=c))
        size = path.stat().st_size
        with h5py.File(path) as f:
            spikes_size = f["spikes"].id.get_storage_size()
        t_read, _ = timed(lambda p=path: open_h5(p).read_packed())
        lat = window_latency(path, n, h, w, reps)
        rows.append({
            "stream": label, "compression": comp, "file_MB": size / 1e6,
            "spikes_MB": spikes_size / 1e6, "ratio": raw_bytes / spikes_size, "write_s": t_write,
            "write_Gpx_per_s": n * h * w / t_write / 1e9,
            "write_MB_per_s": raw_bytes / t_write / 1e6,
            "read_s": t_read, "read_Gpx_per_s": n * h * w / t_read / 1e9,
            "window_39x256x256_ms": lat["median_ms"], "window_p90_ms": lat["p90_ms"],
        })
        print(rows[-1], flush=True)
        path.unlink()
    return rows


def bench_chunks(stream, tmp: Path, compression: str, reps: int) -> list[dict]:
    """Window latency and write speed for a few chunk shapes (readouts, rows, bytes)."""
    shapes = [(16, 64, 8), (32, 128, 16), (64, 256, 32), (128, 128, 16)]
    saved = (h5mod.CHUNK_READOUTS, h5mod.CHUNK_ROWS, h5mod.CHUNK_BYTES)
    rows = []
    try:
        for shape in shapes:
            h5mod.CHUNK_READOUTS, h5mod.CHUNK_ROWS, h5mod.CHUNK_BYTES = shape
            path = tmp / f"chunks-{'x'.join(map(str, shape))}.h5"
            t_write, _ = timed(lambda p=path: write_h5(p, stream, compression=compression))
            lat = window_latency(path, stream.n_readouts, stream.height, stream.width, reps)
            rows.append({"chunk": list(shape), "chunk_KiB": np.prod(shape) / 1024,
                         "compression": compression, "file_MB": path.stat().st_size / 1e6,
                         "write_s": t_write, "window_39x256x256_ms": lat["median_ms"],
                         "window_p90_ms": lat["p90_ms"]})
            print(rows[-1], flush=True)
            path.unlink()
    finally:
        h5mod.CHUNK_READOUTS, h5mod.CHUNK_ROWS, h5mod.CHUNK_BYTES = saved
    return rows


def bench_dat(stream, tmp: Path) -> dict:
    n, h, w = stream.n_readouts, stream.height, stream.width
    path = tmp / "s.dat"
    t_write, _ = timed(lambda: write_dat(path, stream))
    read_dat(path, h, w, length=2)  # compile / load the numba kernel
    t_ours, ours = timed(lambda: read_dat(path, h, w), repeat=3)

    def numpy_decode():
        raw = np.fromfile(path, np.uint8).reshape(n, h, w // 8)
        return np.unpackbits(raw, axis=-1, bitorder="little")[:, ::-1].copy()

    t_np, ref = timed(numpy_decode, repeat=3)
    assert np.array_equal(ours, ref)
    del ours, ref
    t_win, _ = timed(lambda: read_dat(path, h, w, start=(n - 39) // 2, length=39), repeat=5)
    return {
        "write_s": t_write, "write_Gpx_per_s": n * h * w / t_write / 1e9,
        "decode_s": t_ours, "decode_Gpx_per_s": n * h * w / t_ours / 1e9,
        "numpy_unpackbits_s": t_np, "numpy_Gpx_per_s": n * h * w / t_np / 1e9,
        "speedup_vs_numpy": t_np / t_ours, "window_39_full_frame_ms": 1e3 * t_win,
        "file_MB": path.stat().st_size / 1e6,
    }


def markdown(res: dict) -> str:
    m = res["machine"]
    out = [
        "# I/O benchmark (`benchmarks/bench_io.py`)", "",
        f"Command: `{res['command']}`  ",
        f"Machine: {m['description']}; "
        f"Python {m['python']}, h5py {m['h5py']}, HDF5 {m['hdf5']}, hdf5plugin "
        f"{'yes' if m['hdf5plugin'] else 'no'}.  ",
        f"Data: {res['readouts']} readouts of {res['size']}x{res['size']} RGGB "
        "(`color-1000x1000-20k`, astronaut panning); packed size "
        f"{res['packed_MB']:.0f} MB per stream; ratio = packed bytes / stored bytes of the "
        "`spikes` dataset (the file also holds one float32 GT frame).", "",
        "## HDF5 compression", "",
        "| stream | compression | file MB | spikes MB | ratio | write Gpx/s | write MB/s "
        "| read Gpx/s | window 39x256x256 ms (median / p90) |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in res["compression"]:
        out.append(
            f"| {r['stream']} | {r['compression']} | {r['file_MB']:.1f} | {r['spikes_MB']:.1f} | "
            f"{r['ratio']:.2f} | "
            f"{r['write_Gpx_per_s']:.2f} | {r['write_MB_per_s']:.0f} | {r['read_Gpx_per_s']:.2f} | "
            f"{r['window_39x256x256_ms']:.1f} / {r['window_p90_ms']:.1f} |"
        )
    out += ["", "## Chunk shape (readouts, rows, packed bytes) — window reads", "",
            "| chunk | KiB | compression | file MB | write s | window ms (median / p90) |",
            "|---|---:|---|---:|---:|---:|"]
    for r in res["chunks"]:
        out.append(f"| {tuple(r['chunk'])} | {r['chunk_KiB']:.0f} | {r['compression']} | "
                   f"{r['file_MB']:.1f} | {r['write_s']:.2f} | "
                   f"{r['window_39x256x256_ms']:.1f} / {r['window_p90_ms']:.1f} |")
    d = res["dat"]
    out += ["", "## PKU .dat", "",
            "| operation | time s | Gpx-readouts/s |", "|---|---:|---:|",
            f"| write_dat (packed rows, flip) | {d['write_s']:.2f} | {d['write_Gpx_per_s']:.2f} |",
            f"| read_dat (numba LUT, mmap, flip) | {d['decode_s']:.2f} | "
            f"{d['decode_Gpx_per_s']:.2f} |",
            f"| np.fromfile + np.unpackbits + flip | {d['numpy_unpackbits_s']:.2f} | "
            f"{d['numpy_Gpx_per_s']:.2f} |", "",
            f"read_dat is {d['speedup_vs_numpy']:.1f}x np.unpackbits; a 39-readout full-frame "
            f"window decodes in {d['window_39_full_frame_ms']:.1f} ms.", ""]
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--readouts", type=int, default=2000)
    ap.add_argument("--size", type=int, default=1000)
    ap.add_argument("--reps", type=int, default=40, help="random windows per file")
    ap.add_argument("--tmp", default=None, help="scratch folder (default: system temp)")
    ap.add_argument("--out", default=str(RESULTS))
    args = ap.parse_args()
    options = ["none", "gzip:1", "gzip:4"] + (["lz4", "zstd:1", "zstd:3"] if have_hdf5plugin()
                                              else [])
    tmp = Path(tempfile.mkdtemp(prefix="bench_io_", dir=args.tmp))
    try:
        res = {
            "command": "python benchmarks/bench_io.py"
                       + (f" --readouts {args.readouts}" if args.readouts != 2000 else "")
                       + (f" --size {args.size}" if args.size != 1000 else ""),
            "machine": {"cpu": platform.processor() or platform.machine(),
                        "cores": os.cpu_count(), "python": platform.python_version(),
                        "h5py": h5py.__version__, "hdf5": h5py.version.hdf5_version,
                        "hdf5plugin": have_hdf5plugin()},
            "readouts": args.readouts, "size": args.size, "compression": [], "chunks": [],
        }
        with contextlib.suppress(OSError, StopIteration):  # CPU name where Linux tells it
            res["machine"]["cpu"] = next(
                line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo")
                if line.startswith("model name"))
        for label, sigma in (("ideal", 0.0), ("paper σg=10", 10.0)):
            stream = simulate(args.readouts, sigma, args.size)
            res["packed_MB"] = stream.packed.nbytes / 1e6
            res["compression"] += bench_compression(stream, label, tmp, options, args.reps)
            if sigma == 0.0:
                for comp in ("none", "zstd:1" if have_hdf5plugin() else "gzip:1"):
                    res["chunks"] += bench_chunks(stream, tmp, comp, args.reps)
                res["dat"] = bench_dat(stream, tmp)
            del stream
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    res["machine"]["description"] = machine.describe()
    (out / "io.json").write_text(json.dumps(res, indent=1))
    (out / "io.md").write_text(markdown(res))
    print(markdown(res))


if __name__ == "__main__":
    main()
