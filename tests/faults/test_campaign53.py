"""Faults of the hostile campaign of issue 53, item 5: each a clean one-line error (no
traceback, no crash) or the right result."""

from __future__ import annotations

import contextlib
import io
import json
import subprocess
import sys
import warnings

import numpy as np
import pytest

import spikesim as ss
from spikesim.errors import SpikeSimValueError
from tests.support.dataset_helpers import write_frames
from tests.support.fault_helpers import REPO, cli_env


def _main(prog, argv):
    if prog == "spikesim":
        from spikesim.cli import main
    else:
        from spikejdd.cli import main
    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            code = main([str(a) for a in argv])
        except SystemExit as exc:
            code = exc.code
    return code, err.getvalue(), out.getvalue()


def _fails(prog, argv, *needles):
    code, err, _ = _main(prog, argv)
    assert code == 1 and "Traceback" not in err, err
    line = [ln for ln in err.splitlines() if "error" in ln][-1]
    for n in needles:
        assert n in line, (n, line)
    return line


def _scene_sensor(n=16, m=20):
    return (ss.scenes.procedural("astronaut", motion="pan", size=(n, m)),
            ss.Sensor(height=n, width=m))


# --- tracebacks from the API: absurd readout counts --------------------------------------
@pytest.mark.filterwarnings("ignore::Warning")  # (the key frames' runaway warning)
@pytest.mark.parametrize("n", [10**15, 2**70])
def test_simulate_absurd_readouts_in_the_api(n):
    scene, sensor = _scene_sensor()
    with pytest.raises(SpikeSimValueError, match="n_readouts") as info:
        ss.simulate(scene, sensor, n)
    assert "\n" not in str(info.value)
    if n == 10**15:  # within the index range, but the whole stream would not fit in memory
        assert "GiB" in str(info.value) and "simulate_chunks" in str(info.value)


def test_simulate_chunks_takes_any_indexable_length_and_no_more():
    scene, sensor = _scene_sensor()
    with warnings.catch_warnings():  # (the key frames' runaway warning)
        warnings.simplefilter("ignore")
        run = ss.simulate_chunks(scene, sensor, 10**15)  # streamed: nothing held whole
    assert len(run) == 10**15
    with pytest.raises(SpikeSimValueError, match=r"n_readouts=.*\[1, 9007199254740992\]"):
        ss.simulate_chunks(scene, sensor, 2**53 + 1)

