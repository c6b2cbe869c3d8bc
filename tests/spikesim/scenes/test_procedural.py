"""Procedural scenes: exact radiance, continuity, periodicity, key spacing, bad input."""

from __future__ import annotations

import json

import colour
import numpy as np
import pytest

import spikesim.scenes as sc
from spikesim.errors import SpikeSimValueError

SIZE = (48, 64)


def test_list_scenes_one_line_each_and_every_scene_renders():
    scenes = sc.list_scenes()
    for required in ("astronaut", "chelsea", "coffee", "rocket", "sprites", "fan", "flat",
                     "ramp", "flicker", "colorchecker"):
        assert required in scenes
    for name, desc in scenes.items():
        assert desc and "\n" not in desc
        scene = sc.procedural(name, size=SIZE)
        img = scene.radiance(0.0123)
        assert img.shape == SIZE + (3,) and img.dtype == np.float32
        assert np.isfinite(img).all() and img.min() >= 0
        json.dumps(scene.describe())
    for motion in sc.list_motions():
        img = sc.procedural("chelsea", motion=motion, size=SIZE).radiance(0.02)
        assert img.shape == SIZE + (3,) and np.isfinite(img).all()


def test_static_picture_is_the_resized_photo_and_static():
    s = sc.procedural("coffee", motion="static", size=SIZE)
    assert s.is_static and s.key_interval_s is None
    np.testing.assert_array_equal(s.radiance(0.0), s.radiance(3.0))


def test_integer_pixel_pan_equals_shifted_image():
    s = sc.procedural("astronaut", motion="pan", size=SIZE, speed=100.0)
    base = s.radiance(0.0)
    shifted = s.radiance(0.05)  # 5 px to the right
    np.testing.assert_allclose(shifted[:, 5:], base[:, :-5], atol=2e-6)
    down = sc.procedural("astronaut", motion="pan", size=SIZE, speed=100.0, direction_deg=90)
    np.testing.assert_allclose(down.radiance(0.03)[3:], base[:-3], atol=2e-6)
    # sub-pixel shifts are not the image (the spline is really evaluated in between)
    assert np.abs(s.radiance(0.005)[:, 1:] - base[:, :-1]).max() > 1e-3


def test_radiance_is_continuous_in_time():
    for name, motion in [("rocket", "zoom"), ("astronaut", "homography"), ("sprites", None),
                         ("fan", None), ("chelsea", "shake")]:
        s = sc.procedural(name, motion=motion, size=SIZE, speed=300.0)
        a, b = s.radiance(0.0400), s.radiance(0.0400 + 1e-7)
        assert np.abs(a - b).max() < 1e-3, name  # 3e-5 px of motion


def test_rotation_by_360_degrees_returns_start():
    s = sc.procedural("chelsea", motion="rotation", size=SIZE, speed=200.0)
    turn = 2 * np.pi / s.rate
    np.testing.assert_allclose(s.radiance(turn), s.radiance(0.0), atol=1e-4)
    assert np.abs(s.radiance(turn / 2) - s.radiance(0.0)).max() > 0.1
    disk = sc.procedural("disk", size=SIZE, speed=200.0)
    np.testing.assert_allclose(disk.radiance(2 * np.pi / disk.omega), disk.radiance(0.0),
                               atol=1e-4)


@pytest.mark.parametrize("name,motion", [("astronaut", "pan"), ("coffee", "rotation"),
                                         ("rocket", "zoom"), ("chelsea", "homography")])
def test_key_interval_bounds_content_motion(name, motion):
    speed, max_px = 400.0, 0.5
    s = sc.procedural(name, motion=motion, size=SIZE, speed=speed, max_px=max_px)
    assert s.key_interval_s == pytest.approx(max_px / speed)
    # track the corner texture points: displacement over one key interval <= max_px (1 % slack)
    pts = np.array([[0, 0, 1], [SIZE[1] - 1, 0, 1], [0, SIZE[0] - 1, 1],
                    [SIZE[1] - 1, SIZE[0] - 1, 1]], float).T
    worst = 0.0
    for t in np.linspace(0, 0.2, 41):
        src = np.linalg.solve(s.matrix(t), pts)
        a, b = s.matrix(t) @ src, s.matrix(t + s.key_interval_s) @ src
        d = np.hypot(*(a[:2] / a[2] - b[:2] / b[2]))
        worst = max(worst, d.max())
    assert worst <= max_px * 1.01
    assert worst >= max_px * 0.5  # the speed is really reached


