"""sRGB decoding: the 8-bit LUT equals colour-science's EOTF; linear input; exposure."""

from __future__ import annotations

import colour
import numpy as np
import pytest

from spikesim.errors import SpikeSimTypeError, SpikeSimValueError
from spikesim.scenes.photometry import SRGB8_LUT, decode_frame
from spikesim.srgb import linear_to_srgb, linear_to_srgb8, srgb_to_linear


def test_lut_equals_colour_eotf_for_every_code():
    codes = np.arange(256, dtype=np.uint8)
    expected = colour.models.eotf_sRGB(codes / 255.0)
    np.testing.assert_allclose(SRGB8_LUT, expected, rtol=1e-6, atol=1e-9)
    img = codes.reshape(16, 16)
    out = decode_frame(img)
    np.testing.assert_allclose(out[..., 1], expected.reshape(16, 16), rtol=1e-6, atol=1e-9)


def test_known_values_and_round_trip():
    # sRGB 0.5 is 0.214 linear; 0.04045 is the knee of the piecewise curve
    assert srgb_to_linear(0.5) == pytest.approx(0.21404114, abs=1e-7)
    assert srgb_to_linear(0.04045) == pytest.approx(0.04045 / 12.92, rel=1e-6)
    x = np.linspace(0, 1, 101)
    np.testing.assert_allclose(srgb_to_linear(linear_to_srgb(x)), x, atol=1e-12)


def test_sixteen_bit_and_float_paths_match_eotf():
    v16 = np.array([[0, 1000, 32768, 65535]], np.uint16)
    np.testing.assert_allclose(decode_frame(v16)[..., 0], srgb_to_linear(v16 / 65535.0),
                               rtol=1e-6)
    f = np.array([[0.0, 0.25, 0.5, 1.0]], np.float32)
    np.testing.assert_allclose(decode_frame(f)[..., 2], srgb_to_linear(f), rtol=1e-6)


def test_linear_input_and_exposure():
    v16 = np.array([[0, 65535]], np.uint16)
    np.testing.assert_allclose(decode_frame(v16, linear=True)[0, :, 0], [0.0, 1.0])
    v8 = np.array([[51, 255]], np.uint8)
    np.testing.assert_allclose(decode_frame(v8, linear=True, exposure=2.0)[0, :, 0], [0.4, 2.0],
                               rtol=1e-6)
    f = np.full((2, 2, 3), 0.3, np.float32)
    np.testing.assert_allclose(decode_frame(f, linear=True, exposure=0.5), 0.15, rtol=1e-6)


def test_bad_frames():
    with pytest.raises(SpikeSimValueError, match="no NaN"):
        decode_frame(np.array([[0.1, np.nan]], np.float32), name="f.tif")
    with pytest.raises(SpikeSimValueError, match="non-negative"):
        decode_frame(np.array([[-0.1]], np.float32))
    with pytest.raises(SpikeSimValueError, match="exposure"):
        decode_frame(np.zeros((2, 2), np.uint8), exposure=0)
    with pytest.raises(SpikeSimValueError, match="exposure"):
        decode_frame(np.zeros((2, 2), np.uint8), exposure=float("inf"))
    with pytest.raises(SpikeSimTypeError, match="dtype"):
        decode_frame(np.zeros((2, 2), np.int32))
    with pytest.raises(SpikeSimValueError, match="shape"):
        decode_frame(np.zeros((2, 2, 2), np.uint8))


def test_the_one_srgb_curve_is_bit_equal_to_colour_science():
    """spikesim computes the sRGB curves itself (importing colour-science takes seconds in
    every worker process); the bits must be colour-science's, codes and floats alike
    (the encoding clips to [0, 1] first)."""
    rng = np.random.default_rng(7)
    values = np.concatenate([
        np.arange(256) / 255.0, np.arange(65536) / 65535.0,
        rng.random(200_000), rng.random(20_000) * 0.1, rng.normal(0, 2, 20_000),
        np.linspace(0.04, 0.041, 10_001), np.linspace(0.003, 0.0032, 10_001),
        rng.random(200_000).astype(np.float32), [0.0, -0.0, 1.0, 0.0031308, 0.04045]])
    for ours, theirs, x in ((srgb_to_linear, colour.models.eotf_sRGB, values),
                            (linear_to_srgb, colour.models.eotf_inverse_sRGB,
                             np.clip(values, 0.0, 1.0))):
        a, b = np.asarray(ours(x)), np.asarray(theirs(x))
        assert a.dtype == b.dtype == np.float64
        np.testing.assert_array_equal(a.view(np.uint64), b.view(np.uint64))
    np.testing.assert_allclose(linear_to_srgb([-1.0, 2.0]), [0.0, 1.0], rtol=0, atol=1e-15)
    codes = linear_to_srgb8(srgb_to_linear(np.arange(256) / 255.0))
    np.testing.assert_array_equal(codes, np.arange(256))  # every 8-bit code round-trips
