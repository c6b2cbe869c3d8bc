"""A stop (SIGTERM, Ctrl-C) that lands while a progress bar is being built
still ends in the stop's one line: the half-built bar's finalizer report is
dropped."""

from __future__ import annotations

import gc
import sys

import pytest
from tqdm import tqdm

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
