"""``spikesim verify PATH``: read everything, check every checksum, report damage."""

from __future__ import annotations

import json
from pathlib import Path

from spikesim.errors import SpikeSimValueError
from spikesim.io.verify import SPIKE_SUFFIXES

__all__ = ["EXIT_NOTHING", "EXIT_UNCHECKED", "exit_status", "nothing_to_verify", "register",
           "run", "summary_line"]


#: Exit status when nothing is damaged but some file could not be checked (a .dat of
#: unknown frame size).  0: every file checked and ok; 1: something is damaged.
EXIT_UNCHECKED = 3
#: Exit status when PATH holds nothing to verify (no such path, or a folder without a
#: .h5, .hdf5 or .dat file), or an option's value is bad: a usage error, as argparse's,
#: never read as "damaged".
EXIT_NOTHING = 2



def register(subparsers) -> None:
    p = subparsers.add_parser(
        "verify", help="read every chunk of spike files and report damage",
        description="Open each .h5 file (or every file under a folder), read all its chunks "
                    "against their checksums and its ground truth for NaN/inf; check .dat "
                    "lengths. Exit status 0 when every file was checked and is ok, 1 when "
                    "anything is damaged, 2 when PATH does not exist or holds no such file (or "
                    "an option is wrong), 3 "
                    "when nothing is damaged but some .dat file could not be checked (its "
                    "frame size is unknown: give --height and --width).",
    )
    p.add_argument("path", help="a .h5 or .dat file, or a folder")
    p.add_argument("--height", type=int, help="frame height of .dat files (else guessed)")
    p.add_argument("--width", type=int, help="frame width of .dat files (else guessed)")
    p.add_argument("--json", action="store_true", help="print the reports as JSON")
    # a bad option value is a usage error (2), as argparse's, never 1 ("damaged")
    p.set_defaults(func=run, usage_status=EXIT_NOTHING)


def _line(r: dict) -> str:
    """The line printed for one report."""
    status = r.get("status")
    if status == "damaged":
        advice = f"; to fix: {r['advice']}" if r.get("advice") else ""
        return f"DAMAGED {r['path']}: " + "; ".join(r["problems"]) + advice
    if status == "unchecked":
        return f"UNCHECKED {r['path']}: " + "; ".join(r["notes"])
    if status == "temp":
        return f"temp    {r['path']}: " + "; ".join(r["notes"])
    extra = f" ({r['readouts']} readouts)" if "readouts" in r else ""
    note = f"; note: {'; '.join(r['notes'])}" if r["notes"] else ""
    return f"ok      {r['path']}{extra}{note}"


def summary_line(counts: dict) -> str:
    """``N file(s): C checked, K ok, D damaged, U unchecked`` and how to check the rest."""
    line = (f"{counts['files']} file(s): {counts['checked']} checked, {counts['ok']} ok, "
            f"{counts['damaged']} damaged, {counts['unchecked']} unchecked")
    if counts["unchecked"]:
        line += (" (not verified: give the .dat frame size with --height and --width to check "
                 f"{'it' if counts['unchecked'] == 1 else 'them'})")
    return line


def nothing_to_verify(path: Path) -> str | None:
    """Why ``path`` holds nothing to verify (it does not exist, is a file of another kind,
    or is a folder with no ``.h5``, ``.hdf5`` or ``.dat`` file, nor a writer's temporary,
    at any depth); None when it holds something."""
    from spikesim.io.atomic import is_temp_name

    if not path.exists():
        return f"no such file or folder: {str(path)!r}: check the path"
    if path.is_file() and path.suffix.lower() not in SPIKE_SUFFIXES and not is_temp_name(path):
        return (f"{str(path)!r} is not a spike file (.h5, .hdf5 or .dat): give a spike file "
                "or a folder holding some")
    def spike_or_temp(p: Path) -> bool:
        return (p.suffix.lower() in SPIKE_SUFFIXES or is_temp_name(p)) and p.is_file()

    if path.is_dir() and not any(spike_or_temp(p) for p in path.rglob("*")):
        return (f"no .h5, .hdf5 or .dat file found in the folder {str(path)!r} (nor in its "
                "subfolders): give a spike file or a folder holding some")
    return None


def exit_status(counts: dict) -> int:
    """1 if anything is damaged, else 3 if some file was not checked, else 0."""
    if counts["damaged"]:
        return 1
    return EXIT_UNCHECKED if counts["unchecked"] else 0


def run(args) -> int:
    from spikesim._validate import check_int
    from spikesim.commands._io_common import SIZE_PAIR
    from spikesim.io.verify import summarize, verify

    # value errors are usage errors here (usage_status: exit 2, never 1, "damaged")
    for flag, value in (("--height", args.height), ("--width", args.width)):
        if value is not None:
            check_int(flag, value, 1, unit="pixels")
    if (args.height is None) != (args.width is None):
        raise SpikeSimValueError(SIZE_PAIR)
    why = nothing_to_verify(Path(args.path))
    if why:
        raise SpikeSimValueError(why)
    reports = verify(args.path, args.height, args.width)
    counts = summarize(reports)
    if args.json:
        print(json.dumps(reports, indent=1))
    else:
        for r in reports:
            print(_line(r))
        print(summary_line(counts))
    return exit_status(counts)
