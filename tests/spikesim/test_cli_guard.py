"""A stop (SIGTERM, Ctrl-C) that lands while a progress bar is being built
still ends in the stop's one line: the half-built bar's finalizer report is
dropped."""

from __future__ import annotations

import gc
import os
import signal
import sys
import time

import numpy as np
import pytest
from tqdm import tqdm

from spikesim import cli_guard
from spikesim.cli_guard import EXIT_INTERRUPTED, EXIT_TERMINATED, Terminated, run_guarded


class _CutShort(tqdm):
    """A bar whose construction the signal interrupts half way (tqdm has set
    ``disable`` but not ``pos``, which its ``close`` reads)."""

    def __init__(self, stop):
        self.disable = False
        raise stop()


@pytest.mark.parametrize("stop, code, line", [
    (Terminated, EXIT_TERMINATED, "stopped by SIGTERM"),
    (KeyboardInterrupt, EXIT_INTERRUPTED, "interrupted"),
])
def test_a_stop_inside_a_progress_bar_gives_its_one_line_and_nothing_more(stop, code, line,
                                                                          capsys, monkeypatch):
    reported = []
    monkeypatch.setattr(sys, "unraisablehook", reported.append)

    def call():
        _CutShort(stop)

    assert run_guarded("spikesim test", call) == code
    gc.collect()
    err = capsys.readouterr().err
    assert err.splitlines() == [f"spikesim test: {line}; files being written were removed"]
    assert reported == []
    # other finalizers' reports still reach the hook that was there
    sys.unraisablehook(type("U", (), {"object": print, "exc_value": ValueError()})())
    assert len(reported) == 1


def test_an_error_during_a_progress_bar_is_a_line_of_its_own(capsys):
    """An error raised while a bar is drawn ends the bar (its line cleared) and is
    printed on a line of its own, with no bar drawn again after it; a warning
    during the work is printed above the bar, which goes on."""
    import warnings

    from spikesim.errors import SpikeSimValueError

    def call():
        bar = tqdm(total=10, desc="work", file=sys.stderr)
        bar.update(3)
        warnings.warn("careful", stacklevel=2)
        bar.update(3)
        raise SpikeSimValueError("x=1 is invalid")

    assert run_guarded("spikesim test", call) == 1
    err = capsys.readouterr().err
    tail = err.rsplit("\r", 1)[-1]
    assert tail == "spikesim test: error: x=1 is invalid\n", repr(err)
    assert "spikesim test: warning: careful\n" in err
    gc.collect()
    assert capsys.readouterr().err == ""


def test_a_number_below_its_range_names_the_bound_not_the_cap(capsys):
    """`--window 0` says 'an integer >= 1', not the 2**40 cap of readout counts."""
    import argparse

    from spikesim.cli_guard import check_cli_numbers
    from spikesim.errors import SpikeSimValueError

    with pytest.raises(SpikeSimValueError, match=r"--window=0 is invalid: expected an integer "
                                                 r">= 1 \(readouts\)"):
        check_cli_numbers(argparse.Namespace(window=0))
    with pytest.raises(SpikeSimValueError, match=r"--window=.* in \[1, 1099511627776\]"):
        check_cli_numbers(argparse.Namespace(window=2**41))


def test_as_option_names_the_command_line_flag():
    from spikesim.cli_guard import as_option
    from spikesim.errors import SpikeSimFileError, SpikeSimValueError, bad_value

    err = as_option(bad_value("speed", 50.0, "None for scene 'flat'"), {"speed": "--speed"})
    assert isinstance(err, SpikeSimValueError)
    assert str(err) == "--speed=50.0 is invalid: expected no --speed for scene 'flat'"
    other = SpikeSimFileError("no such file")
    assert as_option(other, {"speed": "--speed"}) is other


@pytest.mark.parametrize("argv, named", [
    (["simulate", "flat", "--size", "-4x8", "--readouts", "2", "--out", "x.h5"],
     "--size='-4x8' is invalid"),
    (["simulate", "flat", "--size", "8x8", "--readouts", "-5", "--out", "x.h5"],
     "--readouts=-5 is invalid"),
])
def test_a_value_starting_with_a_dash_is_checked_as_the_options_value(argv, named, capsys,
                                                                        tmp_path, monkeypatch):
    """argparse reads ``-4x8`` as an unknown option ("expected one argument"); the
    parser joins it to its option so that the option's own check names it."""
    from spikesim.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert named in err and "expected one argument" not in err
    assert list(tmp_path.iterdir()) == []


