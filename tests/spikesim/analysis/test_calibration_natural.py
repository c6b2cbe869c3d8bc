"""Calibration of natural 200-readout captures, with and without a flat region (issue 53).

Captures (:func:`spikesim.analysis.natural_capture.natural_capture`): a bundled
picture panning 16 pixels, 96 × 96 pixels, 200 readouts, dim (0.03 spikes per
readout on average, like the public real sample) and bright (0.2), mono and
RGGB, from a chip away from the defaults (PRNU 8 %, E = 400 e⁻, dark current
1.5 % of full scale), under a sky band that is uniform (a flat region) or
falls to half from top to bottom (no flat region: the calibration takes the
path for captures without one).  The scene has no dark region and the chip no
charge noise.

Checked, per capture: the calibration runs unaided; the re-simulation with
the calibrated sensor is at least as close to the capture as the package
defaults' on the three distances; each parameter is within its stated
tolerance or reported as not identified:

* combined response spread ``sqrt(s² + p²)``: 20 % with a flat region, 35 %
  without one (texture left in the locally flat neighbourhoods adds to it:
  measured +24-26 % at 0.03 spikes per readout); per colour plane (the planes
  whose regions were found) 30 % and 50 %;
* cycle CV² κ² (so E, σ_t held): 30 % with a flat region (a bright sky fires
  every 3-6 readouts, where the clock's rounding is most of the variance:
  measured -24 % to +13 % on RGGB at 0.2), 50 % without one (moving light
  adds: measured -8 % to +39 %, the most on RGGB at 0.03), or not identified;
* charge noise (none on this chip), dark current, its spread and the hot
  pixels (no dark region in the scene): not identified, package defaults kept.

Fixed seeds; the tolerances cover the values measured over seeds 1-3 with a
margin (docs/analysis.md gives them).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import spikesim as ss
from spikesim.analysis import calibrate, theory
from spikesim.analysis.capture import as_capture, pixel_intervals
from spikesim.analysis.natural_capture import NATURAL_CHIPS, natural_capture
from spikesim.analysis.temporal_fit import MIN_SHARE, fit_temporal
from spikesim.cli import main

CHIP = NATURAL_CHIPS["prnu 8 %, E = 400, dark 1.5 %"]
SPREAD = math.hypot(CHIP["prnu"], CHIP["threshold_mismatch"])
KAPPA2 = 0.006**2 + 1 / CHIP["electrons_per_threshold"]
DEFAULTS = ss.noise.PhysicalNoise()
#: (flat region, none): tolerances of the combined spread, per plane, and of κ².
TOL_SPREAD = {"flat": 0.20, "gradient": 0.35}
TOL_PLANE = {"flat": 0.30, "gradient": 0.50}
TOL_KAPPA2 = {"flat": 0.30, "gradient": 0.50}

CASES = [(cfa, rate, sky) for cfa in (None, "RGGB") for rate in (0.03, 0.2)
         for sky in ("flat", "gradient")]


@pytest.fixture(scope="module", params=CASES,
                ids=[f"{c or 'mono'}-{r}-{s}" for c, r, s in CASES])
def case(request):
    cfa, rate, sky = request.param
    stream, sky_mask, truth = natural_capture(CHIP, cfa=cfa, mean_rate=rate, sky=sky,
                                              size=(96, 96), n_readouts=200, seed=1)
    return cfa, rate, sky, stream, calibrate(stream, check_readouts=None, check_seed=2)


def test_mean_rate_is_as_asked(case):
    cfa, rate, _, stream, _ = case
    assert stream.n_readouts == 200
    assert float(stream.firing_rate().mean()) == pytest.approx(rate, rel=0.15)


def test_path_taken(case):
    *_, sky, _, res = case
    if sky == "flat":
        assert res.flat_masks, "the uniform sky is a flat region"
    else:
        assert res.data["regions"]["detected"] == "none" and not res.flat_masks
        assert any(n.startswith("no flat region found") for n in res.notes)


def test_calibrated_at_least_as_close_as_defaults(case):
    *_, res = case
    rows = res.data["goodness_of_fit"]["side_by_side"]
    assert len(rows) == 3
    for row in rows:
        assert row["closer"].startswith("calibrated"), row
        assert row["calibrated"] <= row["defaults"]


def test_parameters_within_tolerance_or_not_identified(case):
    cfa, _, sky, _, res = case
    d, p, status = res.data["diagnostics"], res.data["parameters"], res.data["status"]
    assert d["combined_gain_spread"] == pytest.approx(SPREAD, rel=TOL_SPREAD[sky])
    if cfa is not None:
        planes = {q["plane"]: q for q in d["planes"]}
        assert planes and set(planes) <= {"R", "G1", "G2", "B"}
        for q in planes.values():
            assert q["combined_gain_spread"] == pytest.approx(SPREAD, rel=TOL_PLANE[sky])
    if status["electrons_per_threshold"].startswith("not identified"):
        assert p["electrons_per_threshold"] == DEFAULTS.electrons_per_threshold
    else:
        assert d["kappa2"] == pytest.approx(KAPPA2, rel=TOL_KAPPA2[sky])
    for key in ("charge_noise_electrons", "dark_current_rel", "dark_current_spread",
                "hot_pixel_fraction", "hot_pixel_dark_rel"):
        assert status[key].startswith("not identified"), key
        assert p[key] == pytest.approx(getattr(DEFAULTS, key)), key
    assert not res.data["identified"]["charge_noise_electrons"]


def test_report_has_the_side_by_side_table_and_plot(case, tmp_path):
    *_, res = case
    from spikesim.analysis import write_report

    paths = write_report(res, tmp_path)
    md = paths["md"].read_text()
    assert "| distance from the capture | calibrated | defaults | closer |" in md
    assert "| mean interval (readouts) | capture pixels | capture CV | calibrated CV |" in md
    assert paths["png"].stat().st_size > 10_000
    assert "| parameter | value | status |" in md


def test_charge_noise_of_a_capture_without_it_is_not_identified():
    """A term worth a few per cent of the interval variance is not identified even
    when its estimate is several standard errors above 0 (the issue's 0.42 e⁻ at
    3.2 s.e.): interval moments built from the model itself, with a charge-noise
    term of 2 % of κ²·m at the longest intervals, and many pixels."""
    m = np.repeat(np.linspace(6.0, 24.0, 40), 500)
    k2, share = 0.001, 0.02
    sq2 = share * k2 / 24.0
    n = np.full(m.size, 400)
    sd = np.sqrt(k2 * m**2 + sq2 * m**3)
    var = k2 * m**2 + sq2 * m**3 + theory.frac_variance(m, sd)
    mom = _moments(m, var, n)
    fit = fit_temporal(mom, np.ones(m.shape, bool))
    assert fit.sigma_q2_estimate > 3 * fit.sigma_q2_se  # significant, yet
    assert not fit.charge_noise_fitted and fit.sigma_q2 == 0 and share < MIN_SHARE
    assert fit.charge_noise_status().startswith("not identified") and "needed" in fit.reason
    big = _moments(m, k2 * m**2 + 50 * sq2 * m**3 + theory.frac_variance(
        m, np.sqrt(k2 * m**2 + 50 * sq2 * m**3)), n)
    assert fit_temporal(big, np.ones(m.shape, bool)).charge_noise_fitted


def _moments(mean, var, n):
    """IntervalMoments of pixels (a 1 × N image) with the given mean, variance and count."""
    from spikesim.analysis.capture import IntervalMoments

    s1 = mean * n
    s2 = var * (n - 1) + s1**2 / n
    shape = (1, mean.size)
    z = np.zeros(shape, np.int64)
    return IntervalMoments(n.reshape(shape), s1.reshape(shape), s2.reshape(shape), z, z, {})


def test_local_variance_theory_against_monte_carlo():
    """theory.local_frac_term: E[(I[k+1] − I[k])²]/2 − Var(τ) of clocked Gaussian cycles
    with a uniform phase (reference: 2·10⁵ simulated pairs, float64)."""
    rng = np.random.default_rng(0)
    for m, sd in ((10.3, 0.0), (5.7, 0.3), (33.0, 1.6), (4.2, 0.1), (7.5, 0.02)):
        tau = m + sd * rng.standard_normal((200_000, 2))
        t0 = rng.random((200_000, 1))
        spikes = np.ceil(np.concatenate([t0, t0 + np.cumsum(tau, axis=1)], axis=1))
        iv = np.diff(spikes, axis=1)
        local = float(np.mean(np.diff(iv, axis=1) ** 2)) / 2
        assert local == pytest.approx(sd**2 + float(theory.local_frac_term(m, sd)), abs=0.01)


def test_local_var_matches_a_reference():
    """IntervalMoments.local_var: half the mean squared successive difference, across
    block boundaries (reference: per-pixel NumPy)."""
    rng = np.random.default_rng(1)
    spikes = (rng.random((2500, 5, 7)) < 0.2).astype(np.uint8)
    mom = pixel_intervals(as_capture(spikes))
    for i in range(5):
        for j in range(7):
            d = np.diff(np.diff(np.flatnonzero(spikes[:, i, j])))
            assert mom.nd[i, j] == d.size
            assert mom.local_var()[i, j] == pytest.approx(np.mean(d**2) / 2)


def test_cli_report_on_a_natural_dat(tmp_path, capsys):
    """A dim mono capture without a flat region, as a .dat: the command writes the
    report (Markdown, JSON, PNG) and the sensor, and prints what is not identified."""
    stream, _, _ = natural_capture(CHIP, mean_rate=0.03, sky="gradient", size=(64, 64), seed=3)
    from spikesim.io import write_dat

    write_dat(tmp_path / "nat.dat", stream.unpack())
    out = tmp_path / "rep"
    assert main(["analyze", "calibrate", str(tmp_path / "nat.dat"), "--height", "64",
                 "--width", "64", "--cfa", "mono", "--out", str(out), "--no-progress"]) == 0
    printed = capsys.readouterr().out
    assert "Not identified by this capture" in printed
    for name in ("calibration.md", "calibration.json", "calibration.png", "sensor.json"):
        assert (out / name).is_file(), name
