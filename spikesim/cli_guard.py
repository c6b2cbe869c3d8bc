"""One error boundary for the command lines (``spikesim`` and ``spikejdd``).

Library code raises; a command line turns every failure into one line on
stderr and an exit code, never a traceback unless asked for with ``--debug``
(or ``SPIKESIM_DEBUG=1``):

==========================================  =====  ===========================================
what happened                               exit   line
==========================================  =====  ===========================================
a usage error (argparse's: unknown option)  2      ``PROG COMMAND: error: MESSAGE (see ... --help)``
a spikesim error (bad value, file, format)  1      ``PROG COMMAND: error: MESSAGE``
an operating-system error (disk, access)    1      the file, the reason and what to do
not enough memory                           1      what to make smaller
Ctrl-C                                      130    ``interrupted``
SIGTERM                                     143    ``stopped by SIGTERM``
the reader of stdout went away (``| head``)  141    nothing (as other Unix tools)
any other exception (a bug)                 70     its type and message, and ``--debug``
==========================================  =====  ===========================================

SIGTERM is turned into an exception, so the files being written are removed
on the way out exactly as on Ctrl-C.  ``SIGXFSZ`` (file-size limit) is
ignored so that such a write fails with an error instead of killing the
process.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import os
import re
import signal
import sys
import threading
import warnings
from collections.abc import Callable

from spikesim._validate import check_int, check_real, is_int, is_real
from spikesim.errors import SpikeSimError, bad_value

__all__ = ["MAX_READOUTS", "as_option", "check_cli_numbers", "debug_requested",
           "install_signal_handlers", "OneLineParser", "parse_size", "run_guarded",
           "Terminated"]

EXIT_ERROR = 1
_NO_MEMORY = "error: not enough memory for this request: ask for fewer readouts or a smaller size"
#: A value that argparse would take for an option: ``-`` then a digit or a dot.
_DASHED_VALUE = re.compile(r"-[0-9.]")
#: argparse's ``argument --size: `` before a message that starts with the option itself.
_NAMED_TWICE = re.compile(r"^argument (\S+): (?=\1[= ])")
EXIT_BUG = 70
EXIT_INTERRUPTED = 130
EXIT_PIPE = 141
EXIT_TERMINATED = 143


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line (exit 2), pointing to ``--help``
    instead of printing the whole usage block."""

    def error(self, message: str):
        message = _NAMED_TWICE.sub("", message)  # a converter's message names its option
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")

    def parse_args(self, args=None, namespace=None):
        """Parse as argparse does, but arguments left over are reported by the
        (sub)command parser that was chosen (``spikesim verify: error: unrecognized
        arguments: ... (see spikesim verify --help)``), whose options they were
        taken for, not by the top-level parser."""
        namespace, extras = self.parse_known_args(args, namespace)
        if extras:
            self.command_parser(namespace).error(
                "unrecognized arguments: " + " ".join(extras))
        return namespace

    def command_parser(self, namespace) -> argparse.ArgumentParser:
        """The innermost subcommand parser that ``namespace`` names (``spikesim analyze
        calibrate``'s for ``spikesim analyze calibrate ...``); this parser without one.
        Its ``prog`` is the command's name, as its own errors print it."""
        parser = self
        while True:
            action = next((a for a in parser._actions
                           if isinstance(a, argparse._SubParsersAction)), None)
            chosen = None if action is None else getattr(namespace, action.dest, None)
            if not isinstance(chosen, str) or chosen not in action.choices:
                return parser
            parser = action.choices[chosen]

    def parse_known_args(self, args=None, namespace=None):
        """Parse as argparse does, after joining an option and a value that starts
        with ``-`` and a digit or a dot (``--size -4x8`` → ``--size=-4x8``):
        argparse reads such a value as an unknown option and says only "expected
        one argument", where the option's own check can name the bad value."""
        args = list(sys.argv[1:] if args is None else args)
        return super().parse_known_args(self._join_dashed_values(args), namespace)

    def _join_dashed_values(self, args: list[str]) -> list[str]:
        joined, i = [], 0
        while i < len(args):
            token = args[i]
            if token == "--":
                return joined + args[i:]
            action = self._option_string_actions.get(token)
            if (action is not None and action.nargs is None and action.option_strings
                    and i + 1 < len(args) and _DASHED_VALUE.match(args[i + 1])
                    and args[i + 1] not in self._option_string_actions):
                joined.append(f"{token}={args[i + 1]}")
                i += 2
                continue
            joined.append(token)
            i += 1
        return joined


