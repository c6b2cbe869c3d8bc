"""From key-frame times to the kernel's schedule of readouts.

Readout ``n`` integrates the period ``[n, n+1)`` (readout units: seconds ×
clock_hz).  Radiance is linear between consecutive key times and held before
the first and after the last.  A *run* is a range of readouts whose periods all
lie in one segment (or one hold); a readout whose period contains a key time
gets its own entry split into *pieces*.  Every number in the schedule depends
only on the global key times, never on where a chunk starts or stops, which is
what makes chunked simulation bit-identical to one pass.
"""

from __future__ import annotations

import bisect
import math

import numpy as np

from spikesim._kernels import RunSchedule
from spikesim.errors import bad_value

__all__ = ["RunSchedule", "build_schedule", "key_readout_times"]

_SNAP = 1e-9  # key times within this many readouts of an integer are snapped to it


def key_readout_times(key_times_s: np.ndarray, clock_hz: float) -> np.ndarray:
    """Key times in readout units, validated (finite, strictly increasing)."""
    t = np.asarray(key_times_s, dtype=np.float64).ravel()
    if t.size == 0:
        raise bad_value("scene.key_times", "[]", "at least one key time")
    if not np.all(np.isfinite(t)):
        raise bad_value("scene.key_times", t.tolist()[:8], "finite times in seconds")
    if t.size > 1 and not np.all(np.diff(t) > 0):
        raise bad_value("scene.key_times", t.tolist()[:8], "strictly increasing times (in order)")
    tau = t * clock_hz
    near = np.round(tau)
    snap = np.abs(tau - near) < _SNAP
    tau[snap] = near[snap]
    if tau.size > 1 and not np.all(np.diff(tau) > 0):
        raise bad_value("scene.key_times", t.tolist()[:8], "distinct times after clock rounding")
    return tau


def _segment_at(tau: np.ndarray, x: float) -> tuple[int, int, float, float]:
    """(a, b, t_a, inv_span) of the segment or hold containing time x."""
    k = len(tau)
    if k == 1 or x < tau[0]:
        return 0, 0, float(tau[0]), 0.0
    if x >= tau[-1]:
        return k - 1, k - 1, float(tau[-1]), 0.0
    j = bisect.bisect_right(tau.tolist(), x) - 1
    return j, j + 1, float(tau[j]), 1.0 / (float(tau[j + 1]) - float(tau[j]))


def build_schedule(tau: np.ndarray, n0: int, n1: int) -> RunSchedule:
    """Schedule of readouts ``[n0, n1)`` given key readout times ``tau``."""
    tau_list = [float(v) for v in tau]
    k = len(tau_list)
    runs: list[tuple] = []
    pieces: list[tuple] = []
    n = n0
    while n < n1:
        if k == 1 or n + 1 <= tau_list[0]:
            stop = n1 if k == 1 else min(n1, math.floor(tau_list[0]))
            runs.append((0, n, stop, 0, 0, tau_list[0], 0.0, 0, 0))
            n = stop
            continue
        if n >= tau_list[-1]:
            runs.append((0, n, n1, k - 1, k - 1, tau_list[-1], 0.0, 0, 0))
            break
        j = bisect.bisect_right(tau_list, n) - 1
        if j >= 0 and n + 1 <= tau_list[j + 1]:
            stop = min(n1, math.floor(tau_list[j + 1]))
            inv = 1.0 / (tau_list[j + 1] - tau_list[j])
            runs.append((0, n, stop, j, j + 1, tau_list[j], inv, 0, 0))
            n = stop
            continue
        # the period [n, n+1) contains key times: split it into pieces
        inner = [t for t in tau_list if n < t < n + 1]
        bounds = [float(n), *inner, float(n + 1)]
        p0 = len(pieces)
        for lo, hi in zip(bounds[:-1], bounds[1:], strict=True):
            mid = 0.5 * (lo + hi)
            a, b, ta, inv = _segment_at(tau, mid)
            pieces.append((a, b, hi - lo, (mid - ta) * inv))
        runs.append((1, n, n + 1, 0, 0, 0.0, 0.0, p0, len(pieces)))
        n += 1
    r = np.array(runs, dtype=object).reshape(-1, 9)
    p = np.array(pieces, dtype=np.float64).reshape(-1, 4)
    return RunSchedule(
        kind=r[:, 0].astype(np.int8),
        start=r[:, 1].astype(np.int64),
        stop=r[:, 2].astype(np.int64),
        a=r[:, 3].astype(np.int64),
        b=r[:, 4].astype(np.int64),
        ta=r[:, 5].astype(np.float64),
        inv=r[:, 6].astype(np.float64),
        p0=r[:, 7].astype(np.int64),
        p1=r[:, 8].astype(np.int64),
        piece_a=p[:, 0].astype(np.int64),
        piece_b=p[:, 1].astype(np.int64),
        piece_len=p[:, 2].copy(),
        piece_phi=p[:, 3].copy(),
    )
