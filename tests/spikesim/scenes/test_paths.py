"""Camera paths: the batched speed scan against the scalar computation it replaced."""

from __future__ import annotations

import math

import numpy as np
import pytest

from spikesim.errors import SpikeSimValueError
from spikesim.scenes.analytic import SplineTexture
from spikesim.scenes.paths import (
    MOTIONS,
    make_path,
    peak_speed,
    peak_speed_per_phase,
    perspective_from_corners,
)

# --- slow reference: the scalar code the batched scan replaced (one phase at a time) ---


def _ref_translate(dx, dy):
    return np.array([[1.0, 0.0, dx], [0.0, 1.0, dy], [0.0, 0.0, 1.0]])


def _ref_perspective(src, dst):
    a, b = np.zeros((8, 8)), np.zeros(8)
    for i, ((x, y), (u, v)) in enumerate(zip(src, dst, strict=True)):
        a[2 * i] = [x, y, 1, 0, 0, 0, -u * x, -u * y]
        a[2 * i + 1] = [0, 0, 0, x, y, 1, -v * x, -v * y]
        b[2 * i], b[2 * i + 1] = u, v
    return np.append(np.linalg.solve(a, b), 1.0).reshape(3, 3)


def _ref_path(motion, height, width, direction_deg=0.0):
    cx, cy = (width - 1) / 2.0, (height - 1) / 2.0
    about, back = _ref_translate(cx, cy), _ref_translate(-cx, -cy)
    side = min(height, width)
    if motion == "static":
        return (lambda p: np.eye(3)), 1.0
    if motion == "pan":
        d = math.radians(direction_deg)
        return (lambda p: _ref_translate(p * math.cos(d), p * math.sin(d))), 1.0
    if motion == "rotation":
        return (lambda p: about @ np.array([[math.cos(p), -math.sin(p), 0.0],
                                            [math.sin(p), math.cos(p), 0.0],
                                            [0.0, 0.0, 1.0]]) @ back), 2 * math.pi
    if motion == "zoom":
        amp = math.log(1.5)
        return (lambda p: about @ np.diag([math.exp(amp * math.sin(p))] * 2 + [1.0]) @ back,
                2 * math.pi)
    if motion == "shake":
        a = 0.04 * side
        return (lambda p: _ref_translate(
            a * (math.sin(p) + 0.5 * math.sin(2.3 * p + 1.0) - 0.5 * math.sin(1.0)),
            a * (math.cos(1.3 * p) + 0.5 * math.sin(3.1 * p + 2.0) - 1.0
                 - 0.5 * math.sin(2.0)))), 20 * math.pi
    a = 0.08 * side
    x1, y1 = max(width - 1, 1), max(height - 1, 1)
    corners = np.array([[0, 0], [x1, 0], [x1, y1], [0, y1]], float)
    ph, fx, fy = (np.array([0.0, 1.7, 3.1, 4.4]), np.array([1.0, 1.3, 0.8, 1.1]),
                  np.array([0.9, 1.2, 1.4, 0.7]))

    def homog(p):
        dx = np.sin(fx * p + ph) - np.sin(ph)
        dy = np.cos(fy * p + ph) - np.cos(ph)
        return _ref_perspective(corners, corners + a * np.stack([dx, dy], axis=1))

    return homog, 20 * math.pi


def _ref_probes(height, width):
    xs, ys = np.linspace(0, width - 1, 65), np.linspace(0, height - 1, 65)
    edge = np.concatenate([np.stack([xs, np.zeros_like(xs)], 1),
                           np.stack([xs, np.full_like(xs, height - 1)], 1),
                           np.stack([np.zeros_like(ys), ys], 1),
                           np.stack([np.full_like(ys, width - 1), ys], 1)])
    gx, gy = np.meshgrid(np.linspace(0, width - 1, 9), np.linspace(0, height - 1, 9))
    pts = np.concatenate([edge, np.stack([gx.ravel(), gy.ravel()], 1)])
    return np.concatenate([pts, np.ones((len(pts), 1))], axis=1).T


def _ref_peak(path, period, height, width):
    """One ``np.linalg.solve`` per phase over every probe point (the code before batching)."""
    pts, best, eps = _ref_probes(height, width), 0.0, 1e-4
    for p in np.linspace(0.0, period, 513):
        src = np.linalg.solve(path(p), pts)
        q1, q0 = path(p + eps) @ src, path(p - eps) @ src
        v = (q1[:2] / q1[2] - q0[:2] / q0[2]) / (2 * eps)
        best = max(best, float(np.sqrt((v**2).sum(axis=0)).max()))
    return best


