"""Sensor configuration, presets, CFA geometry, odd sizes, and bad input."""

from __future__ import annotations

import json
import pickle

import numpy as np
import pytest

import spikesim as ss
from spikesim import cfa as cfa_mod
from spikesim.noise import PaperNoise, PhysicalNoise  # noqa: F401  (used by eval(repr))
from spikesim.scenes.keyframes import Keyframes
from spikesim.sensor import Sensor  # noqa: F401


@pytest.mark.parametrize("name", list(ss.list_presets()))
def test_presets_round_trip(name):
    s = ss.Sensor.preset(name)
    assert ss.Sensor.from_json(s.to_json()) == s
    assert ss.Sensor.from_dict(json.loads(json.dumps(s.to_dict()))) == s
    assert eval(repr(s)) == s
    assert pickle.loads(pickle.dumps(s)) == s


def test_required_presets_exist_with_stated_properties():
    p = ss.list_presets()
    for name in ["vidar-400x250-40k", "vidar-400x250-20k", "color-1000x1000-20k", "ideal",
                 "sjdd-gn", "sjdd-gpn", "physical"]:
        assert name in p and p[name]
    assert ss.Sensor.preset("vidar-400x250-40k").shape == (250, 400)
    assert ss.Sensor.preset("vidar-400x250-40k").cfa is None
    assert ss.Sensor.preset("color-1000x1000-20k").cfa == "RGGB"
    assert ss.Sensor.preset("sjdd-gn").noise == ss.noise.PaperNoise(10.0, 0.0)
    assert ss.Sensor.preset("physical").noise.threshold_mismatch == 0.045
    assert ss.Sensor.preset("ideal", height=8).height == 8


@pytest.mark.parametrize(
    "kwargs,param",
    [
        ({"threshold": 0}, "threshold"),
        ({"threshold": -1.0}, "threshold"),
        ({"clock_hz": 0}, "clock_hz"),
        ({"clock_hz": float("inf")}, "clock_hz"),
        ({"full_scale_rate": float("nan")}, "full_scale_rate"),
        ({"cfa": "RGBG"}, "cfa"),
        ({"reset": "hold"}, "reset"),
        ({"init": "random"}, "init"),
        ({"height": 0}, "height"),
        ({"width": 2.5}, "width"),
        ({"noise": "gaussian"}, "noise"),
    ],
)
def test_bad_sensor_parameters_name_the_parameter(kwargs, param):
    with pytest.raises(ss.SpikeSimValueError, match=param):
        ss.Sensor(**kwargs)


def test_bad_noise_and_preset_names():
    with pytest.raises(ValueError, match="preset"):
        ss.Sensor.preset("vidar-9000")
    with pytest.raises(ValueError, match="sigma_g"):
        ss.noise.PaperNoise(sigma_g=-1)
    with pytest.raises(ValueError, match="prnu"):
        ss.noise.PhysicalNoise(prnu=float("nan"))
    with pytest.raises(ValueError, match="noise.type"):
        ss.Sensor.from_dict({"noise": {"type": "pink"}})
    with pytest.raises(ValueError, match="sensor keys"):
        ss.Sensor.from_dict({"heigth": 3})


def test_cfa_masks_and_geometry():
    for pattern in cfa_mod.PATTERNS:
        m = cfa_mod.mask_rgb(pattern, 5, 7)
        assert m.shape == (5, 7, 3) and np.all(m.sum(axis=2) == 1)
        planes = cfa_mod.mask_planes(pattern, 5, 7)
        assert np.all(planes.sum(axis=0) == 1)
        # planes agree with the RGB mask: R, G1+G2, B
        np.testing.assert_array_equal(planes[0], m[..., 0])
        np.testing.assert_array_equal(planes[1] + planes[2], m[..., 1])
        np.testing.assert_array_equal(planes[3], m[..., 2])
        full = cfa_mod.channel_index(pattern, 9, 9)
        for top in range(3):
            for left in range(3):
                crop = cfa_mod.cfa_after_crop(pattern, top, left)
                np.testing.assert_array_equal(cfa_mod.channel_index(crop, 4, 4),
                                              full[top : top + 4, left : left + 4])
        for h, w in [(4, 6), (5, 7), (4, 7)]:
            idx = cfa_mod.channel_index(pattern, h, w)
            for hor, ver in [(True, False), (False, True), (True, True)]:
                f = idx[:, ::-1] if hor else idx
                f = f[::-1] if ver else f
                new = cfa_mod.cfa_after_flip(pattern, h, w, horizontal=hor, vertical=ver)
                np.testing.assert_array_equal(cfa_mod.channel_index(new, h, w), f)
    # G1 is the green on the red row
    assert cfa_mod.mask_planes("RGGB", 2, 2)[1, 0, 1] == 1
    assert cfa_mod.mask_planes("GRBG", 2, 2)[1, 0, 0] == 1
    assert cfa_mod.normalize_cfa("mono") is None


