"""Command line ``spikejdd``: a thin layer over :mod:`spikejdd.evaluate`.

``spikejdd evaluate --data DIR --methods a,b,c [--out STEM]``
``spikejdd evaluate --sweep [--methods ...] [--size 64x96] [--out STEM]``
``spikejdd methods``
"""

from __future__ import annotations

import argparse
import shlex
import sys

from spikesim.errors import SpikeSimError

__all__ = ["main", "build_parser"]


def _size(text: str) -> tuple[int, int]:
    try:
        h, w = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--size {text!r}: expected HxW, e.g. 64x96") from None
    return h, w


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="spikejdd", description="Spike-camera JDD reconstruction.")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    ev = sub.add_parser("evaluate", help="score methods (PSNR/SSIM) and time them")
    ev.add_argument("--data", help="spikesim HDF5 file or folder")
    ev.add_argument("--sweep", action="store_true",
                    help="Table-1-shaped sweep on sets simulated on the fly")
    ev.add_argument("--methods", default=None,
                    help="comma-separated method names (default: the standard pipelines)")
    ev.add_argument("--context", type=int, default=41, help="readouts given to each method")
    ev.add_argument("--per-sequence", type=int, default=1, help="GT frames per sequence")
    ev.add_argument("--repeats", type=int, default=3, help="timed calls per frame (median)")
    ev.add_argument("--size", type=_size, default=(64, 96), help="sweep frame size HxW")
    ev.add_argument("--frames-per-scene", type=int, default=2)
    ev.add_argument("--seed", type=int, default=0)
    ev.add_argument("--out", default="evaluation", help="output path stem (.json/.md/.png)")
    ev.add_argument("--quiet", action="store_true", help="no progress bars")
    sub.add_parser("methods", help="list reconstruction methods")
    return p


def _evaluate(args) -> int:
    from spikejdd import evaluate
    from spikejdd.pipelines import standard_pipelines

    methods = ([m.strip() for m in args.methods.split(",") if m.strip()]
               if args.methods else standard_pipelines())
    if args.sweep == bool(args.data):
        print("spikejdd evaluate: give exactly one of --data DIR or --sweep", file=sys.stderr)
        return 2
    if args.sweep:
        result = evaluate.sweep(methods, size=args.size, context=args.context,
                                frames_per_scene=args.frames_per_scene, repeats=args.repeats,
                                seed=args.seed, progress=not args.quiet)
    else:
        frames = evaluate.frames_from_dataset(args.data, args.context, args.per_sequence)
        result = evaluate.run(frames, methods, repeats=args.repeats, progress=not args.quiet)
    command = "spikejdd " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    paths = evaluate.write_report(result, methods, args.out, command=command)
    for m in methods:
        e = result["summary"][m]["all"]
        print(f"{m:32s} PSNR[linear] {e['PSNR[linear]']:6.2f} dB  "
              f"SSIM-gauss11[linear] {e['SSIM-gauss11[linear]']:.4f}  "
              f"{e['ms_per_frame']:8.1f} ms/frame")
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        if args.command == "evaluate":
            return _evaluate(args)
        if args.command == "methods":
            from spikejdd import list_methods

            for name, desc in list_methods().items():
                print(f"{name:32s} {desc}")
            return 0
        parser.print_help()
        return 2
    except SpikeSimError as exc:
        print(f"spikejdd: error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
