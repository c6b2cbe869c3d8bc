"""``spikesim dataset MANIFEST --out DIR``: build a dataset (see spikesim.dataset)."""

from __future__ import annotations

import json
import sys


def register(sub) -> None:
    p = sub.add_parser("dataset", help="build a dataset from a TOML manifest",
                       description="MANIFEST is a TOML file or builtin:NAME (see --list).")
    p.add_argument("manifest", nargs="?", help="manifest.toml or builtin:NAME")
    p.add_argument("--out", help="output folder")
    p.add_argument("--workers", type=int, default=1, help="local worker processes (spawned)")
    p.add_argument("--dask-local", type=int, default=None, metavar="N",
                   help="start a local Dask cluster with N worker processes")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run on an existing Dask scheduler, e.g. tcp://10.0.0.1:8786")
    p.add_argument("--limit", type=int, default=None, help="only the first N sequences")
    p.add_argument("--prune", action="store_true",
                   help="delete sequence files in the output that the manifest no longer makes "
                        "(left by a build of an earlier version of it)")
    p.add_argument("--dry-run", action="store_true",
                   help="print the plan with disk and time estimates, write nothing")
    p.add_argument("--list", action="store_true", help="list the built-in manifests")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="value of ${NAME} in the manifest (e.g. REDS=/data/REDS); "
                        "default: the environment variable NAME")
    p.set_defaults(func=run)


def run(args) -> int:
    from spikesim.cli_guard import as_option
    from spikesim.dataset import (
        BuildFailedError,
        build_dataset,
        builtin_manifests,
        estimate_dataset,
        load_manifest,
    )
    from spikesim.errors import SpikeSimValueError

    if args.list:
        for name, desc in builtin_manifests().items():
            print(f"builtin:{name:20s} {desc}")
        return 0
    if not args.manifest:
        raise SpikeSimValueError("MANIFEST is required (a .toml file or builtin:NAME)")
    variables = {}
    for item in args.set:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise SpikeSimValueError(f"--set {item!r}: expected NAME=VALUE")
        variables[name.strip()] = value
    from spikesim._validate import check_int
    from spikesim.dataset.build import check_executors

    check_int("--workers", args.workers, 1, 1024, unit="processes")
    if args.dask_local is not None:
        check_int("--dask-local", args.dask_local, 1, 1024, unit="Dask workers")
    if args.limit is not None:
        check_int("--limit", args.limit, 1, unit="sequences")
    check_executors(args.workers, args.scheduler, args.dask_local,
                    names=("--workers", "--scheduler", "--dask-local"))
    manifest = load_manifest(args.manifest, variables)
    if args.dry_run:
        try:
            est = estimate_dataset(manifest, workers=args.workers, limit=args.limit,
                                   dask_local=args.dask_local, out_dir=args.out)
        except SpikeSimValueError as exc:
            raise as_option(exc, {"out_dir": "--out"}) from None
        print(json.dumps(est, indent=2))  # stdout holds only the JSON: the summary is for people
        if not est["to_make"]:
            print(f"plan: {est['sequences']} sequence{'' if est['sequences'] == 1 else 's'} "
                  f"({est['by_split']}), all already made in {args.out}: nothing to build",
                  file=sys.stderr)
            return 0
        print(f"plan: {est['sequences']} sequence{'' if est['sequences'] == 1 else 's'} "
              f"({est['by_split']}), {est['to_make']} to "
              f"make, {est['px_readouts']:.3g} pixel-readouts, about "
              f"{est['estimated_bytes'] / 2**20:.1f} MiB and {est['estimated_seconds']:.0f} s "
              f"({est['executor']}, {est['startup_seconds']:.1f} s of it start-up)",
              file=sys.stderr)
        if args.scheduler:
            print("(a dry run does not contact the scheduler: the estimate is for a serial "
                  "build on this machine)", file=sys.stderr)
        if est.get("compile_seconds"):
            print(f"(this dry run also compiled the simulation kernels, "
                  f"{est['compile_seconds']:.0f} s: a one-off after installing or upgrading "
                  "spikesim, not counted above)", file=sys.stderr)
        return 0
    if not args.out:
        raise SpikeSimValueError("--out is required (the output folder)")
    try:
        summary = build_dataset(manifest, args.out, workers=args.workers,
                                scheduler=args.scheduler, dask_local=args.dask_local,
                                limit=args.limit, prune=args.prune, progress=not args.quiet)
    except BuildFailedError as exc:  # every sequence failed: listed below, exit status 1
        summary = exc.summary
    except SpikeSimValueError as exc:
        raise as_option(exc, {"out_dir": "--out"}) from None
    print(summary.line())
    for rec in summary.failures:
        print(f"  failed {rec['file']}: {rec['error']}")
    return 0 if summary.failed == 0 else 1