@pytest.mark.parametrize("shape", [(1, 1), (3, 5), (2, 9), (7, 64), (5, 65), (1, 130)])
@pytest.mark.parametrize("pattern", ["RGGB", None])
def test_odd_sizes(shape, pattern):
    h, w = shape
    img = np.random.default_rng(0).random((h, w, 3)).astype(np.float32)
    sensor = ss.Sensor(height=h, width=w, cfa=pattern)
    st = ss.simulate(ss.scenes.Static(img), sensor, 50, seed=1, gt_readouts=[0, 49])
    assert st.packed.shape == (50, h, (w + 7) // 8)
    assert st.unpack().shape == (50, h, w)
    # padding bits of the last byte stay zero (np.packbits convention)
    np.testing.assert_array_equal(ss.bits.pack(st.unpack()), st.packed)
    assert st.gt.shape == (2, h, w, 3) and list(st.gt_index) == [0, 49]
    np.testing.assert_array_equal(st.gt[0], img)
    rate = st.firing_rate()
    expected = 0.6 * ss.cfa.mosaic(img, pattern)
    assert np.all(np.abs(rate - expected) <= 1 / 50 + 1e-9)


@pytest.mark.parametrize("chunk", [None, 7])
def test_grey_ground_truth_is_the_image_in_every_channel(chunk):
    """A grey scene's ground truth is written by its own kernel (not NumPy's
    broadcast copy): the image in each channel of each requested readout,
    in one chunk or several, and an empty array when none is asked for."""
    img = np.random.default_rng(3).random((5, 65)).astype(np.float32)
    sensor = ss.Sensor(height=5, width=65, cfa=None)
    st = ss.simulate(ss.scenes.Static(img), sensor, 30, gt_readouts=[29, 0, 12],
                     chunk_readouts=chunk)
    assert st.gt.shape == (3, 5, 65, 3) and st.gt.dtype == np.float32
    assert st.gt.flags.c_contiguous and list(st.gt_index) == [0, 12, 29]
    for k in range(3):
        for c in range(3):
            np.testing.assert_array_equal(st.gt[k, :, :, c], img)
    none = ss.simulate(ss.scenes.Static(img), sensor, 30, gt_readouts=[], chunk_readouts=chunk)
    assert none.gt.shape == (0, 5, 65, 3) and len(none.gt_index) == 0


def test_meta_records_full_configuration():
    sensor = ss.Sensor.preset("sjdd-gpn", height=4, width=10)
    st = ss.simulate(ss.scenes.Static(np.ones((4, 10))), sensor, 5, seed=77, clean_twin=True)
    meta = json.loads(json.dumps(st.meta))
    assert ss.Sensor.from_dict(meta["sensor"]) == sensor
    assert meta["seed"] == 77 and meta["clean_twin"] and meta["bitorder"] == "little"
    assert meta["scene"]["type"] == "static"
    assert st.sensor == sensor and st.seed == 77 and st.cfa == "RGGB"


BAD_IMAGES = [
    (np.full((4, 4), np.nan), "NaN"),
    (np.full((4, 4), np.inf), "inf"),
    (-np.ones((4, 4)), "non-negative"),
    (np.ones((4, 4, 2)), "shape"),
    (np.ones(4), "shape"),
    (np.array([["a"]]), "dtype"),
]


@pytest.mark.parametrize("image,what", BAD_IMAGES)
def test_bad_radiance_is_rejected_with_the_parameter_name(image, what):
    with pytest.raises(ss.SpikeSimError, match="image") as info:
        ss.scenes.Static(image)
    assert what.lower() in str(info.value).lower()


class _BadScene(ss.scenes.Scene):
    height, width = 4, 4

    def __init__(self, value=0.5, keys=(0.0,)):
        self.value, self.keys = value, np.array(keys)

    def radiance(self, t):
        return np.full((4, 4, 3), self.value, np.float32)

    def key_times(self, start_s, stop_s):
        return self.keys

    def describe(self):
        return {"type": "bad"}


def test_bad_simulation_arguments():
    sensor = ss.Sensor(height=4, width=4)
    scene = ss.scenes.Static(np.ones((4, 4)))
    for n in (0, -3, 2.5):
        with pytest.raises(ValueError, match="n_readouts"):
            ss.simulate(scene, sensor, n)
    with pytest.raises(ValueError, match="seed"):
        ss.simulate(scene, sensor, 5, seed=-1)
    # flags are True or False, never a string ("False" would be true)
    with pytest.raises(ValueError, match="clean_twin='False' is invalid: expected True or"):
        ss.simulate(scene, sensor, 5, clean_twin="False")
    with pytest.raises(ValueError, match="progress='no'"):
        ss.simulate_chunks(scene, sensor, 5, progress="no")
    with pytest.raises(ValueError, match="scene size"):
        ss.simulate(ss.scenes.Static(np.ones((5, 4))), sensor, 5)
    with pytest.raises(TypeError, match="scene"):
        ss.simulate(np.ones((4, 4)), sensor, 5)
    with pytest.raises(ValueError, match="gt_readouts"):
        ss.simulate(scene, sensor, 5, gt_readouts=[5])
    with pytest.raises(ValueError, match="chunk_readouts"):
        ss.simulate(scene, sensor, 5, chunk_readouts=0)
    with pytest.raises(ValueError, match="key_times"):
        ss.simulate(_BadScene(keys=(0.0, 0.002, 0.001)), sensor, 5)
    with pytest.raises(ValueError, match="NaN"):
        ss.simulate(_BadScene(value=np.nan), sensor, 5)
    with pytest.raises(ValueError, match="non-negative"):
        ss.simulate(_BadScene(value=-1.0), sensor, 5)
    with pytest.raises(ValueError, match="times_s"):
        Keyframes([0.2, 0.1], [np.ones((2, 2))] * 2)


class _ViewScene(ss.scenes.Scene):
    """Returns a radiance view that is not C-contiguous (a transposed image)."""

    height, width = 6, 5

    def __init__(self, img, poison=None):
        self.img, self.poison = img, poison

    def radiance(self, t):
        view = self.img.transpose(1, 0, 2)
        if self.poison is not None:
            view = view.copy()
            view[4, 3, 2] = self.poison  # one bad value in the last channel
        return view

    def key_times(self, start_s, stop_s):
        return np.array([0.0])

    def describe(self):
        return {"type": "view"}


@pytest.mark.parametrize("cfa", ["RGGB", "mono"])
def test_non_contiguous_radiance_equals_contiguous(cfa):
    img = np.random.default_rng(3).random((5, 6, 3)).astype(np.float32)
    sensor = ss.Sensor(height=6, width=5, cfa=cfa)
    got = ss.simulate(_ViewScene(img), sensor, 50, seed=1).packed
    want = ss.simulate(ss.scenes.Static(np.ascontiguousarray(img.transpose(1, 0, 2))),
                       sensor, 50, seed=1).packed
    np.testing.assert_array_equal(got, want)
    for bad, what in ((np.inf, "inf"), (np.nan, "NaN"), (-0.5, "non-negative")):
        with pytest.raises(ValueError, match=what):
            ss.simulate(_ViewScene(img, poison=bad), sensor, 5)


def test_static_scene_costs_one_key_frame():
    calls = []

    class Counting(ss.scenes.Static):
        def radiance(self, t):
            calls.append(("rgb", t))
            return super().radiance(t)

        def grey(self, t):
            calls.append(("grey", t))
            return super().grey(t)

    sensor = ss.Sensor(height=4, width=4)
    ss.simulate(Counting(np.ones((4, 4, 3))), sensor, 1000, chunk_readouts=100, gt_readouts=[])
    assert calls == [("grey", 0.0), ("rgb", 0.0)]  # asked for a grey frame first, then RGB
    calls.clear()
    ss.simulate(Counting(np.ones((4, 4))), sensor, 1000, chunk_readouts=100, gt_readouts=[])
    assert calls == [("grey", 0.0)]  # a grey image: its one channel only
