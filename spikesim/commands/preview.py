"""``spikesim preview PATH --out x.png|x.gif``: look at a spike stream.

A PNG shows one TFP or TFI image at a chosen readout; a GIF animates over
readouts.  Bayer streams are demosaiced (Malvar 2004); images are
sRGB-encoded for viewing (``spikesim.io.preview``).
"""

from __future__ import annotations

from spikesim.commands._io_common import add_source_options, source_from_args

__all__ = ["register", "run"]

#: TFP window (readouts) when ``--window`` is not given and the stream is longer.
DEFAULT_WINDOW = 41


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "preview", help="write a TFP/TFI preview image (.png) or animation (.gif)",
        description="Reconstruct a viewable image from a spike file with TFP or TFI "
                    "(demosaiced for colour, sRGB-encoded): one frame to .png, or an animation "
                    "over readouts to .gif.",
    )
    p.add_argument("path", help="a .h5 file, a dataset folder (see --sequence) or a .dat")
    p.add_argument("--out", required=True, help="output image: *.png or *.gif")
    p.add_argument("--method", choices=("tfp", "tfi"), default="tfp",
                   help="estimator (default tfp)")
    p.add_argument("--readout", type=int, default=None,
                   help="readout to show (PNG) or first readout (GIF); default: the middle / "
                        "start of the stream")
    p.add_argument("--window", type=int, default=None,
                   help="TFP window in readouts (default 41, or the whole stream when shorter)")
    p.add_argument("--rate", type=float, default=None,
                   help="spikes per readout at full scale (default: from the file, else 0.6)")
    p.add_argument("--frames", type=int, default=24, help="GIF: number of frames (default 24)")
    p.add_argument("--step", type=int, default=None,
                   help="GIF: readouts between frames (default: spread over the stream)")
    p.add_argument("--fps", type=float, default=10.0, help="GIF: frames per second (default 10)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_source_options(p)
    p.set_defaults(func=run)


def _gif_readouts(n: int, first: int | None, frames: int, step: int | None, window: int):
    from spikesim.errors import bad_value

    if frames < 1:
        raise bad_value("--frames", frames, "at least 1")
    half = min(window, n) // 2
    first = half if first is None else first
    if step is None:
        step = max(1, (n - half - first) // frames)
    if step < 1:
        raise bad_value("--step", step, "at least 1 readout")
    return [r for r in range(first, n, step)][:frames]


def run(args) -> int:
    from spikesim._validate import check_int, check_real
    from spikesim.errors import bad_value
    from spikesim.io.preview import render_frames, save_image

    check_real("--fps", args.fps, 0, 100, low_open=True, unit="GIF frames per second")
    if args.rate is not None:
        check_real("--rate", args.rate, 0, 1, low_open=True, unit="spikes per readout")
    if args.window is not None:
        check_int("--window", args.window, 1, unit="readouts")
    if not args.out.lower().endswith((".png", ".gif")):
        raise bad_value("--out", args.out, "a path ending in .png or .gif")
    src = source_from_args(args, args.path)
    n = src.n_readouts
    window = min(DEFAULT_WINDOW, n) if args.window is None else args.window
    if window > n:
        raise bad_value("--window", window, f"at most the stream's {n} readouts")
    if args.readout is not None:
        check_int("--readout", args.readout, 0, n - 1, unit="readout index")
    if args.out.lower().endswith(".gif"):
        readouts = _gif_readouts(n, args.readout, args.frames, args.step, window)
        if len(readouts) < args.frames:
            import sys

            print(f"spikesim preview: note: {len(readouts)} of the {args.frames} frames asked "
                  f"for fit in the stream's {n} readouts (--step, --readout)", file=sys.stderr)
    else:
        readouts = [n // 2 if args.readout is None else args.readout]
    frames = render_frames(src, readouts, args.method, window, args.rate,
                           progress=not args.quiet and len(readouts) > 1)
    save_image(args.out, frames, fps=args.fps)
    print(f"wrote {args.out} ({len(frames)} frame{'s' if len(frames) > 1 else ''}, "
          f"{args.method}, readout{'s' if len(frames) > 1 else ''} "
          f"{readouts[0]}{'..' + str(readouts[-1]) if len(frames) > 1 else ''})")
    return 0
