"""Every subcommand of ``spikesim`` and ``spikejdd`` with missing and invalid arguments.

Each call runs in this process through the command line's ``main``; whatever
the arguments, it must end with an exit code (argparse's usage error 2, or a
one-line error and 1) and never show a traceback.  The default run gives each
option one invalid value; the full run (``make test-faults``) every value of
:data:`BAD_VALUES`.  The issue's repros follow, each with the message it must
give.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import signal

import pytest

from tests.support.fault_helpers import FULL

# invalid values by option kind: the first of each is the default run's
BAD_VALUES = {
    int: ["-1", "abc", "0", "99999999999999999999999", ""],
    float: ["nan", "-5", "abc", "inf", "0", "1e400"],
    str: ["", "/no/such/path", "\udcff", "nosuch=3"],
}
#: seconds a call may run (a value accepted as valid starts real work: stopped, not failed)
CALL_LIMIT_S = 30 if FULL else 20


class _Stop(BaseException):
    pass


def _alarm(signum, frame):
    raise _Stop()


def _subcommands(parser: argparse.ArgumentParser, prefix=()):
    """(argv prefix, subparser) for every leaf subcommand."""
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        yield prefix, parser
        return
    for name, sub in subs[0].choices.items():
        yield from _subcommands(sub, prefix + (name,))


def _mains():
    from spikejdd.cli import build_parser as jdd_parser
    from spikejdd.cli import main as jdd_main
    from spikesim.cli import build_parser as ss_parser
    from spikesim.cli import main as ss_main

    return {"spikesim": (ss_parser, ss_main), "spikejdd": (jdd_parser, jdd_main)}


def _cases():
    cases = []
    for prog, (build, _) in _mains().items():
        for prefix, sub in _subcommands(build()):
            if prefix != ("demo",):  # `spikesim demo`, `spikejdd demo` alone build the demo
                cases.append((prog, prefix, None, None))  # no arguments at all
            for action in sub._actions:
                if not action.option_strings or action.nargs == 0 or action.dest == "help":
                    continue
                kind = action.type if action.type in (int, float) else str
                values = BAD_VALUES[kind] if FULL else BAD_VALUES[kind][:1]
                for v in values:
                    cases.append((prog, prefix, action.option_strings[-1], v))
    return cases


# inputs that exist, so that option checks after opening them are reached too
def _base_args(prog, prefix, h5):
    base = {
        ("spikesim", "simulate"): ["astronaut", "--size", "8x8", "--readouts", "20",
                                    "--out", "o.h5"],
        ("spikesim", "info"): [h5], ("spikesim", "verify"): [h5],
        ("spikesim", "convert"): [h5, "o.dat"],
        ("spikesim", "preview"): [h5, "--out", "o.png"],
        ("spikesim", "dataset"): ["missing.toml", "--out", "ds"],
        ("spikesim", "demo"): ["--limit", "0"], ("spikejdd", "demo"): ["--limit", "0"],
        ("spikejdd", "reconstruct"): [h5, "--method", "tfp+bilinear", "--out", "rec"],
        ("spikejdd", "evaluate"): ["--data", "missing-folder"],
        ("spikejdd", "train"): ["--data", "missing-folder", "--steps", "1"],
    }
    if prefix and prefix[0] == "analyze":
        return ["--out", "an", "--readouts", "-3"] if prefix[1] != "calibrate" else \
            ["missing.dat", "--out", "an"]
    return list(base.get((prog, prefix[0]), []))


def _call(main, argv) -> tuple[int, str]:
    err, out = io.StringIO(), io.StringIO()
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(CALL_LIMIT_S)
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            try:
                code = main(argv)
            except SystemExit as exc:  # argparse: usage error (2) or --help
                code = exc.code if isinstance(exc.code, int) else 2
    except _Stop:
        code = None
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    return code, err.getvalue()


CASES = _cases()


@pytest.fixture(scope="module", autouse=True)
def _imported():
    """Import what the commands import lazily, outside the time limit of a call: an
    import cut short by the limit would leave a half-initialised module behind."""
    import importlib

    for name in ("torch", "spikejdd.train", "spikejdd.evaluate", "spikejdd.registry",
                 "spikejdd.capture", "spikejdd.pipelines", "spikesim.analysis",
                 "spikesim.dataset", "spikesim.io.preview", "spikesim.demo", "spikejdd.demo", "cv2",
                 "PIL.Image", "matplotlib.pyplot"):
        try:
            importlib.import_module(name)
        except ImportError:
            pass


@pytest.mark.parametrize("prog,prefix,option,value", CASES,
                         ids=[f"{p}-{'-'.join(x)}-{o}={v!r}" for p, x, o, v in CASES])
def test_bad_arguments_never_give_a_traceback(h5_original, tmp_path, monkeypatch,
                                              prog, prefix, option, value):
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("SPIKESIM_DEBUG", raising=False)
    main = _mains()[prog][1]
    argv = list(prefix)
    if option is not None:
        argv += _base_args(prog, prefix, str(h5_original[0])) + [option, value]
    code, err = _call(main, argv)
    assert "Traceback" not in err and "internal error" not in err, err[-3000:]
    if code is not None and code != 0:
        assert code in (1, 2, 130), (code, err[-2000:])
        assert "error" in err.lower() or "usage" in err.lower(), err[-2000:]
