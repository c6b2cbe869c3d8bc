"""Demosaicing: exact flat images (borders included) and every method on every CFA."""

from __future__ import annotations

import numpy as np
import pytest
from skimage import data

from spikejdd.demosaic import DEMOSAIC_METHODS, demosaic
from spikesim.cfa import PATTERNS, mosaic
from spikesim.errors import SpikeSimTypeError, SpikeSimValueError

COLOUR = np.array([0.2, 0.5, 0.8])


@pytest.mark.parametrize("cfa", PATTERNS)
@pytest.mark.parametrize("shape", [(2, 2), (3, 5), (8, 10), (17, 9)])
def test_bilinear_flat_exact_everywhere(cfa, shape):
    img = np.ones(shape + (3,)) * COLOUR
    out = demosaic(mosaic(img, cfa), cfa, "bilinear")
    np.testing.assert_allclose(out, img, rtol=0, atol=1e-14)


def test_bilinear_interior_is_textbook():
    rng = np.random.default_rng(0)
    raw = rng.random((6, 6))
    out = demosaic(raw, "RGGB", "bilinear")
    # (2, 2) is red in RGGB: G = mean of 4 neighbours, B = mean of 4 diagonals
    assert out[2, 2, 0] == raw[2, 2]
    assert out[2, 2, 1] == pytest.approx((raw[1, 2] + raw[3, 2] + raw[2, 1] + raw[2, 3]) / 4)
    assert out[2, 2, 2] == pytest.approx((raw[1, 1] + raw[1, 3] + raw[3, 1] + raw[3, 3]) / 4)
    # (2, 3) is green on a red row: R = mean left/right, B = mean up/down
    assert out[2, 3, 0] == pytest.approx((raw[2, 2] + raw[2, 4]) / 2)
    assert out[2, 3, 2] == pytest.approx((raw[1, 3] + raw[3, 3]) / 2)
    # corner (0, 0): only the existing neighbours are averaged
    assert out[0, 0, 1] == pytest.approx((raw[0, 1] + raw[1, 0]) / 2)
    assert out[0, 0, 2] == raw[1, 1]


@pytest.fixture(scope="module")
def picture():
    return data.astronaut()[180:276, 160:256].astype(np.float64) / 255.0


def _psnr(a, b):
    return 10 * np.log10(1 / np.mean((np.clip(a, 0, 1) - b) ** 2))


@pytest.mark.parametrize("cfa", PATTERNS)
@pytest.mark.parametrize("method", list(DEMOSAIC_METHODS))
def test_each_method_on_each_cfa(method, cfa, picture):
    flat = np.ones((9, 12, 3)) * COLOUR
    np.testing.assert_allclose(demosaic(mosaic(flat, cfa), cfa, method), flat, atol=2e-5)
    raw = mosaic(picture, cfa)
    good = _psnr(demosaic(raw, cfa, method), picture)
    assert good > 27.0
    wrong = {"RGGB": "BGGR", "BGGR": "RGGB", "GRBG": "GBRG", "GBRG": "GRBG"}[cfa]
    assert _psnr(demosaic(raw, wrong, method), picture) < good - 5.0


def test_quality_ordering(picture):
    raw = mosaic(picture, "RGGB")
    scores = {m: _psnr(demosaic(raw, "RGGB", m), picture) for m in DEMOSAIC_METHODS}
    assert scores["menon2007"] > scores["malvar2004"] > scores["bilinear"]


def test_mono_copies_grey():
    raw = np.random.default_rng(0).random((5, 7))
    out = demosaic(raw, None)
    assert out.shape == (5, 7, 3) and np.array_equal(out[..., 1], raw)


def test_bad_input():
    with pytest.raises(SpikeSimValueError, match="demosaic method"):
        demosaic(np.zeros((4, 4)), "RGGB", "ahd")
    with pytest.raises(SpikeSimValueError, match="cfa"):
        demosaic(np.zeros((4, 4)), "RGBG")
    with pytest.raises(SpikeSimValueError, match="raw.shape"):
        demosaic(np.zeros((4, 4, 3)), "RGGB")
    with pytest.raises(SpikeSimValueError, match="2×2"):
        demosaic(np.zeros((1, 4)), "RGGB")
    with pytest.raises(SpikeSimTypeError, match="dtype"):
        demosaic(np.zeros((4, 4), bool), "RGGB")
