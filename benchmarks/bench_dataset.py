"""Dataset generation throughput: serial, 2 local processes, 2-worker Dask LocalCluster.

Builds the same manifest (default: ``builtin:sjdd-train-small`` limited to 12
sequences) three times into temporary folders and reports sequences per
minute, pixel-readouts per second, and where the worker time went (scene
rendering, optical flow, kernel, writing; summed over sequences).

Run::

    .venv/bin/python benchmarks/bench_dataset.py [--manifest builtin:NAME] [--limit N]

Writes ``benchmarks/results/dataset.json`` and ``dataset.md``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
from pathlib import Path

from spikesim.dataset import build_dataset, load_manifest

RESULTS = Path(__file__).parent / "results"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--manifest", default="builtin:sjdd-train-small")
    ap.add_argument("--limit", type=int, default=48)
    ap.add_argument("--out", default=str(RESULTS))
    args = ap.parse_args(argv)
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
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "dataset.json").write_text(json.dumps(result, indent=2))
    (out / "dataset.md").write_text(to_markdown(result))
    print(to_markdown(result))


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
        " scene s | flow s | kernel s | write s |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for row in r["rows"]:
        st = row["stage_seconds"]
        lines.append(
            f"| {row['executor']} | {row['sequences']} | {row['seconds']:.1f} | "
            f"{row['sequences_per_min']:.1f} | {row['px_readouts_per_s']:.3g} | {row['mib']:.1f} | "
            f"{st['scene']:.1f} | {st['flow']:.1f} | {st['kernel']:.1f} | {st['write']:.1f} |")
    lines += ["", "Each spawned process (pool or Dask worker) pays its own start-up (interpreter,",
              "imports, numba cache load) once; parallel executors win only when the sequences",
              "take longer than that.", ""]
    return "\n".join(lines)


if __name__ == "__main__":
    main()
