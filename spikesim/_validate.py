"""One set of validators for numbers given by users, files and command lines.

Each returns the value as a plain Python ``int`` or ``float`` or raises
:class:`~spikesim.errors.SpikeSimValueError` naming the parameter, the bad
value and the allowed range.  NumPy scalars are numbers like any other; a
``bool`` or a string never is (``'5'`` is a typo to report, not a number to
guess).
"""

from __future__ import annotations

import math
import numbers

from spikesim.errors import bad_value

__all__ = ["check_int", "check_real", "is_int", "is_real"]


def is_int(value) -> bool:
    """A Python or NumPy integer (not a bool)."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool) and \
        type(value).__name__ != "bool_"


def is_real(value) -> bool:
    """A Python or NumPy real number (not a bool, not a string)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool) and \
        type(value).__name__ != "bool_"


def _range_text(kind: str, low, high, low_open: bool, unit: str) -> str:
    lo = "" if low is None else (f"> {low}" if low_open else f">= {low}")
    if high is not None and low is not None and not low_open:
        text = f"{kind} in [{low}, {high}]"
    elif high is not None:
        text = f"{kind} {lo} and <= {high}".replace("  ", " ")
    else:
        text = f"{kind} {lo}".strip()
    return f"{text} ({unit})" if unit else text


def check_int(name: str, value, low: int | None = None, high: int | None = None,
              unit: str = "") -> int:
    """``value`` as an int within ``[low, high]`` (either bound optional)."""
    if not is_int(value) or (low is not None and value < low) or \
            (high is not None and value > high):
        raise bad_value(name, value, _range_text("an integer", low, high, False, unit))
    return int(value)


def check_real(name: str, value, low: float | None = None, high: float | None = None,
               low_open: bool = False, unit: str = "") -> float:
    """``value`` as a finite float within the bounds (``low_open``: strictly above ``low``)."""
    ok = is_real(value) and math.isfinite(float(value))
    if ok:
        v = float(value)
        if low is not None and (v <= low if low_open else v < low):
            ok = False
        if high is not None and v > high:
            ok = False
    if not ok:
        raise bad_value(name, value, _range_text("a finite number", low, high, low_open, unit))
    return float(value)
