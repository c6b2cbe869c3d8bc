"""fit_temporal recovers κ² and the charge noise σ_q² of simulated flat fields.

Reference: the sensor's true parameters, κ² = σ_t² + 1/E and σ_q² = (σ_e/E)²
(spikesim.analysis.theory), on captures without fixed pattern (every pixel of
a band has the same charge q = 1/m).  About 500 pixels × 40–200 intervals
per band give sub-percent sampling errors on the pooled variances; the
tolerances (10 %) leave room for the clock's rounding model.
"""

from __future__ import annotations

import numpy as np
import pytest

import spikesim as ss
from spikesim.analysis.capture import as_capture, pixel_intervals
from spikesim.analysis.gof_stats import cv_by_interval, summary_distances
from spikesim.analysis.temporal_fit import fit_temporal

MEAN_INTERVALS = (5, 8, 12, 18, 25)  # readouts


def _moments(mean_intervals, n_readouts=1000, **noise_kw):
    rows = 8
    levels = np.repeat(1.0 / np.asarray(mean_intervals, np.float32), rows)
    img = levels[:, None] * np.ones((1, 64), np.float32)
    noise = ss.noise.PhysicalNoise(threshold_mismatch=0.0, prnu=0.0, dark_current_rel=0.0,
                                   hot_pixel_fraction=0.0, **noise_kw)
    sensor = ss.Sensor(height=img.shape[0], width=64, cfa=None, full_scale_rate=1.0,
                       noise=noise)
    stream = ss.simulate(ss.scenes.Static(img), sensor, n_readouts, seed=3)
    return pixel_intervals(as_capture(stream), 0, n_readouts), noise


def test_recovers_charge_noise_and_kappa():
    mom, noise = _moments(MEAN_INTERVALS, electrons_per_threshold=400.0,
                          charge_noise_electrons=8.0)
    fit = fit_temporal(mom, np.ones(mom.n.shape, bool))
    assert fit.charge_noise_fitted and "grows with the interval" in fit.reason
    assert fit.sigma_q2 == pytest.approx((8.0 / 400.0) ** 2, rel=0.1)
    assert fit.kappa2 == pytest.approx(noise.temporal_threshold_noise**2 + 1 / 400.0, rel=0.1)
    assert fit.sigma_q2 > 3 * fit.sigma_q2_se


def test_per_cycle_noise_alone_gives_no_charge_noise():
    mom, noise = _moments(MEAN_INTERVALS, electrons_per_threshold=400.0)
    fit = fit_temporal(mom, np.ones(mom.n.shape, bool))
    assert not fit.charge_noise_fitted and fit.sigma_q2 == 0.0
    assert "not significant" in fit.reason
    assert fit.kappa2 == pytest.approx(noise.temporal_threshold_noise**2 + 1 / 400.0, rel=0.1)


@pytest.mark.parametrize("pattern, e_old", [({}, 262.5),
                                             ({"threshold_mismatch": 0.07, "prnu": 0.09}, 243.8)])
def test_calibration_with_charge_noise_and_a_fixed_pattern_finds_e(pattern, e_old):
    """σ_e is fixed in electrons, so a pixel of threshold t has σ_q/t: with the m³/t̂²
    column and the dark pixels (which fire by diffusion) left out, E and σ_e come back
    within 5 % where the plain m³ column gave them 12–19 % low (``e_old``, same capture)."""
    from spikesim.analysis import calibrate

    img = np.zeros((64, 128), np.float32)
    for k, level in enumerate((0.1, 0.25, 0.6)):
        img[:, 32 * (k + 1):32 * (k + 2)] = level
    noise = ss.noise.PhysicalNoise(electrons_per_threshold=300.0, charge_noise_electrons=10.0,
                                   fpn_seed=4, **pattern)
    sensor = ss.Sensor(height=64, width=128, cfa=None, full_scale_rate=0.5, noise=noise)
    cal = calibrate(ss.simulate(ss.scenes.Static(img), sensor, 4000, seed=3), check=False)
    fitted = cal.sensor.noise
    assert fitted.electrons_per_threshold == pytest.approx(300.0, rel=0.05)
    assert abs(fitted.electrons_per_threshold - 300) < 0.5 * abs(e_old - 300)
    assert fitted.charge_noise_electrons == pytest.approx(10.0, rel=0.05)
    assert any("fire by diffusion" in n for n in cal.notes)


def test_one_interval_length_cannot_show_a_slope():
    mom, _ = _moments((10, 10, 10), electrons_per_threshold=400.0, charge_noise_electrons=8.0)
    fit = fit_temporal(mom, np.ones(mom.n.shape, bool))
    assert not fit.charge_noise_fitted and "no slope" in fit.reason
    off = fit_temporal(mom, np.ones(mom.n.shape, bool), fit_charge_noise=False)
    assert off.sigma_q2 == 0.0 and "fit_charge_noise=False" in off.reason


def test_distances_of_a_capture_with_itself_are_zero():
    mom, _ = _moments((6, 12, 24), n_readouts=400, electrons_per_threshold=400.0)
    rate = mom.n / 400.0
    h = mom.n.shape[0] // 3
    flats = [np.zeros(mom.n.shape, bool) for _ in range(3)]
    for k, f in enumerate(flats):
        f[k * h:(k + 1) * h] = True
    d = summary_distances(rate, rate, mom, mom, None, flats)
    assert d["rate_ks"] == 0 and d["interval_cv_error"] == 0 and d["spatial_spread_error"] == 0
    bins = cv_by_interval(mom, np.ones(mom.n.shape, bool))
    assert [b["lo"] for b in bins] == [4.0, 8.0, 16.0]
    assert sum(b["pixels"] for b in bins) == mom.n.size
