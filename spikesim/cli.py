"""Command line ``spikesim``: a thin layer that parses, calls library functions,
and maps errors to exit codes.

Each sub-command lives in ``spikesim/commands/<name>.py`` and exposes
``register(subparsers)``, which adds its parser and sets ``func`` to a callable
taking the parsed namespace and returning an exit code.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from spikesim._version import __version__
from spikesim.cli_guard import OneLineParser, check_cli_numbers, debug_requested, run_guarded
from spikesim.errors import SpikeSimValueError

#: Modules under spikesim.commands, in the order their commands are listed.
COMMAND_MODULES = (
    "demo",
    "simulate",
    "presets",
    "scenes",
    "dataset",
    "manifests",
    "info",
    "convert",
    "preview",
    "analyze",
    "verify",
    "compile",
)

EXIT_OK = 0
EXIT_USAGE = 2
EXIT_ERROR = 1


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="spikesim", description="Bayer spike-camera simulator (spikesim)."
    )
    parser.add_argument("--version", action="version", version=f"spikesim {__version__}")
    parser.add_argument("--debug", action="store_true",
                        help="show Python tracebacks instead of one-line errors (anywhere on "
                             "the line; or set SPIKESIM_DEBUG=1)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        try:
            module = importlib.import_module(f"spikesim.commands.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"spikesim.commands.{name}":
                continue  # command not part of this build
            raise
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    debug = debug_requested(argv)
    argv = [a for a in argv if a != "--debug"]
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return EXIT_USAGE
    # errors are prefixed with the command's full name, as argparse's own
    # (``spikesim analyze calibrate``, not ``spikesim analyze``)
    label = parser.command_parser(args).prog

    def call():
        try:
            check_cli_numbers(args)
            return args.func(args)
        except SpikeSimValueError as exc:
            status = getattr(args, "usage_status", None)  # verify: 1 would say "damaged"
            if status is None or debug:
                raise
            print(f"{label}: error: {exc}", file=sys.stderr)
            return status

    return run_guarded(label, call, debug=debug)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
