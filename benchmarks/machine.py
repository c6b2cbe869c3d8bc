"""The machine a benchmark ran on, as it describes itself (never fixed text), and
the command line it ran with, as given.

Imported by the ``bench_*.py`` scripts (run as ``python benchmarks/bench_x.py``,
so this folder is on ``sys.path``).  Import it first: the load average at
import time is the one "at the start" of the run.
"""

from __future__ import annotations

import os
import shlex
import sys
from pathlib import Path

from spikejdd.runtime import describe_machine, machine_info

__all__ = ["LOAD_AT_START", "load_average", "describe", "command_line", "print_medians"]


def load_average() -> float | None:
    """The 1-minute load average now (None where the OS does not tell it)."""
    try:
        return os.getloadavg()[0]
    except (AttributeError, OSError):
        return None


#: The 1-minute load average when the benchmark started.
LOAD_AT_START = load_average()


def describe() -> str:
    """One line: CPU, cores, memory, torch threads, OS, and the load average at the
    start and now (other jobs on the machine show as a load above zero)."""
    info = machine_info()
    info.pop("load_average_1min", None)
    text = describe_machine(info)
    end = load_average()
    if LOAD_AT_START is not None and end is not None:
        text += f"; 1-min load average {LOAD_AT_START:.2f} at the start, {end:.2f} at the end"
    return text


def command_line(script: str, argv: list[str] | None = None) -> str:
    """``python benchmarks/SCRIPT`` and every argument as given (``argv``, default
    ``sys.argv[1:]``), quoted for a POSIX shell where needed: the line a results
    file records, so that running it again repeats the run."""
    args = sys.argv[1:] if argv is None else [str(a) for a in argv]
    return shlex.join(["python", f"benchmarks/{Path(script).name}", *args])


def print_medians(script: str, argv: list[str] | None, key: str, unit: str,
                  times: dict, digits: int = 2) -> None:
    """Print the machine and command lines, then a Markdown table with one row
    per entry of ``times`` (key → repeated timings in ``unit``): the key
    (column ``key``), the median and the range of its timings."""
    print(f"Machine: {describe()}. Command: `{command_line(script, argv)}`\n")
    print(f"| {key} | {unit}, median | range |\n|---:|---:|---|")
    for name, values in times.items():
        v = sorted(values)
        print(f"| {name} | {v[len(v) // 2]:.{digits}f} | {v[0]:.{digits}f}–{v[-1]:.{digits}f} |")
