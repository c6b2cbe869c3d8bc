"""Metrics against scikit-image and known values."""

from __future__ import annotations

import numpy as np
import pytest
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

from spikejdd import metrics
from spikesim.errors import SpikeSimValueError


@pytest.fixture(scope="module")
def pair():
    rng = np.random.default_rng(0)
    ref = rng.random((48, 40, 3)) ** 2
    return np.clip(ref + rng.normal(0, 0.05, ref.shape), 0, 1), ref


@pytest.mark.parametrize("domain", ["linear", "srgb"])
def test_agrees_with_skimage(pair, domain):
    x, ref = pair
    enc = metrics.srgb_encode if domain == "srgb" else (lambda a: a)
    a, b = enc(x), enc(ref)
    assert metrics.psnr(x, ref, domain) == pytest.approx(
        peak_signal_noise_ratio(b, a, data_range=1.0), abs=1e-10)
    assert metrics.ssim(x, ref, "uniform7", domain) == pytest.approx(
        structural_similarity(a, b, data_range=1.0, channel_axis=-1), abs=1e-10)
    assert metrics.ssim(x, ref, "gauss11", domain) == pytest.approx(
        structural_similarity(a, b, data_range=1.0, channel_axis=-1, gaussian_weights=True,
                              sigma=1.5, use_sample_covariance=False), abs=1e-10)


def test_known_values():
    a, b = np.full((16, 16, 3), 0.5), np.full((16, 16, 3), 0.6)
    assert metrics.psnr(a, b) == pytest.approx(20.0)
    c1 = 0.01**2  # constant images: variance terms cancel, SSIM = luminance term
    expect = (2 * 0.5 * 0.6 + c1) / (0.5**2 + 0.6**2 + c1)
    for v in metrics.SSIM_VARIANTS:
        assert metrics.ssim(a, b, v) == pytest.approx(expect)
    assert metrics.psnr(a, a) == float("inf")
    assert metrics.ssim(a, a) == pytest.approx(1.0)


def test_range_is_not_inferred_and_clamped():
    # a dark pair keeps peak 1.0 (skimage's old default would infer a small range)
    a, b = np.full((16, 16, 3), 0.01), np.full((16, 16, 3), 0.02)
    assert metrics.psnr(a, b) == pytest.approx(40.0)
    # values outside [0, 1] are clamped before scoring
    assert metrics.psnr(np.full((8, 8, 3), 1.7), np.ones((8, 8, 3))) == float("inf")


def test_srgb_curve():
    np.testing.assert_allclose(metrics.srgb_encode([0.0, 0.0031308, 0.18, 1.0]),
                               [0.0, 0.0404500, 0.4613561, 1.0], atol=1e-6)


def test_score_labels(pair):
    s = metrics.score(*pair)
    assert set(s) == {"PSNR[linear]", "PSNR[srgb]", "SSIM-gauss11[linear]",
                      "SSIM-uniform7[linear]", "SSIM-gauss11[srgb]", "SSIM-uniform7[srgb]"}


def test_bad_input(pair):
    x, ref = pair
    with pytest.raises(SpikeSimValueError, match="shape"):
        metrics.psnr(x[:-1], ref)
    with pytest.raises(SpikeSimValueError, match="domain"):
        metrics.psnr(x, ref, "log")
    with pytest.raises(SpikeSimValueError, match="variant"):
        metrics.ssim(x, ref, "gauss7")
    with pytest.raises(SpikeSimValueError, match="11×11"):
        metrics.ssim(x[:8, :8], ref[:8, :8])
    with pytest.raises(SpikeSimValueError, match="NaN|finite"):
        metrics.psnr(np.full_like(ref, np.nan), ref)