class Terminated(BaseException):  # noqa: N818 - a signal, not an error
    """Raised in the main thread when the process receives SIGTERM."""


#: llvmlite's Python functions that native code calls (numba's cache of compiled
#: objects, read while a kernel loads): an exception raised in one is lost and
#: its native caller then crashes (SIGSEGV instead of exit 143, seen when a
#: SIGTERM landed as a cached kernel loaded).
_NATIVE_CALLBACKS = frozenset({"_raw_object_cache_getbuffer", "_raw_object_cache_notify"})
_REDELIVER_S = 0.05


def _in_native_callback(frame) -> bool:
    while frame is not None:
        code = frame.f_code
        if code.co_name in _NATIVE_CALLBACKS and "llvmlite" in code.co_filename:
            return True
        frame = frame.f_back
    return False


def _on_sigterm(signum, frame):
    if _in_native_callback(frame):  # send it again shortly, to land outside the callback
        timer = threading.Timer(_REDELIVER_S, os.kill, (os.getpid(), signum))
        timer.daemon = True
        timer.start()
        return
    raise Terminated()


def install_signal_handlers() -> None:
    """SIGTERM raises :class:`Terminated`; SIGXFSZ is ignored (writes then fail cleanly)."""
    with contextlib.suppress(ValueError, OSError, AttributeError):  # not the main thread
        signal.signal(signal.SIGTERM, _on_sigterm)
    with contextlib.suppress(ValueError, OSError, AttributeError):
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)


def debug_requested(argv: list[str] | None) -> bool:
    """``--debug`` anywhere among the arguments, or ``SPIKESIM_DEBUG`` set to a true value."""
    env = os.environ.get("SPIKESIM_DEBUG", "").strip().lower()
    return env not in ("", "0", "false", "no") or "--debug" in (argv or [])


def _os_message(exc: OSError) -> str:
    where = f"{exc.filename!r}: " if getattr(exc, "filename", None) else ""
    code = getattr(exc, "errno", None)
    hint = {
        errno.ENOSPC: "the disk is full: free space or write elsewhere",
        errno.EFBIG: "file-size limit reached: raise `ulimit -f` or write less",
        errno.EACCES: "permission denied: choose a path you can write",
        errno.EROFS: "read-only file system: choose another path",
        errno.ENOENT: "no such file or folder: check the path",
        errno.EEXIST: "it exists: choose another name or remove it",
        errno.ENOTDIR: "a part of the path is a file, not a folder",
        errno.EISDIR: "it is a folder: give a file name",
        errno.ECONNREFUSED: "connection refused: check the address and that the server runs",
    }.get(code)
    return where + (hint or exc.strerror or str(exc) or type(exc).__name__)


def _is_out_of_memory(exc: Exception) -> bool:
    """OpenCV's failed allocation (``cv2.error``, "Insufficient memory"), which is not
    a :class:`MemoryError`."""
    return type(exc).__module__.startswith("cv2") and "Insufficient memory" in str(exc)


def _quiet_stdout() -> None:
    # stdout's reader is gone: point it at /dev/null so that the interpreter's
    # final flush does not raise again (Python's documented recipe).
    with contextlib.suppress(OSError, ValueError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())