def test_a_dash_value_is_not_joined_to_a_flag_or_after_the_option_list():
    from spikesim.cli_guard import OneLineParser

    p = OneLineParser(prog="t")
    p.add_argument("--size")
    p.add_argument("--quiet", action="store_true")
    p.add_argument("rest", nargs="*")
    assert p._join_dashed_values(["--size", "-4x8", "--quiet", "--", "--size", "-1"]) == [
        "--size=-4x8", "--quiet", "--", "--size", "-1"]
    assert p.parse_args(["--size", "-.5"]).size == "-.5"


def _two_level_parser():
    import argparse

    from spikesim.cli_guard import OneLineParser

    def pair(text):
        raise argparse.ArgumentTypeError(f"--pair={text!r} is invalid: expected A,B")

    p = OneLineParser(prog="tool")
    sub = p.add_subparsers(dest="command")
    group = sub.add_parser("group").add_subparsers(dest="study")
    leaf = group.add_parser("leaf")
    leaf.add_argument("--pair", type=pair)
    sub.add_parser("plain")
    return p


@pytest.mark.parametrize("argv, prog", [
    (["plain", "--bogus", "1"], "tool plain"),
    (["group", "leaf", "--bogus", "1"], "tool group leaf"),
])
def test_leftover_arguments_are_reported_by_the_chosen_subcommand(argv, prog, capsys):
    """Leftovers were reported by the top-level parser (``tool: error: unrecognized
    arguments: ... (see tool --help)``), whose help does not list the subcommand's
    options they were taken for."""
    p = _two_level_parser()
    with pytest.raises(SystemExit) as stop:
        p.parse_args(argv)
    assert stop.value.code == 2
    assert capsys.readouterr().err == (f"{prog}: error: unrecognized arguments: --bogus 1 "
                                       f"(see {prog} --help)\n")
    assert p.command_parser(p.parse_args(argv[:-2])).prog == prog


def test_a_converters_error_names_its_option_once(capsys):
    """argparse prefixes a converter's message with ``argument --pair: ``, which named
    the option twice (``argument --pair: --pair='x' is invalid``)."""
    with pytest.raises(SystemExit) as stop:
        _two_level_parser().parse_args(["group", "leaf", "--pair", "x"])
    assert stop.value.code == 2
    assert capsys.readouterr().err == ("tool group leaf: error: --pair='x' is invalid: "
                                       "expected A,B (see tool group leaf --help)\n")


def test_a_size_beyond_the_free_memory_is_refused_before_any_work(capsys, tmp_path, monkeypatch):
    """`spikesim simulate --size 30000x30000` names the memory it needs and what is
    free, instead of swapping until the system kills it; `--force` goes on."""
    from spikesim import workload
    from spikesim.cli import main

    monkeypatch.setattr(workload, "available_memory", lambda: 2**30)
    out = tmp_path / "x.h5"
    argv = ["simulate", "flat", "--readouts", "2", "--out", str(out)]
    assert main(argv + ["--size", "2000x2000"]) == 1
    err = capsys.readouterr().err
    assert ("--size 2000x2000 needs about 1.49 GiB of memory but 1 GiB is free: ask for a "
            "smaller --size, or pass --force") in err
    assert not out.exists()
    assert main(argv + ["--size", "16x16", "--force"]) == 0
    assert out.exists()


def test_the_free_memory_is_read_from_the_system():
    from spikesim.workload import available_memory

    free = available_memory()
    assert free is None or 2**20 < free < 2**50


def test_opencvs_failed_allocation_is_the_memory_error_line(capsys):
    import cv2

    def call():
        cv2.resize(np.zeros((4, 4), np.float32), (1 << 20, 1 << 20))  # 4 TiB

    assert run_guarded("spikesim test", call) == 1
    assert capsys.readouterr().err == ("spikesim test: error: not enough memory for this "
                                       "request: ask for fewer readouts or a smaller size\n")


def test_sigterm_inside_a_native_callback_is_sent_again_after_it(monkeypatch):
    """An exception raised in a Python function that native code calls (numba's
    object cache, through llvmlite) is lost and the native caller crashes, so
    there the handler sends the signal again shortly instead of raising;
    anywhere else it raises :class:`Terminated`."""
    sent = []
    monkeypatch.setattr(cli_guard.os, "kill", lambda pid, sig: sent.append((pid, sig)))
    space = {"guard": cli_guard, "sys": sys}
    exec(compile("def _raw_object_cache_getbuffer():\n"
                 "    guard._on_sigterm(15, sys._getframe())\n",
                 os.path.join("site-packages", "llvmlite", "binding", "executionengine.py"),
                 "exec"), space)
    space["_raw_object_cache_getbuffer"]()  # returns: nothing raised inside the callback
    deadline = time.monotonic() + 5
    while not sent and time.monotonic() < deadline:
        time.sleep(0.01)
    assert sent == [(os.getpid(), signal.SIGTERM)]
    with pytest.raises(Terminated):
        cli_guard._on_sigterm(signal.SIGTERM, sys._getframe())
