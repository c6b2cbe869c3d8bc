"""Error hierarchy of spikesim.

Every error raised by library code derives from :class:`SpikeSimError`, and the
concrete classes also derive from the matching builtin, so ``except ValueError``
keeps working for callers who do not know this package.  Messages name the
parameter, the bad value and the allowed range or choices.
"""

from __future__ import annotations

__all__ = [
    "SpikeSimError",
    "SpikeSimValueError",
    "SpikeSimTypeError",
    "SpikeSimFileError",
    "SpikeSimFormatError",
    "bad_value",
]


class SpikeSimError(Exception):
    """Base class of every error raised by spikesim."""


class SpikeSimValueError(SpikeSimError, ValueError):
    """A parameter has a value outside its allowed range or set."""


class SpikeSimTypeError(SpikeSimError, TypeError):
    """A parameter has the wrong type, dtype or shape kind."""


class SpikeSimFileError(SpikeSimError, OSError):
    """A file is missing, unreadable, or cannot be written."""


class SpikeSimFormatError(SpikeSimError, ValueError):
    """A file exists but its content is not what the format requires."""


def bad_value(name: str, value: object, allowed: str) -> SpikeSimValueError:
    """Build the standard message ``name=value is invalid: allowed``."""
    shown = repr(value)
    if len(shown) > 80:
        shown = shown[:77] + "..."
    return SpikeSimValueError(f"{name}={shown} is invalid: expected {allowed}")