def test_sprites_occlude_and_move_at_most_speed():
    s = sc.procedural("sprites", size=(64, 64), speed=300.0)
    c0, c1 = s.centres(0.0), s.centres(0.01)
    assert np.hypot(*(c1 - c0).T).max() <= 3.0 + 1e-9
    bg = s._bg
    img = s.radiance(0.0)
    far = np.hypot(*(np.mgrid[0:64, 0:64][::-1] - c0[:, :, None, None]).transpose(1, 0, 2, 3))
    outside = (far > s.radius + 1).all(axis=0)
    np.testing.assert_array_equal(img[outside], bg[outside])  # background untouched
    assert np.abs(img[~outside] - bg[~outside]).mean() > 0.01
    # find a moment where sprites 0 (front) and 1 overlap: the overlap shows sprite 0 only
    for t in np.arange(0, 2, 0.002):
        c = s.centres(t)
        if np.hypot(*(c[0] - c[1])) < s.radius:
            break
    else:  # pragma: no cover - the seed makes them meet
        pytest.fail("sprites never overlap")
    x, y = np.round((c[0] + c[1]) / 2).astype(int)
    half = (s._side - 1) / 2
    front = s._tex[0].sample(np.array([[y - c[0, 1] + half]]), np.array([[x - c[0, 0] + half]]))
    np.testing.assert_allclose(s.radiance(t)[y, x], front[0, 0], atol=1e-6)


def test_flicker_period_and_depth():
    s = sc.procedural("flicker", size=(4, 4), mains_hz=50.0, depth=0.5, level=0.8)
    t = np.linspace(0, 0.02, 401)
    g = np.array([s.radiance(x)[0, 0, 0] for x in t])
    assert g.max() == pytest.approx(0.8, rel=1e-4) and g.min() == pytest.approx(0.4, rel=1e-4)
    np.testing.assert_allclose(s.radiance(0.0013), s.radiance(0.0013 + 0.01), rtol=1e-5)  # 100 Hz
    s60 = sc.procedural("flicker", size=(4, 4), mains_hz=60.0)
    np.testing.assert_allclose(s60.radiance(0.002), s60.radiance(0.002 + 1 / 120), rtol=1e-5)
    # linear interpolation between key frames errs by at most `tolerance` (of the peak)
    h = s.key_interval_s
    mid = [abs(0.5 * (s.gain(k * h) + s.gain((k + 1) * h)) - s.gain((k + 0.5) * h))
           for k in range(200)]
    assert max(mid) <= 1e-3 * 1.001


def test_colorchecker_patches_match_colour_science():
    s = sc.procedural("colorchecker", size=(80, 120))
    img = s.radiance(0.0)
    names = s.patch_names
    cc = colour.CCS_COLOURCHECKERS["ColorChecker24 - After November 2014"]
    xyz = colour.xyY_to_XYZ(np.array(list(cc.data.values())))
    rgb = colour.XYZ_to_RGB(xyz, "sRGB", illuminant=cc.illuminant,
                            chromatic_adaptation_transform="Bradford")
    assert names[0] == "dark skin" and len(names) == 24
    for k, (r, c) in enumerate(s.patch_centres()):
        np.testing.assert_allclose(img[r, c], np.clip(rgb[k], 0, None), atol=1e-6)
    # white patch (index 18) is bright, black (23) dark; surround is black
    assert img[s.patch_centres()[18]].min() > 0.8 and img[s.patch_centres()[23]].max() < 0.04
    assert img[0, 0].max() == 0


def test_flat_and_ramp():
    flat = sc.procedural("flat", size=(3, 5), level=(0.1, 0.2, 0.3))
    np.testing.assert_allclose(flat.radiance(1.0)[1, 2], [0.1, 0.2, 0.3], rtol=1e-6)
    ramp = sc.procedural("ramp", size=(2, 11), low=0.0, high=1.0)
    np.testing.assert_allclose(ramp.radiance(0)[0, :, 0], np.linspace(0, 1, 11), atol=1e-7)
    log = sc.procedural("ramp", size=(2, 5), low=1e-3, high=1.0, log=True)
    np.testing.assert_allclose(log.radiance(0)[1, :, 2], np.logspace(-3, 0, 5), rtol=1e-5)
    assert flat.is_static and ramp.is_static


