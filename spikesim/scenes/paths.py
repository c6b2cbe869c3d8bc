"""Camera-motion paths over a still picture, as projective maps of the image plane.

Each path is a function ``phase -> M`` giving a 3×3 matrix that maps texture
coordinates ``(x=col, y=row, 1)`` to output coordinates; ``M(0)`` is the
identity, so every path starts at the undistorted picture.  A path takes a
scalar phase (→ one 3×3 matrix) or an array of phases (→ one matrix per phase,
shape ``phases.shape + (3, 3)``), so the speed scan below is one batched
computation.  The scene turns its ``speed`` (largest content speed, pixels per
second) into a phase rate: the peak content speed per unit phase is measured
numerically over the frame (boundary and a 9×9 interior grid, 513 phases over
the path's period, central differences of step 10⁻⁴; for affine paths the
maximum lies on the corners, so this is exact there) and the rate is
``speed / peak``.

Paths (``c`` = frame centre, ``r`` = centre-to-corner distance):

* ``static`` – identity;
* ``pan`` – translation ``phase · (cos d, sin d)`` pixels, ``d = direction_deg``;
* ``rotation`` – rotation by ``phase`` radians about ``c``;
* ``zoom`` – scaling by ``exp(A sin(phase))`` about ``c``, ``A = ln 1.5``
  (between 1/1.5 and 1.5 times);
* ``shake`` – hand-held jitter: translation
  ``a·(sin φ + ½ sin(2.3φ + 1) − sin 1 / 2, cos 1.3φ + ½ sin(3.1φ + 2) − 1 − sin 2 / 2)``
  with ``a`` = 4 % of the smaller side;
* ``homography`` – the four corners wander on Lissajous curves of amplitude
  8 % of the smaller side, ``M`` the projective map through them (the
  direct linear transform with ``h33 = 1``: Hartley & Zisserman, *Multiple
  View Geometry*, 2nd ed., §4.1).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import lru_cache

import numpy as np

from spikesim.errors import bad_value

__all__ = ["MOTIONS", "make_path", "peak_speed_per_phase", "perspective_from_corners",
           "peak_speed", "SPEED_SCAN_PHASES"]

#: Motion name → one-line description.
MOTIONS: dict[str, str] = {
    "static": "no motion",
    "pan": "constant-velocity translation (direction_deg, default 0 = content moves right)",
    "rotation": "rotation about the frame centre at constant angular speed",
    "zoom": "oscillating zoom about the centre between 1/1.5x and 1.5x",
    "shake": "hand-held camera shake: smooth quasi-periodic jitter of the picture",
    "homography": "perspective wobble: the four corners wander on Lissajous curves",
}
#: Phases the peak-speed scan samples over a path's period (both ends included).
SPEED_SCAN_PHASES = 513
_EPS = 1e-4  # phase step of the central difference

Path = Callable[[float | np.ndarray], np.ndarray]


def _matrices(p, entries) -> np.ndarray:
    """(..., 3, 3) matrices ``[[a, b, c], [d, e, f], [0, 0, 1]]`` from entries broadcast
    to the shape of phase(s) ``p`` (a scalar phase gives one 3×3 matrix)."""
    shape = np.shape(p)
    out = np.zeros(shape + (3, 3))
    for (i, j), v in zip(((0, 0), (0, 1), (0, 2), (1, 0), (1, 1), (1, 2)), entries, strict=True):
        out[..., i, j] = v
    out[..., 2, 2] = 1.0
    return out


def _about(m: np.ndarray, cx: float, cy: float) -> np.ndarray:
    """``T(c) · m · T(−c)`` for linear parts ``m`` (..., 3, 3): ``m`` applied about ``c``."""
    about = np.array([[1.0, 0.0, cx], [0.0, 1.0, cy], [0.0, 0.0, 1.0]])
    back = np.array([[1.0, 0.0, -cx], [0.0, 1.0, -cy], [0.0, 0.0, 1.0]])
    return about @ m @ back


def perspective_from_corners(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """3×3 projective matrix mapping 4 points ``src`` to ``dst`` (float64, DLT with h33 = 1).

    ``src`` and ``dst`` are (4, 2) point lists (x, y), or stacks (..., 4, 2) of them
    (broadcast together): one matrix per stack entry, shape (..., 3, 3), from one
    batched ``numpy.linalg.solve``."""
    src, dst = np.broadcast_arrays(np.asarray(src, np.float64), np.asarray(dst, np.float64))
    x, y = src[..., 0], src[..., 1]
    u, v = dst[..., 0], dst[..., 1]
    one, zero = np.ones_like(x), np.zeros_like(x)
    even = np.stack([x, y, one, zero, zero, zero, -u * x, -u * y], axis=-1)  # (..., 4, 8)
    odd = np.stack([zero, zero, zero, x, y, one, -v * x, -v * y], axis=-1)
    a = np.stack([even, odd], axis=-2).reshape(src.shape[:-2] + (8, 8))
    b = np.stack([u, v], axis=-1).reshape(src.shape[:-2] + (8,))
    h = np.linalg.solve(a, b[..., None])[..., 0]
    return np.concatenate([h, np.ones(h.shape[:-1] + (1,))], axis=-1).reshape(
        h.shape[:-1] + (3, 3))


def make_path(
    motion: str, height: int, width: int, direction_deg: float = 0.0
) -> tuple[Path, float]:
    """Return ``(path, period)``: the phase → matrix function and the phase span to scan."""
    cx, cy = (width - 1) / 2.0, (height - 1) / 2.0
    side = min(height, width)
    if motion == "static":
        return (lambda p: _matrices(p, (1.0, 0.0, 0.0, 0.0, 1.0, 0.0))), 1.0
    if motion == "pan":
        d = math.radians(direction_deg)
        ux, uy = math.cos(d), math.sin(d)

        def pan(p):
            p = np.asarray(p, np.float64)
            return _matrices(p, (1.0, 0.0, p * ux, 0.0, 1.0, p * uy))

        return pan, 1.0
    if motion == "rotation":

        def rot(p):
            c, s = np.cos(p), np.sin(p)
            return _about(_matrices(p, (c, -s, 0.0, s, c, 0.0)), cx, cy)

        return rot, 2 * math.pi
    if motion == "zoom":
        amp = math.log(1.5)

        def zoom(p):
            s = np.exp(amp * np.sin(p))
            return _about(_matrices(p, (s, 0.0, 0.0, 0.0, s, 0.0)), cx, cy)

        return zoom, 2 * math.pi
    if motion == "shake":
        a = 0.04 * side

        def shake(p):
            dx = np.sin(p) + 0.5 * np.sin(2.3 * p + 1.0) - 0.5 * math.sin(1.0)
            dy = np.cos(1.3 * p) + 0.5 * np.sin(3.1 * p + 2.0) - 1.0 - 0.5 * math.sin(2.0)
            return _matrices(p, (1.0, 0.0, a * dx, 0.0, 1.0, a * dy))

        return shake, 20 * math.pi
    if motion == "homography":
        a = 0.08 * side
        x1, y1 = max(width - 1, 1), max(height - 1, 1)  # (a box, even for a one-pixel side)
        corners = np.array([[0, 0], [x1, 0], [x1, y1], [0, y1]], float)
        ph = np.array([0.0, 1.7, 3.1, 4.4])
        fx = np.array([1.0, 1.3, 0.8, 1.1])
        fy = np.array([0.9, 1.2, 1.4, 0.7])

        def homog(p):
            p = np.asarray(p, np.float64)[..., None]  # (..., 1) against the 4 corners
            dx = np.sin(fx * p + ph) - np.sin(ph)
            dy = np.cos(fy * p + ph) - np.cos(ph)
            dst = corners + a * np.stack([dx, dy], axis=-1)
            return perspective_from_corners(corners, dst)

        return homog, 20 * math.pi
    raise bad_value("motion", motion, f"one of {sorted(MOTIONS)}")


@lru_cache(maxsize=64)
def _probe_points(height: int, width: int) -> np.ndarray:
    xs = np.linspace(0, width - 1, 65)
    ys = np.linspace(0, height - 1, 65)
    edge = np.concatenate(
        [
            np.stack([xs, np.zeros_like(xs)], 1),
            np.stack([xs, np.full_like(xs, height - 1)], 1),
            np.stack([np.zeros_like(ys), ys], 1),
            np.stack([np.full_like(ys, width - 1), ys], 1),
        ]
    )
    gx, gy = np.meshgrid(np.linspace(0, width - 1, 9), np.linspace(0, height - 1, 9))
    pts = np.concatenate([edge, np.stack([gx.ravel(), gy.ravel()], 1)])
    out = np.concatenate([pts, np.ones((len(pts), 1))], axis=1).T  # (3, N)
    out.setflags(write=False)
    return out


def _path_matrices(path: Path, phases: np.ndarray) -> np.ndarray:
    """``path`` at every phase, (n, 3, 3): one call where the path takes an array of
    phases (every path of :func:`make_path`), one call per phase otherwise."""
    try:
        m = np.asarray(path(phases), np.float64)
        if m.shape == phases.shape + (3, 3):
            return m
    except (TypeError, ValueError):  # a path of scalars only (math.cos of an array, ...)
        pass
    return np.stack([np.asarray(path(float(p)), np.float64) for p in phases])


def _velocities(path: Path, phases: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """(n, N) output speeds of the texture points at probe positions ``pts`` (3, N) at each
    phase: central differences of their projections under ``M(p ± ε) M(p)⁻¹``."""
    inv = np.linalg.inv(_path_matrices(path, phases))
    x, y = pts[0], pts[1]
    out = []
    for m in (_path_matrices(path, phases + _EPS) @ inv, _path_matrices(path, phases - _EPS) @ inv):
        q = [m[:, k, 0, None] * x + m[:, k, 1, None] * y + m[:, k, 2, None] for k in range(3)]
        out.append((q[0] / q[2], q[1] / q[2]))
    vx = (out[0][0] - out[1][0]) / (2 * _EPS)
    vy = (out[0][1] - out[1][1]) / (2 * _EPS)
    return np.sqrt(vx**2 + vy**2)


def peak_speed_per_phase(path: Path, period: float, height: int, width: int) -> float:
    """Largest content speed in output pixels per unit phase, over the frame and the period.

    At each of :data:`SPEED_SCAN_PHASES` phases ``p`` over ``[0, period]`` the texture
    points now at the probe positions ``x`` are ``M(p)⁻¹ x``; their output velocity is
    the central difference of ``M(p ± ε) M(p)⁻¹ x`` (projected), ε = 10⁻⁴.  All phases
    are computed at once.  Where every matrix is affine (last row 0, 0, 1) the velocity
    is an affine function of ``x``, whose norm is convex: its maximum over the frame is
    at a corner, and only the four corners are evaluated (the same maximum as over all
    probes, to rounding)."""
    phases = np.linspace(0.0, float(period), SPEED_SCAN_PHASES)
    pts = _probe_points(int(height), int(width))
    if np.all(_path_matrices(path, phases)[:, 2] == (0.0, 0.0, 1.0)):
        x1, y1 = width - 1.0, height - 1.0
        pts = np.array([[0.0, x1, x1, 0.0], [0.0, 0.0, y1, y1], [1.0, 1.0, 1.0, 1.0]])
    return float(_velocities(path, phases, pts).max())


@lru_cache(maxsize=256)
def _peak_speed(motion: str, height: int, width: int, direction_deg: float) -> float:
    path, period = make_path(motion, height, width, direction_deg)
    return peak_speed_per_phase(path, period, height, width)


def peak_speed(motion: str, height: int, width: int, direction_deg: float = 0.0) -> float:
    """:func:`peak_speed_per_phase` of :func:`make_path`'s path ``motion`` (pixels per unit
    phase), remembered per motion and frame size (and direction, for ``pan``, the one
    path that depends on it): scenes of one size share the scan."""
    if motion not in MOTIONS:
        raise bad_value("motion", motion, f"one of {sorted(MOTIONS)}")
    return _peak_speed(motion, int(height), int(width),
                       float(direction_deg) if motion == "pan" else 0.0)
