"""A grey image is simulated from its one channel: the same bits as its
three-channel copy, at a third of the memory traffic."""

from __future__ import annotations

import sys

import numpy as np
import pytest

import spikesim as ss
from spikesim.errors import SpikeSimValueError


def _grey(h=40, w=70, seed=0):
    rng = np.random.default_rng(seed)
    return (rng.random((h, w)) * 1.4).astype(np.float32)  # some pixels above full scale


@pytest.mark.parametrize("cfa", ["RGGB", None])
@pytest.mark.parametrize("noise", [None, "paper", "physical"])
def test_grey_static_equals_its_three_channel_copy(cfa, noise):
    img = _grey()
    noise_model = {None: None, "paper": ss.noise.PaperNoise(sigma_g=10),
                   "physical": ss.noise.PhysicalNoise()}[noise]
    sensor = ss.Sensor(height=40, width=70, cfa=cfa, noise=noise_model)
    kw = dict(seed=5, clean_twin=True, gt_readouts=[0, 33, 90], chunk_readouts=29)
    a = ss.simulate(ss.scenes.Static(img), sensor, 100, **kw)
    b = ss.simulate(ss.scenes.Static(np.repeat(img[..., None], 3, axis=2)), sensor, 100, **kw)
    np.testing.assert_array_equal(a.packed, b.packed)
    np.testing.assert_array_equal(a.clean_packed, b.clean_packed)
    np.testing.assert_array_equal(a.gt, b.gt)
    assert a.unpack().any()
    assert a.meta["scene"]["mean_radiance"] == pytest.approx(b.meta["scene"]["mean_radiance"],
                                                             rel=1e-12)


@pytest.mark.parametrize("make", [lambda: _grey(), lambda: np.repeat(_grey()[..., None], 3, 2),
                                  lambda: np.repeat(_grey()[..., None], 3, 2)[:, :50]])
def test_static_keeps_its_own_copy_and_leaves_the_callers_array_writable(make):
    img = make()
    scene = ss.scenes.Static(img)
    assert img.flags.writeable
    before = scene.radiance(0.0).copy()
    img[:] = 0.0  # the caller's array changes; the scene does not
    np.testing.assert_array_equal(scene.radiance(0.0), before)
    assert scene.radiance(0.0).shape == (40, img.shape[1], 3)
    if img.ndim == 2:
        np.testing.assert_array_equal(scene.grey(0.0), before[..., 1])
    else:
        assert scene.grey(0.0) is None


class _BadGrey(ss.scenes.Scene):
    height, width = 8, 64

    def radiance(self, t):
        return np.ones((8, 64, 3), np.float32)

    def grey(self, t):
        g = np.ones((8, 64), np.float32)
        g[3, 5] = np.nan
        return g

    def describe(self):
        return {"type": "bad-grey"}


def test_a_grey_frame_with_nan_is_a_one_line_error_naming_grey():
    sensor = ss.Sensor(height=8, width=64, cfa="RGGB")
    with pytest.raises(SpikeSimValueError, match=r"scene\.grey\(t=0\).*finite"):
        ss.simulate(_BadGrey(), sensor, 10)


def test_a_grey_frame_of_the_wrong_size_names_the_sensor_size():
    class Small(_BadGrey):
        def grey(self, t):
            return np.ones((8, 60, 1), np.float32)

    with pytest.raises(SpikeSimValueError, match=r"grey\(t=0\)\.shape.*\(8, 64\)"):
        ss.simulate(Small(), ss.Sensor(height=8, width=64), 10)


def test_a_grey_attribute_that_is_not_a_method_is_ignored():
    class Flagged(_BadGrey):
        grey = True  # a scene's own attribute, not the protocol's method

    stream = ss.simulate(Flagged(), ss.Sensor(height=8, width=64), 10)
    assert stream.gt.shape == (1, 8, 64, 3)


def test_a_static_frame_sampled_once_is_reused_only_for_the_same_image_and_cfa():
    """Later runs copy a frozen image's sampled key frame instead of sampling it
    again: the same bits as a cold run, for each CFA, and never for another
    image (even one that reuses a dead image's address)."""
    sim = sys.modules["spikesim.simulate"]
    rng = np.random.default_rng(7)
    sensors = [ss.Sensor(height=20, width=70, cfa=c) for c in ("RGGB", None, "GBRG")]

    def cold(img, sensor):
        sim._FROZEN_FRAMES.clear()
        return ss.simulate(ss.scenes.Static(img), sensor, 50, seed=3).packed

    for _ in range(3):  # new images, likely at recycled addresses
        img = rng.random((20, 70, 3)).astype(np.float32)
        scene = ss.scenes.Static(img)
        want = [cold(img, s) for s in sensors]
        for _ in range(2):
            for sensor, w in zip(sensors, want, strict=True):
                np.testing.assert_array_equal(ss.simulate(scene, sensor, 50, seed=3).packed, w)
        assert len(sim._FROZEN_FRAMES) > 0  # the warm runs had frames to reuse
        del scene


def test_a_kept_frame_lent_to_the_kernel_is_never_pooled_or_written():
    """A run of one chunk and one key frame passes the kept frame to the kernel
    as it is: afterwards it is unchanged, no pooled buffer shares its memory,
    and runs of several chunks (which copy it) give the same bits."""
    sim = sys.modules["spikesim.simulate"]
    img = np.random.default_rng(5).random((64, 300, 3)).astype(np.float32)
    scene = ss.scenes.Static(img)  # a key frame of 80 kB: large enough to be pooled
    sensor = ss.Sensor(height=64, width=300, cfa="RGGB",
                       noise=ss.noise.PaperNoise(sigma_g=5.0, sigma_p=0.0))
    sim._FROZEN_FRAMES.clear()
    first = ss.simulate(scene, sensor, 40, seed=1, clean_twin=True)  # samples and keeps it
    (kept,) = [v[1] for v in sim._FROZEN_FRAMES.values()]
    before = kept.copy()
    for n in (1, 40):
        lent = ss.simulate(scene, sensor, n, seed=1, clean_twin=True)
        np.testing.assert_array_equal(lent.packed, first.packed[:n])
        np.testing.assert_array_equal(lent.clean_packed, first.clean_packed[:n])
        chunked = ss.simulate(scene, sensor, n, seed=1, chunk_readouts=7)
        np.testing.assert_array_equal(chunked.packed, lent.packed)
    np.testing.assert_array_equal(kept, before)
    assert not any(np.shares_memory(kept, a) for a in sim._KEY_POOL._free)


def test_an_8bit_picture_given_as_radiance_warns():
    """Static takes radiance as given (255 = 255× full scale): an 8-bit picture warns
    with the conversion to make; 0/1 masks and float images do not."""
    import warnings

    import numpy as np
    import pytest

    import spikesim as ss

    with pytest.warns(UserWarning, match=r"8-bit \(0..200\).*srgb_to_linear\(image / 255\)"):
        ss.scenes.Static(np.full((4, 4, 3), 200, np.uint8))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ss.scenes.Static(np.ones((4, 4), np.uint8))
        ss.scenes.Static(np.full((4, 4), 200.0))