def run_guarded(label: str, call: Callable[[], int | None], debug: bool = False) -> int:
    """Run ``call()`` and map what it raises to one stderr line and an exit code.

    ``label`` prefixes every line (``"spikesim simulate"``).  With ``debug``
    nothing is caught, so Python prints the full traceback.  An error whose
    class sets ``traceback_helps`` (a user's method failing inside it) says
    that ``--debug`` shows that traceback.
    """
    install_signal_handlers()
    if debug:
        return int(call() or 0)
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _warning_line(label)
            code = int(call() or 0)
        with contextlib.suppress(BrokenPipeError):
            sys.stdout.flush()
        return code
    except BrokenPipeError:
        _quiet_stdout()
        return EXIT_PIPE
    except SpikeSimError as exc:
        hint = " (--debug shows the traceback)" if getattr(exc, "traceback_helps", False) else ""
        _say(label, f"error: {exc}{hint}")
        return EXIT_ERROR
    except argparse.ArgumentTypeError as exc:
        _say(label, f"error: {exc}")
        return EXIT_ERROR
    except KeyboardInterrupt:
        _drop_cut_short_bars()
        _say(label, "interrupted; files being written were removed")
        return EXIT_INTERRUPTED
    except Terminated:
        _drop_cut_short_bars()
        _say(label, "stopped by SIGTERM; files being written were removed")
        return EXIT_TERMINATED
    except MemoryError:
        _say(label, _NO_MEMORY)
        return EXIT_ERROR
    except OverflowError as exc:
        _say(label, f"error: a number is too large ({exc}): ask for fewer readouts or a "
                    "smaller size")
        return EXIT_ERROR
    except OSError as exc:
        _say(label, f"error: {_os_message(exc)}")
        return EXIT_ERROR
    except Exception as exc:  # noqa: BLE001 - the boundary: a bug still gets one line
        if _is_out_of_memory(exc):
            _say(label, _NO_MEMORY)
            return EXIT_ERROR
        _say(label, f"internal error: {type(exc).__name__}: {exc} (run again with --debug "
                    "for the traceback, and please report it)")
        return EXIT_BUG


def _drop_cut_short_bars() -> None:
    """A stop that lands while a progress bar is being built leaves it half
    made, and tqdm's finalizer then fails on it ("Exception ignored in
    tqdm.__del__", with a traceback) once the stop's exception is cleared:
    drop those reports (the stop's one line says what happened); any other
    goes to the hook that was there."""
    previous = sys.unraisablehook
    if getattr(previous, "drops_cut_short_bars", False):
        return

    def hook(unraisable):
        where = unraisable.object
        if (getattr(where, "__name__", "") == "__del__"
                and (getattr(where, "__module__", "") or "").startswith("tqdm")):
            return
        previous(unraisable)

    hook.drops_cut_short_bars = True
    sys.unraisablehook = hook


def _warning_line(label: str):
    """A ``warnings.showwarning`` that prints ``LABEL: warning: MESSAGE`` (no file
    name or source line: they point into the package, not at the user's input)."""
    def show(message, category, filename, lineno, file=None, line=None):
        _say(label, f"warning: {message}", end_bars=False)
    return show


def _say(label: str, text: str, end_bars: bool = True) -> None:
    """Print ``LABEL: TEXT`` to stderr on a line of its own.  Progress bars still on
    the terminal are ended first (``end_bars``: their line is cleared, so an error
    is not glued to a bar and no bar is drawn again after it) or, for a warning
    during work, the line is printed above them."""
    line = f"{label}: {text}"
    with contextlib.suppress(OSError, ValueError):
        bars = _open_bars()
        if bars and not end_bars:
            bars[0].write(line, file=sys.stderr)
            return
        for bar in bars:
            with contextlib.suppress(Exception):
                bar.leave = False
                bar.close()
        print(line, file=sys.stderr)


def _open_bars() -> list:
    """tqdm's progress bars still open in this process (none when tqdm is not loaded)."""
    tqdm_module = sys.modules.get("tqdm")
    if tqdm_module is None:
        return []
    return [b for b in list(getattr(tqdm_module.tqdm, "_instances", ()))
            if not getattr(b, "disable", True)]