SIZES = [(64, 64, 0.0), (48, 64, 37.0), (1, 5, 200.0), (96, 33, 290.0), (7, 300, 123.0)]


@pytest.mark.parametrize("motion", sorted(MOTIONS))
@pytest.mark.parametrize("height,width,direction", SIZES)
def test_batched_peak_speed_equals_the_scalar_scan(motion, height, width, direction):
    ref_path, period = _ref_path(motion, height, width, direction)
    path, period2 = make_path(motion, height, width, direction)
    assert period == period2
    for p in (0.0, 0.37, 5.1, period):  # the same matrices, one phase or many
        np.testing.assert_allclose(path(p), ref_path(p), rtol=1e-12, atol=1e-9)
    many = path(np.array([0.0, 0.37, 5.1]))
    assert many.shape == (3, 3, 3)
    np.testing.assert_allclose(many[1], ref_path(0.37), rtol=1e-12, atol=1e-9)
    want = _ref_peak(ref_path, period, height, width)
    got = peak_speed_per_phase(path, period, height, width)
    assert got == pytest.approx(want, rel=1e-9, abs=1e-12)
    assert peak_speed(motion, height, width, direction) == got


def test_a_path_of_scalars_only_is_scanned_phase_by_phase():
    ref_path, period = _ref_path("rotation", 20, 30)
    assert peak_speed_per_phase(ref_path, period, 20, 30) == pytest.approx(
        _ref_peak(ref_path, period, 20, 30), rel=1e-9)


def test_known_peak_speeds():
    # translation: 1 px per unit phase; rotation: the corner radius; zoom: ln 1.5 × it
    r = math.hypot(31.5, 23.5)
    assert peak_speed("pan", 48, 64, 33.0) == pytest.approx(1.0, rel=1e-8)
    assert peak_speed("rotation", 48, 64) == pytest.approx(r, rel=1e-6)
    assert peak_speed("zoom", 48, 64) == pytest.approx(math.log(1.5) * r, rel=1e-6)
    assert peak_speed("static", 48, 64) == 0.0
    with pytest.raises(SpikeSimValueError, match="motion"):
        peak_speed("spin", 8, 8)


def test_perspective_from_corners_maps_the_corners_in_a_batch():
    src = np.array([[0, 0], [9, 0], [9, 7], [0, 7]], float)
    rng = np.random.default_rng(0)
    dst = src + rng.normal(0, 0.8, (5, 4, 2))
    m = perspective_from_corners(src, dst)
    assert m.shape == (5, 3, 3)
    for k in range(5):
        np.testing.assert_allclose(m[k], _ref_perspective(src, dst[k]), rtol=1e-10, atol=1e-12)
        q = m[k] @ np.concatenate([src.T, np.ones((1, 4))])
        np.testing.assert_allclose((q[:2] / q[2]).T, dst[k], atol=1e-9)


def _ref_spline_sample(img, rows, cols):
    """The mirrored 2H × 2W tile with SciPy's ``grid-wrap`` (the texture before ``reflect``)."""
    from scipy import ndimage

    img = np.asarray(img, np.float64)
    tile = np.concatenate([img, img[::-1]], 0)
    tile = np.concatenate([tile, tile[:, ::-1]], 1)
    out = []
    for c in range(3):
        coef = ndimage.spline_filter(tile[..., c], order=3, mode="grid-wrap")
        v = ndimage.map_coordinates(coef, np.stack([rows, cols]), order=3, mode="grid-wrap",
                                    prefilter=False)
        out.append(np.clip(v, max(float(img[..., c].min()), 0.0), float(img[..., c].max())))
    return np.stack(out, -1)


@pytest.mark.parametrize("h,w", [(1, 1), (2, 3), (5, 40), (15, 16), (16, 16), (40, 64)])
def test_spline_texture_is_the_mirrored_periodic_field(h, w):
    rng = np.random.default_rng(h * 100 + w)
    img = rng.random((h, w, 3)).astype(np.float32)
    rows, cols = rng.uniform(-3 * h - 5, 3 * h + 5, (2, 9, 11))
    got = SplineTexture(img).sample(rows, cols)
    np.testing.assert_allclose(got, _ref_spline_sample(img, rows, cols), atol=1e-6)
