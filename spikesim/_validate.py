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

import numpy as np

from spikesim.errors import bad_value

__all__ = ["check_crop", "check_int", "check_positive",
           "check_real", "check_size", "check_time", "check_window", "is_int",
           "is_real"]


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


def check_window(start: int, length: int | None, n_readouts: int) -> tuple[int, int]:
    """Validate ``start``/``length`` against a stream of ``n_readouts``; ``None`` = to the end."""
    if not is_int(start) or not 0 <= start < n_readouts:
        raise bad_value("start", start, f"an integer readout index in [0, {n_readouts - 1}]")
    start = int(start)
    if length is None:
        return start, n_readouts - start
    if not is_int(length) or not 1 <= length <= n_readouts - start:
        raise bad_value(
            "length", length,
            f"an integer in [1, {n_readouts - start}] (the stream has {n_readouts} readouts, "
            f"start={start})",
        )
    return start, int(length)


def check_crop(crop: tuple | None, height: int, width: int) -> tuple[int, int, int, int]:
    """Validate ``crop = (top, left, h, w)`` inside an ``height × width`` frame."""
    if crop is None:
        return 0, 0, height, width
    try:
        top, left, h, w = crop
    except (TypeError, ValueError):
        raise bad_value("crop", crop, "None or (top, left, height, width)") from None
    if not all(is_int(v) for v in (top, left, h, w)):
        raise bad_value("crop", crop, "four integers (top, left, height, width)")
    if not (0 <= top and 0 <= left and h >= 1 and w >= 1 and top + h <= height
            and left + w <= width):
        raise bad_value(
            "crop", tuple(int(v) for v in crop),
            f"(top, left, height, width) with top+height <= {height}, left+width <= {width}, "
            "all >= 0 and sizes >= 1",
        )
    return int(top), int(left), int(h), int(w)


def check_positive(name: str, value: object, allow_none: bool = False) -> float | None:
    """Validate a finite, strictly positive number (``None`` allowed if ``allow_none``)."""
    if value is None and allow_none:
        return None
    return check_real(name, value, 0, low_open=True)


def check_time(t: object) -> float:
    """Validate a time ``t`` in seconds (a finite real number)."""
    return check_real("t", t, unit="seconds")


def check_size(size: object) -> tuple[int, int]:
    """Validate ``size=(H, W)`` in pixels, each an integer >= 1."""
    try:
        h, w = size  # type: ignore[misc]
        ok = all(is_int(v) for v in (h, w))
    except (TypeError, ValueError):
        ok = False
    if not ok or h < 1 or w < 1:
        raise bad_value("size", size, "(H, W) with integers H >= 1 and W >= 1")
    return int(h), int(w)


def check_flag(name: str, value: object) -> bool:
    """``value`` as a ``bool``; anything but ``True``/``False`` (or NumPy's) is refused:
    ``flip="no"`` is a typo to report, not a true value to take."""
    if not isinstance(value, (bool, np.bool_)):
        raise bad_value(name, value, "True or False")
    return bool(value)
