"""``spikesim verify PATH``: read everything, check every checksum, report damage."""

from __future__ import annotations

import json

from spikesim.errors import SpikeSimValueError

__all__ = ["register", "run"]


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "verify", help="read every chunk of spike files and report damage",
        description="Open each .h5 file (or every file under a folder), read all its chunks "
                    "against their checksums and its ground truth for NaN/inf; check .dat "
                    "lengths. Exit status 1 when anything is damaged.",
    )
    p.add_argument("path", help="a .h5 or .dat file, or a folder")
    p.add_argument("--height", type=int, help="frame height of .dat files (else guessed)")
    p.add_argument("--width", type=int, help="frame width of .dat files (else guessed)")
    p.add_argument("--json", action="store_true", help="print the reports as JSON")
    p.set_defaults(func=run)


def run(args) -> int:
    from spikesim._validate import check_int
    from spikesim.io.verify import verify

    for flag, value in (("--height", args.height), ("--width", args.width)):
        if value is not None:
            check_int(flag, value, 1, unit="pixels")
    if (args.height is None) != (args.width is None):
        raise SpikeSimValueError("give both --height and --width (the .dat frame size), or "
                                 "neither to have it guessed")
    reports = verify(args.path, args.height, args.width)
    if args.json:
        print(json.dumps(reports, indent=1))
    else:
        for r in reports:
            if not r["ok"]:
                print(f"DAMAGED {r['path']}: " + "; ".join(r["problems"]))
            elif r.get("unchecked"):
                print(f"unknown {r['path']}: " + "; ".join(r["notes"]))
            elif r["kind"] == "temp":
                print(f"temp    {r['path']}: " + "; ".join(r["notes"]))
            else:
                extra = f" ({r['readouts']} readouts)" if "readouts" in r else ""
                note = f"; note: {'; '.join(r['notes'])}" if r["notes"] else ""
                print(f"ok      {r['path']}{extra}{note}")
        bad = sum(not r["ok"] for r in reports)
        files = sum(r["kind"] != "temp" for r in reports)
        print(f"{files - bad} of {files} file(s) ok" + (f", {bad} damaged" if bad else ""))
    return 1 if any(not r["ok"] for r in reports) else 0
