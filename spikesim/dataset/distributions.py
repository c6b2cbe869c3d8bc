"""Sampling distributions for manifest parameters.

A manifest value is either a constant or a one-key table naming a law:

* ``5.0`` / ``"pan"`` — fixed;
* ``{uniform = [a, b]}`` — uniform on [a, b];
* ``{loguniform = [a, b]}`` — log-uniform on [a, b] (0 < a ≤ b);
* ``{choice = [x, y, ...]}`` — one of the values, equally likely.

Every draw takes an explicit ``numpy.random.Generator`` (seeded per sequence),
so a sequence's parameters depend only on the global seed and its id.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from spikesim.errors import bad_value

__all__ = ["Distribution", "parse_distribution"]

_LAWS = ("uniform", "loguniform", "choice")


@dataclass(frozen=True)
class Distribution:
    law: str  # "fixed", "uniform", "loguniform", "choice"
    args: tuple

    def sample(self, rng: np.random.Generator):
        if self.law == "fixed":
            return self.args[0]
        if self.law == "uniform":
            return float(rng.uniform(self.args[0], self.args[1]))
        if self.law == "loguniform":
            lo, hi = math.log(self.args[0]), math.log(self.args[1])
            return float(math.exp(rng.uniform(lo, hi)))
        return self.args[int(rng.integers(len(self.args)))]

    def bounds(self) -> tuple:
        """(low, high) for numeric laws; used by validation."""
        if self.law in ("uniform", "loguniform"):
            return self.args
        values = [v for v in self.args if isinstance(v, (int, float)) and not isinstance(v, bool)]
        return (min(values), max(values)) if values else (None, None)


def parse_distribution(key: str, value, kind: str = "number",
                       low: float | None = None, high: float | None = None) -> Distribution:
    """Parse and validate a manifest value at key path ``key``.

    ``kind`` is ``"number"`` (bounded by ``low``/``high``) or ``"any"`` (constants
and ``choice`` values of any type; ``uniform``/``loguniform`` still take numbers).
    """
    def check_number(path, v, numeric=False):
        if kind != "number" and not numeric:
            return v
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise bad_value(path, v, "a finite number")
        if (low is not None and v < low) or (high is not None and v > high):
            raise bad_value(path, v, f"a number in [{low}, {high}]")
        return float(v)

    if isinstance(value, dict):
        if len(value) != 1 or next(iter(value)) not in _LAWS:
            raise bad_value(key, value, f"a constant or a one-key table among {_LAWS}")
        law, args = next(iter(value.items()))
        if not isinstance(args, list) or not args:
            raise bad_value(f"{key}.{law}", args, "a non-empty list")
        if law == "choice":
            return Distribution("choice", tuple(check_number(f"{key}.choice", v) for v in args))
        if len(args) != 2:
            raise bad_value(f"{key}.{law}", args, "[low, high] numbers")
        # uniform and loguniform are numeric laws whatever the key (options too)
        a, b = (check_number(f"{key}.{law}", v, numeric=True) for v in args)
        if a > b:
            raise bad_value(f"{key}.{law}", args, "low <= high")
        if law == "loguniform" and a <= 0:
            raise bad_value(f"{key}.{law}", args, "0 < low <= high")
        return Distribution(law, (a, b))
    return Distribution("fixed", (check_number(key, value),))
