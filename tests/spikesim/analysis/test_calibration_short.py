"""Calibration of short (200-readout) captures of moving scenes, without masks.

The claim (issue 15): on 200-readout captures of a moving scene simulated with
known non-default parameters, regions are detected, the charge noise is
fitted when present, and the calibrated sensor re-simulates the capture at
least as closely as the package defaults on the three goodness-of-fit
distances.  Fixed seeds; sizes kept small (48 × 128 pixels).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import spikesim as ss
from spikesim.analysis import calibrate
from spikesim.analysis.calibrate_fit import DARK_FALLBACK
from spikesim.analysis.calibration_config import MIN_READOUTS, CalibrationConfig
from spikesim.analysis.capture import as_capture, pixel_intervals
from spikesim.analysis.short_capture import FAR_FROM_DEFAULTS, FIDELITY_SETTINGS, moving_capture
from spikesim.cli import main
from spikesim.errors import SpikeSimValueError
from tests.support.fixture_paths import PEER_REDS

STRONG, WEAK = FAR_FROM_DEFAULTS
DISTANCES = ("rate KS (mean D)", "interval CV error", "spatial spread error")


@pytest.fixture(scope="module")
def strong():
    rate, noise_kw, levels = FIDELITY_SETTINGS[STRONG]
    stream, dark, flats, truth = moving_capture(rate, noise_kw, levels, seed=0)
    return stream, dark, flats, truth, calibrate(stream, check_readouts=None)


@pytest.fixture(scope="module")
def weak():
    rate, noise_kw, levels = FIDELITY_SETTINGS[WEAK]
    stream, dark, flats, truth = moving_capture(rate, noise_kw, levels, seed=0)
    return stream, dark, flats, truth, calibrate(stream, check_readouts=None)


@pytest.mark.parametrize("case", ["strong", "weak"])
def test_regions_found_in_a_short_moving_capture(case, request):
    stream, dark, flats, _, res = request.getfixturevalue(case)
    assert stream.n_readouts == MIN_READOUTS == 200
    assert res.data["regions"]["detected"]
    # the detected dark region is truly dark and most of it; the moving texture is not "flat"
    assert not np.any(res.dark_mask & ~dark) and res.dark_mask.sum() > 0.6 * dark.sum()
    assert len(res.flat_masks) == 3
    for found, true in zip(res.flat_masks, flats, strict=True):
        assert not np.any(found & ~true) and found.sum() > 0.4 * true.sum()


@pytest.mark.parametrize("case", ["strong", "weak"])
def test_calibrated_resimulates_at_least_as_close_as_defaults(case, request):
    *_, res = request.getfixturevalue(case)
    comp = {r["sensor"]: r for r in res.data["goodness_of_fit"]["comparison"]}
    for key in DISTANCES:
        assert comp["calibrated"][key] <= comp["defaults"][key], key
    # and the verdict line says so
    assert any("rate KS: calibrated closer" in n for n in res.notes)


def test_short_capture_recovers_parameters(strong):
    _, _, _, truth, res = strong
    p, noise = res.data["parameters"], truth.noise
    i_max = max(FIDELITY_SETTINGS[STRONG][2])
    # radiances unknown: full scale is the brightest band
    assert p["full_scale_rate"] == pytest.approx(truth.full_scale_rate * i_max, rel=0.03)
    # combined response spread: ~1200 flat pixels give a few % sampling error
    assert res.data["diagnostics"]["combined_gain_spread"] == pytest.approx(
        math.hypot(noise.threshold_mismatch, noise.prnu), rel=0.1)
    assert p["dark_current_rel"] == pytest.approx(noise.dark_current_rel / i_max, rel=0.15)
    # temporal: the charge noise is detected; sigma_q² within 25 %, kappa² within 25 %
    d = res.data["diagnostics"]
    assert d["charge_noise_fitted"]
    true_sq2 = (noise.charge_noise_electrons / noise.electrons_per_threshold) ** 2
    assert d["sigma_q2"] == pytest.approx(true_sq2, rel=0.25)
    true_k2 = noise.temporal_threshold_noise**2 + 1 / noise.electrons_per_threshold
    assert d["kappa2"] == pytest.approx(true_k2, rel=0.25)
    assert p["charge_noise_electrons"] == pytest.approx(
        math.sqrt(d["sigma_q2"]) * p["electrons_per_threshold"])


def test_a_known_full_scale_rate_places_the_regions(strong, capsys, tmp_path):
    """Radiances unknown but the rate at radiance 1 known: the regions' radiances and
    the currents relative to full scale are measured, not fractions of the brightest band."""
    stream, _, _, truth, blind = strong
    levels = FIDELITY_SETTINGS[STRONG][2]
    res = calibrate(stream, check=False, full_scale_rate=truth.full_scale_rate)
    p, noise = res.data["parameters"], truth.noise
    assert p["full_scale_rate"] == truth.full_scale_rate
    assert res.flat_levels == pytest.approx(levels, rel=0.03)
    assert p["dark_current_rel"] == pytest.approx(noise.dark_current_rel, rel=0.15)
    assert blind.data["parameters"]["dark_current_rel"] > 2 * noise.dark_current_rel
    # the scale does not change the fitted spreads or temporal noise
    for key in ("combined_gain_spread", "kappa2", "sigma_q2"):
        assert res.data["diagnostics"][key] == pytest.approx(blind.data["diagnostics"][key],
                                                             rel=1e-6), key
    assert any("known full_scale_rate" in n for n in res.notes)
    assert not any("brightest flat region defines" in n for n in res.notes)
    with pytest.raises(SpikeSimValueError, match=r"full_scale_rate=0.6 .*None when flat_levels"):
        calibrate(stream, check=False, full_scale_rate=0.6, flat_levels=levels)
    with pytest.raises(SpikeSimValueError, match="full_scale_rate=1.5"):
        calibrate(stream, check=False, full_scale_rate=1.5)
    from spikesim.io import write_dat

    write_dat(tmp_path / "cap.dat", stream.unpack())
    args = ["analyze", "calibrate", str(tmp_path / "cap.dat"), "--height", "48", "--width",
            "128", "--no-check", "--no-progress", "--full-scale-rate", "0.6"]
    assert main(args + ["--levels", "0.1,0.2,0.3", "--out", str(tmp_path / "c0")]) == 1
    assert "--full-scale-rate=0.6 is invalid: expected no --full-scale-rate when --levels" in \
        capsys.readouterr().err
    assert main(args + ["--out", str(tmp_path / "c1")]) == 0
    import json

    rep = json.loads((tmp_path / "c1" / "calibration.json").read_text())
    assert rep["parameters"]["full_scale_rate"] == 0.6


def test_no_charge_noise_is_not_invented(weak):
    *_, res = weak
    d = res.data["diagnostics"]
    assert not d["charge_noise_fitted"] and res.data["parameters"]["charge_noise_electrons"] == 0
    assert any("not significant" in n for n in res.notes)
    assert res.data["status"]["charge_noise_electrons"].startswith("not identified")
    # weak dark current (0.2 spikes per pixel in 200 readouts): spread held at the default
    assert res.data["parameters"]["dark_current_spread"] == DARK_FALLBACK["dark_current_spread"]
    assert any("too weak" in n for n in res.notes)


def test_fit_charge_noise_off_keeps_zero(strong):
    stream, *_ = strong
    res = calibrate(stream, fit_charge_noise=False, check=False)
    assert res.data["parameters"]["charge_noise_electrons"] == 0.0
    assert any("fit_charge_noise=False" in n for n in res.notes)
    cfg = CalibrationConfig(fit_charge_noise=False, check=False)
    assert calibrate(stream, config=cfg).data["parameters"] == res.data["parameters"]


def test_no_dark_region_falls_back_to_defaults():
    rate, noise_kw, levels = FIDELITY_SETTINGS[STRONG]
    stream, dark, flats, _ = moving_capture(rate, noise_kw, levels, seed=3, top_level=0.5)
    assert not dark.any()
    res = calibrate(stream, check=False)
    assert res.dark_mask is None and len(res.flat_masks) == 4
    p = res.data["parameters"]
    for k, v in DARK_FALLBACK.items():
        assert p[k] == pytest.approx(v), k
    assert any("no dark region" in n and "package default" in n for n in res.notes)


def test_a_capture_without_flat_region_is_calibrated_without_one():
    """Nothing flat (a ramp): the natural-capture path runs instead of refusing,
    and the notes say why and what it could not identify."""
    h, w = 32, 64
    rng = np.random.default_rng(0)
    q = np.linspace(0.02, 0.6, w)[None, None, :] * np.ones((1, h, 1))
    spikes = (rng.random((300, h, w)) < q).astype(np.uint8)
    res = calibrate(spikes, check=False, cfa="mono")
    assert res.data["regions"]["detected"] == "none"
    assert any(n.startswith("no flat region found") and "spatial residuals" in n
               for n in res.notes)
    assert res.data["status"]["charge_noise_electrons"].startswith("not identified")
    assert res.data["status"]["dark_current_rel"].startswith("not identified")


@pytest.mark.skipif(not PEER_REDS.is_dir(), reason="shared fixtures not present")
def test_fixture_capture_200_readouts_without_masks():
    """The shared 200-readout fixture (a moving street scene from another
    simulator) has no uniform static region: it is calibrated from its steady
    pixels and spatial residuals, and what it cannot identify is said so."""
    cap = as_capture(PEER_REDS / "203_part2_key_id151.dat", height=250, width=400)
    res = calibrate(cap, max_readouts=200, check=False)
    assert res.data["regions"]["detected"] == "none" and not res.flat_masks
    status = res.data["status"]
    for key in ("dark_current_rel", "dark_current_spread", "hot_pixel_fraction",
                "charge_noise_electrons"):
        assert status[key].startswith("not identified"), key
        assert res.data["parameters"][key] == pytest.approx(
            getattr(ss.noise.PhysicalNoise(), key)), key
    assert any(n.startswith("Not identified by this capture") for n in res.notes)


def test_too_short_and_bad_options():
    spikes = np.zeros((MIN_READOUTS - 1, 16, 16), np.uint8)
    with pytest.raises(SpikeSimValueError, match="capture length=.199 readouts.*at least 200"):
        calibrate(spikes)
    with pytest.raises(SpikeSimValueError, match="calibrate options.*fit_charge"):
        calibrate(spikes, fit_charge=True)
    with pytest.raises(SpikeSimValueError, match="fit_charge_noise"):
        CalibrationConfig(fit_charge_noise="yes")
    with pytest.raises(SpikeSimValueError, match="mismatch_split"):
        CalibrationConfig(mismatch_split=1.5)
    with pytest.raises(SpikeSimValueError, match="check_readouts"):
        CalibrationConfig(check_readouts=0)


def test_cv_bins_are_the_within_pixel_cv(strong):
    """The interval CV per rate bin of the report is the within-pixel CV of the regions."""
    stream, _, _, _, res = strong
    mom = pixel_intervals(as_capture(stream), 0, stream.n_readouts)
    bins = res.data["goodness_of_fit"]["summary"]["cv_bins"]
    assert bins
    union = res.dark_mask | np.logical_or.reduce(res.flat_masks)
    m, v = mom.mean(), mom.var()
    for b in bins:
        sel = union & (mom.n >= 3) & (m >= b["lo"]) & (m < b["hi"])
        assert sel.sum() == b["capture_pixels"]
        assert b["capture_cv"] == pytest.approx(np.sqrt(np.median(v[sel] / m[sel] ** 2)))


def test_cli_short_study_and_no_charge_noise(tmp_path, strong):
    out = tmp_path / "short"
    assert main(["analyze", "calibration-short", "--size", "48x128", "--seeds", "0",
                 "--out", str(out), "--no-progress"]) == 0
    import json

    rep = json.loads((out / "calibration_short.json").read_text())
    assert len(rep["rows"]) == len(FIDELITY_SETTINGS) and rep["far_settings_closer"]
    stream, *_ = strong
    from spikesim.io import write_dat

    write_dat(tmp_path / "cap.dat", stream.unpack())
    assert main(["analyze", "calibrate", str(tmp_path / "cap.dat"), "--height", "48", "--width",
                 "128", "--no-charge-noise", "--no-check", "--out", str(tmp_path / "cal"),
                 "--no-progress"]) == 0
    rep = json.loads((tmp_path / "cal" / "calibration.json").read_text())
    assert rep["parameters"]["charge_noise_electrons"] == 0.0


def test_given_masks_over_moving_content_get_a_warning(strong):
    stream, dark, flats, _, _ = strong
    texture = np.zeros_like(dark)
    texture[4:-4, 70:-4] = True  # the sliding texture: not a static region
    res = calibrate(stream, dark_mask=dark, flat_masks=[*flats, texture], check=False)
    warned = [n for n in res.notes if "does not look static" in n]
    assert len(warned) == 1 and warned[0].startswith("flat_masks[3]")