def test_exposure_scales_radiance():
    a = sc.procedural("camera", motion="pan", size=SIZE, speed=50.0)
    b = sc.procedural("camera", motion="pan", size=SIZE, speed=50.0, exposure=3.0)
    np.testing.assert_allclose(b.radiance(0.01), 3 * a.radiance(0.01), rtol=1e-6)


@pytest.mark.parametrize(
    "kwargs,match",
    [
        (dict(name="nope"), "name"),
        (dict(name="astronaut", motion="spin"), "motion"),
        (dict(name="astronaut", size=(0, 5)), "size"),
        (dict(name="astronaut", size=(5.5, 5)), "size"),
        (dict(name="astronaut", speed=-1.0), "speed"),
        (dict(name="astronaut", speed=float("nan")), "speed"),
        (dict(name="astronaut", motion="static", speed=10.0), "speed"),
        (dict(name="fan", motion="pan"), "motion"),
        (dict(name="flat", speed=5.0), "speed"),
        (dict(name="flat", level=-1), "level"),
        (dict(name="flat", level=(1, 2)), "level"),
        (dict(name="ramp", low=0.5, high=0.2), "high"),
        (dict(name="ramp", low=0.0, log=True), "low"),
        (dict(name="flicker", depth=1.5), "depth"),
        (dict(name="flicker", mains_hz=0), "mains_hz"),
        (dict(name="flicker", base="moon"), "base"),
        (dict(name="sprites", n_sprites=0), "n_sprites"),
        (dict(name="fan", blades=0), "blades"),
        (dict(name="astronaut", max_px=0), "max_px"),
        (dict(name="astronaut", exposure=-2), "exposure"),
        # a keyword the scene does not take: named, with those it does
        (dict(name="flat", bogus=2), r"options=\['bogus'\].*'flat' takes: level, max_px"),
        (dict(name="astronaut", levle=1), r"options=\['levle'\].*direction_deg"),
        (dict(name="fan", image="x"), r"options=\['image'\].*blades"),
    ],
)
def test_bad_input_names_the_parameter(kwargs, match):
    kwargs.setdefault("size", (16, 16))
    with pytest.raises(SpikeSimValueError, match=match):
        sc.procedural(**kwargs)


def test_bad_time():
    s = sc.procedural("astronaut", size=(8, 8))
    with pytest.raises(SpikeSimValueError, match="t="):
        s.radiance(float("nan"))


def test_every_scene_pickles_and_renders_the_same():
    import pickle

    for name in sc.list_scenes():
        s = sc.procedural(name, size=(24, 24))
        t = pickle.loads(pickle.dumps(s))
        np.testing.assert_array_equal(t.radiance(0.0137), s.radiance(0.0137))
    v = sc.procedural("chelsea", motion="zoom", size=(24, 24)).as_video(24.0, 3)
    w = pickle.loads(pickle.dumps(v))
    np.testing.assert_array_equal(w.radiance(0.01), v.radiance(0.01))


@pytest.mark.parametrize("name,motion", [("astronaut", "pan"), ("astronaut", "zoom"),
                                         ("coffee", "rotation"), ("sprites", None)])
def test_picture_radiance_stays_within_its_texture(name, motion):
    """The cubic spline overshoots at sharp edges (the astronaut reached 1.13 of full
    scale): samples are clipped to the texture's own range, so ground truth of a
    picture whose brightest pixel is at most full scale stays within 0..1."""
    scene = sc.procedural(name, motion=motion, size=(96, 96), speed=3000.0)
    peak = max(float(scene.radiance(t).max()) for t in np.linspace(0.0, 0.02, 9))
    assert 0.9 < peak <= 1.0


@pytest.mark.parametrize("size", [(4096, 1), (1, 4096), (2, 40000)])
def test_every_built_in_scene_renders_at_a_long_thin_size(size):
    """A size far from the picture's aspect crops the picture to at least one pixel
    (it cropped to none, and OpenCV's resize failed, at 4096x1)."""
    import spikesim as ss

    for name in ss.scenes.list_scenes():
        try:
            scene = ss.scenes.procedural(name, size=size)
        except SpikeSimValueError as exc:  # a scene that needs room says so (the chart)
            assert str(exc).startswith(f"size={size}"), exc
            continue
        for t in (0.0, 0.01):
            frame = scene.radiance(t)
            assert frame.shape == (*size, 3) and np.isfinite(frame).all(), name
    for motion in ss.scenes.list_motions():
        frame = ss.scenes.procedural("astronaut", motion=motion, size=size).radiance(0.01)
        assert frame.shape == (*size, 3) and np.isfinite(frame).all(), motion