def as_option(exc: SpikeSimError, names: dict[str, str]) -> SpikeSimError:
    """``exc`` with the API parameter its message starts with (``weights=...``,
    ``compression level=...``) replaced by its command-line option in ``names``
    (``{"weights": "--weights"}``); a value the option leaves out (``expected None``)
    reads ``expected no --option``.  Other errors are returned unchanged."""
    text = str(exc)
    for api, flag in names.items():
        if text.startswith((api + "=", api + " ")):  # ``speed=…``, ``compression level=…``
            text = flag + text[len(api):]
            return type(exc)(text.replace("expected None", f"expected no {flag}"))
    return exc


#: Upper bound of any readout count given on a command line (2**40: ~1.7 years at 20 kHz).
MAX_READOUTS = 2**40

#: Command-line numbers checked by name, whatever the command: (low, high, unit).
_CLI_INTS = {
    "readouts": (1, MAX_READOUTS, "readouts"), "max_readouts": (1, MAX_READOUTS, "readouts"),
    "stats_readouts": (1, MAX_READOUTS, "readouts"), "window": (1, MAX_READOUTS, "readouts"),
    "context": (1, MAX_READOUTS, "readouts"), "frames": (1, 100_000, "frames"),
    "step": (1, MAX_READOUTS, "readouts"), "limit": (1, None, "sequences"),
    "workers": (0, 1024, "processes"), "repeats": (1, 10_000, "timed calls"),
    "per_sequence": (1, 1_000_000, "frames"), "frames_per_scene": (1, 1_000_000, "frames"),
    "panels": (0, 10_000, "image panels"),
    "centers": (1, 1_000_000, "readouts"), "seed": (0, 2**64 - 1, ""),
    "steps": (1, None, "steps"), "batch_size": (1, 1 << 20, "samples"),
    "crop": (1, 1 << 16, "pixels"), "threads": (1, 4096, "threads"),
    "eval_every": (1, None, "steps"), "eval_frames": (1, None, "frames"),
    "checkpoint_every": (1, None, "steps"), "lr_step": (1, None, "steps"),
    "head_columns": (0, 1 << 16, "columns"), "height": (1, 1 << 16, "pixels"),
    "width": (1, 1 << 16, "pixels"), "size": (1, 1 << 16, "pixels"),
}
_CLI_REALS = {
    "fps": (0.0, None, "frames per second"), "rate": (0.0, None, "spikes per readout"),
    "clock_hz": (0.0, None, "Hz"), "electrons": (0.0, None, "electrons"),
    "lr": (0.0, None, ""), "time_limit_min": (0.0, None, "minutes"),
}


def check_cli_numbers(args) -> None:
    """Check the numbers of a parsed command line by their names (``--readouts``, ...).

    One table for every command, so a new option named like an old one is
    checked the same way; values left unset (None) are skipped.
    """
    for dest, (low, high, unit) in _CLI_INTS.items():
        value = getattr(args, dest, None)
        if is_int(value):  # below the range, the bound is what to say (not 2**40 above)
            check_int("--" + dest.replace("_", "-"), value, low,
                      None if value < low else high, unit)
    for dest, (low, high, unit) in _CLI_REALS.items():
        value = getattr(args, dest, None)
        if is_real(value):
            check_real("--" + dest.replace("_", "-"), value, low, high, low_open=True, unit=unit)


def parse_size(text: str, name: str = "--size", example: str = "256x256") -> tuple[int, int]:
    """``HxW`` of a command line (``"256x96"``) as ``(height, width)``, each side an
    integer within the bounds of ``--height``/``--width``; errors name the option ``name``."""
    low, high, unit = _CLI_INTS["size"]
    try:
        h, w = (int(v) for v in str(text).lower().split("x"))
    except ValueError:
        h = w = low - 1
    if not (low <= h <= high and low <= w <= high):
        raise bad_value(name, text, f"HxW, both sides integers in [{low}, {high}] ({unit}), "
                                    f"e.g. {example}")
    return h, w
