"""Camera-motion paths over a still picture, as projective maps of the image plane.

Each path is a function ``phase -> M`` giving a 3×3 matrix that maps texture
coordinates ``(x=col, y=row, 1)`` to output coordinates; ``M(0)`` is the
identity, so every path starts at the undistorted picture.  The scene turns
its ``speed`` (largest content speed, pixels per second) into a phase rate:
the peak content speed per unit phase is measured numerically over the frame
(boundary and a 9×9 interior grid, 512 phases over the path's period; for
affine paths the maximum lies on the corners, so this is exact there) and the
rate is ``speed / peak``.

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
  8 % of the smaller side, ``M`` the projective map through them.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from spikesim.errors import bad_value

__all__ = ["MOTIONS", "make_path", "peak_speed_per_phase", "perspective_from_corners"]

#: Motion name → one-line description.
MOTIONS: dict[str, str] = {
    "static": "no motion",
    "pan": "constant-velocity translation (direction_deg, default 0 = content moves right)",
    "rotation": "rotation about the frame centre at constant angular speed",
    "zoom": "oscillating zoom about the centre between 1/1.5x and 1.5x",
    "shake": "hand-held camera shake: smooth quasi-periodic jitter of the picture",
    "homography": "perspective wobble: the four corners wander on Lissajous curves",
}

Path = Callable[[float], np.ndarray]


def _translate(dx: float, dy: float) -> np.ndarray:
    return np.array([[1.0, 0.0, dx], [0.0, 1.0, dy], [0.0, 0.0, 1.0]])


def perspective_from_corners(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """3×3 projective matrix mapping 4 points ``src`` to ``dst`` (float64, DLT with h33 = 1)."""
    a = np.zeros((8, 8))
    b = np.zeros(8)
    for i, ((x, y), (u, v)) in enumerate(zip(src, dst, strict=True)):
        a[2 * i] = [x, y, 1, 0, 0, 0, -u * x, -u * y]
        a[2 * i + 1] = [0, 0, 0, x, y, 1, -v * x, -v * y]
        b[2 * i], b[2 * i + 1] = u, v
    h = np.linalg.solve(a, b)
    return np.append(h, 1.0).reshape(3, 3)


def make_path(
    motion: str, height: int, width: int, direction_deg: float = 0.0
) -> tuple[Path, float]:
    """Return ``(path, period)``: the phase → matrix function and the phase span to scan."""
    cx, cy = (width - 1) / 2.0, (height - 1) / 2.0
    about = _translate(cx, cy)
    back = _translate(-cx, -cy)
    side = min(height, width)
    if motion == "static":
        return (lambda p: np.eye(3)), 1.0
    if motion == "pan":
        d = math.radians(direction_deg)
        ux, uy = math.cos(d), math.sin(d)
        return (lambda p: _translate(p * ux, p * uy)), 1.0
    if motion == "rotation":

        def rot(p: float) -> np.ndarray:
            c, s = math.cos(p), math.sin(p)
            return about @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ back

        return rot, 2 * math.pi
    if motion == "zoom":
        amp = math.log(1.5)

        def zoom(p: float) -> np.ndarray:
            s = math.exp(amp * math.sin(p))
            return about @ np.diag([s, s, 1.0]) @ back

        return zoom, 2 * math.pi
    if motion == "shake":
        a = 0.04 * side

        def shake(p: float) -> np.ndarray:
            dx = math.sin(p) + 0.5 * math.sin(2.3 * p + 1.0) - 0.5 * math.sin(1.0)
            dy = math.cos(1.3 * p) + 0.5 * math.sin(3.1 * p + 2.0) - 1.0 - 0.5 * math.sin(2.0)
            return _translate(a * dx, a * dy)

        return shake, 20 * math.pi
    if motion == "homography":
        a = 0.08 * side
        x1, y1 = max(width - 1, 1), max(height - 1, 1)  # (a box, even for a one-pixel side)
        corners = np.array([[0, 0], [x1, 0], [x1, y1], [0, y1]], float)
        ph = np.array([0.0, 1.7, 3.1, 4.4])
        fx = np.array([1.0, 1.3, 0.8, 1.1])
        fy = np.array([0.9, 1.2, 1.4, 0.7])

        def homog(p: float) -> np.ndarray:
            dx = np.sin(fx * p + ph) - np.sin(ph)
            dy = np.cos(fy * p + ph) - np.cos(ph)
            dst = corners + a * np.stack([dx, dy], axis=1)
            return perspective_from_corners(corners, dst)

        return homog, 20 * math.pi
    raise bad_value("motion", motion, f"one of {sorted(MOTIONS)}")


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
    return np.concatenate([pts, np.ones((len(pts), 1))], axis=1).T  # (3, N)


def _apply(m: np.ndarray, pts: np.ndarray) -> np.ndarray:
    q = m @ pts
    return q[:2] / q[2]


def peak_speed_per_phase(path: Path, period: float, height: int, width: int) -> float:
    """Largest content speed in output pixels per unit phase, over the frame and the period."""
    pts = _probe_points(height, width)
    best = 0.0
    eps = 1e-4
    for p in np.linspace(0.0, period, 513):
        src = np.linalg.solve(path(p), pts)  # texture points now at the probe positions
        v = (_apply(path(p + eps), src) - _apply(path(p - eps), src)) / (2 * eps)
        best = max(best, float(np.sqrt((v**2).sum(axis=0)).max()))
    return best
