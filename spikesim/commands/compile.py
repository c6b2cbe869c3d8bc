"""``spikesim compile``: compile kernel families into numba's cache ahead of use."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time

_CHILD = """
import json, resource, sys, time
t0 = time.perf_counter()
from spikesim.precompile import precompile
precompile([sys.argv[1]], resets=sys.argv[2:])
usage = resource.getrusage(resource.RUSAGE_SELF)
print(json.dumps({"seconds": time.perf_counter() - t0, "cpu_s": usage.ru_utime + usage.ru_stime,
                  "peak_rss_mb": usage.ru_maxrss / 1024}))
"""


def register(sub) -> None:
    from spikesim.families import FAMILIES, RESETS

    p = sub.add_parser(
        "compile", help="compile the simulation kernels into numba's cache ahead of use",
        description="Compile kernel families (default: all) into numba's on-disk cache, so "
                    "that later runs, worker processes and machines sharing NUMBA_CACHE_DIR "
                    "start at once.  Families: " + ", ".join(FAMILIES) + "; the physical "
                    "family is compiled per reset mode.")
    p.add_argument("families", nargs="*", metavar="FAMILY",
                   help="families to compile (default: all)")
    p.add_argument("--reset", action="append", choices=RESETS, metavar="RESET",
                   help="the physical family's reset mode to compile (" + ", ".join(RESETS)
                        + "; repeat for several; default: all three)")
    p.add_argument("--measure", action="store_true",
                   help="compile each family in a fresh process with an empty temporary cache "
                        "and print its wall and CPU time (with the interpreter's start and "
                        "imports) and peak memory; leaves your cache alone")
    p.add_argument("--json", metavar="PATH", help="with --measure: also write the table as JSON")
    p.set_defaults(func=run)


def run(args) -> int:
    from spikesim._numba_cache import cache_folder
    from spikesim.families import FAMILIES, RESETS, family_markers
    from spikesim.precompile import precompile

    names = args.families or list(FAMILIES)
    resets = args.reset or list(RESETS)
    for name in names:
        family_markers(name)  # a one-line error for an unknown name
    if args.json and not args.measure:
        from spikesim.errors import SpikeSimValueError

        raise SpikeSimValueError("--json needs --measure (it writes the measured table)")
    if args.measure:
        return _measure(names, resets, args.json)
    folder = cache_folder(_package_dir())
    print(f"compiling {', '.join(names)} into {folder}", file=sys.stderr, flush=True)
    os.environ.setdefault("SPIKESIM_QUIET_COMPILE", "1")  # this command says it itself

    def report(name, seconds):
        print(f"  {name}: {seconds:.1f} s", file=sys.stderr, flush=True)

    precompile(names, progress=report, resets=resets)
    print("done: later runs load these kernels from the cache", file=sys.stderr)
    return 0


def _package_dir():
    from pathlib import Path

    import spikesim

    return Path(spikesim.__file__).parent


def _measure(families, resets, json_path) -> int:
    from spikesim.families import kernel_name

    rows = []
    print("| kernel | wall (s) | CPU (s) | peak memory (MB) |")
    print("|---|---:|---:|---:|")
    jobs = [(kernel_name(f, r), f, r) for f in families
            for r in (resets if f == "physical" else resets[:1])]
    for name, family, reset in jobs:
        with tempfile.TemporaryDirectory(prefix="spikesim-compile-") as cache:
            env = dict(os.environ, NUMBA_CACHE_DIR=cache, SPIKESIM_QUIET_COMPILE="1")
            t0 = time.perf_counter()
            done = subprocess.run([sys.executable, "-c", _CHILD, family, reset], env=env,
                                  capture_output=True, text=True)
            wall = time.perf_counter() - t0
        if done.returncode != 0:
            tail = (done.stderr.strip().splitlines() or ["no output"])[-1]
            print(f"spikesim compile: error: compiling {name} failed: {tail}", file=sys.stderr)
            return 1
        got = json.loads(done.stdout.strip().splitlines()[-1])
        rows.append({"kernel": name, "wall_s": round(wall, 1), "cpu_s": round(got["cpu_s"], 1),
                     "peak_rss_mb": round(got["peak_rss_mb"])})
        print(f"| {name} | {wall:.1f} | {got['cpu_s']:.1f} | {got['peak_rss_mb']:.0f} |",
              flush=True)
    if json_path:
        with open(json_path, "w") as fh:
            json.dump({"cpu_count": os.cpu_count(), "families": rows}, fh, indent=2)
    return 0
