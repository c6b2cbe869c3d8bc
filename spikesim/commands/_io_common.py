"""Options shared by the file commands (info, convert, preview) to open a spike file."""

from __future__ import annotations

import argparse

from spikesim.io.dat import HALF_SIZE as SIZE_PAIR
from spikesim.io.source import open_source

__all__ = ["add_source_options", "command_label", "parse_crop", "resolve_path",
           "source_from_args"]


def add_source_options(parser: argparse.ArgumentParser) -> None:
    g = parser.add_argument_group("input")
    g.add_argument("--split", default=None,
                   help="split folder of a dataset root (as `spikesim dataset` writes it)")
    g.add_argument("--sequence", default=None,
                   help="sequence name (or position) in a dataset folder; default: the first")
    g.add_argument("--height", type=int, default=None,
                   help=".dat: frame height in pixels (default: guess from known sensor sizes)")
    g.add_argument("--width", type=int, default=None,
                   help=".dat: stored frame width in pixels, head columns included")
    g.add_argument("--no-flip", dest="flip", action="store_false",
                   help=".dat: the file is stored top row first (default: upside down, PKU)")
    g.add_argument("--drop-head", action="store_true",
                   help=".dat: drop the 16 head columns of a raw 416-wide capture")
    g.add_argument("--partial", choices=("error", "drop"), default="error",
                   help=".dat: a trailing partial frame is an error (default) or dropped")
    g.add_argument("--cfa", default=None,
                   help=".dat: Bayer pattern of the sensor (RGGB, BGGR, GRBG, GBRG; default mono)")
    g.add_argument("--clock-hz", type=float, default=None, help=".dat: readout clock in Hz")


def _sequence_key(text):
    if text is None:
        return None
    return int(text) if text.lstrip("-").isdigit() else text


def source_from_args(args: argparse.Namespace, path):
    """Open ``path`` per the options; library warnings become one ``note:`` line on stderr."""
    import sys
    import warnings

    from spikesim.cli_guard import as_option
    from spikesim.errors import SpikeSimValueError
    from spikesim.io.dat import RAW_HEAD_COLUMNS
    from spikesim.io.source import is_dat

    if is_dat(path) and (args.height is None) != (args.width is None):
        raise SpikeSimValueError(SIZE_PAIR)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            if not is_dat(path):
                path = resolve_path(path, getattr(args, "split", None))
            src = open_source(
                path, sequence=_sequence_key(args.sequence), height=args.height,
                width=args.width, flip=args.flip,
                head_columns=RAW_HEAD_COLUMNS if args.drop_head else 0, cfa=args.cfa,
                clock_hz=args.clock_hz, partial=args.partial,
            )
        except SpikeSimValueError as exc:  # name the options, not the reader's parameters
            named = as_option(exc, OPTION_NAMES)
            if named is exc and str(exc).startswith("head_columns="):
                named = type(exc)(f"--drop-head: {exc}")
            raise named from None
    for w in caught:
        print(f"{command_label(args)}: note: {w.message}", file=sys.stderr)
    if not is_dat(path):
        unused = [flag for flag, given in DAT_ONLY.items() if given(args)]
        if unused:
            print(f"{command_label(args)}: note: {', '.join(unused)} ignored: they describe a "
                  ".dat capture, and a spikesim HDF5 file records its own", file=sys.stderr)
    return src


#: The options of a ``.dat`` capture only (an HDF5 file records its size, CFA and
#: clock): flag -> whether it was given.
DAT_ONLY = {
    "--height": lambda a: a.height is not None, "--width": lambda a: a.width is not None,
    "--no-flip": lambda a: not a.flip, "--drop-head": lambda a: a.drop_head,
    "--partial": lambda a: a.partial != "error", "--cfa": lambda a: a.cfa is not None,
    "--clock-hz": lambda a: a.clock_hz is not None,
}



#: The reader's parameters (as its errors name them) -> the options of add_source_options.
OPTION_NAMES = {"sequence": "--sequence", "split": "--split", "cfa": "--cfa",
                "clock_hz": "--clock-hz", "height": "--height", "width": "--width",
                "partial": "--partial"}


def resolve_path(path, split):
    """:func:`spikesim.io.index.resolve_dataset`, its errors naming ``--split``."""
    from spikesim.cli_guard import as_option
    from spikesim.errors import SpikeSimValueError
    from spikesim.io.index import resolve_dataset

    try:
        return resolve_dataset(path, split)
    except SpikeSimValueError as exc:
        raise as_option(exc, {"split": "--split"}) from None


def command_label(args: argparse.Namespace) -> str:
    """``spikesim info``, or ``spikesim analyze calibrate`` for a study of analyze."""
    study = getattr(args, "study", None)
    return f"spikesim {args.command}" + (f" {study}" if study else "")


def parse_crop(text: str | None):
    """``TOP,LEFT,HEIGHT,WIDTH`` -> tuple of ints (validated later by the reader)."""
    if text is None:
        return None
    parts = text.split(",")
    if len(parts) != 4 or not all(p.strip().isdigit() for p in parts):
        raise argparse.ArgumentTypeError(f"--crop {text!r}: expected TOP,LEFT,HEIGHT,WIDTH")
    return tuple(int(p) for p in parts)
