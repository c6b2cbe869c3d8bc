"""Calibration recovers known parameters, re-simulates like the capture, and rejects bad input.

Tolerances are those stated in spikesim.analysis.accuracy.TOLERANCES (64 × 64 pixels,
10⁴ readouts; fixed seeds).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import spikesim as ss
from spikesim.analysis import calibrate, calibration_accuracy
from spikesim.analysis.accuracy import CALIBRATION_SETTINGS, _compare, band_capture
from spikesim.analysis.fitcheck import goodness_of_fit, ks_critical, ks_distance
from spikesim.cli import main
from spikesim.errors import SpikeSimTypeError, SpikeSimValueError
from spikesim.io import write_dat

LEVELS = (0.15, 0.4, 0.8)


@pytest.fixture(scope="module")
def capture():
    rate, noise_kw, _, levels = CALIBRATION_SETTINGS["defaults (SCSim), hot 1 %"]
    return band_capture(rate, noise_kw, levels, (64, 64), 10_000, seed=2)


@pytest.fixture(scope="module")
def fitted(capture):
    stream, dark, flats, _ = capture
    return calibrate(stream, dark_mask=dark, flat_masks=flats, flat_levels=LEVELS,
                     check_readouts=3000)


def test_recovers_known_parameters(capture, fitted):
    _, _, _, truth = capture
    rows = _compare("defaults", truth, fitted.data["parameters"], LEVELS,
                    fitted.data["diagnostics"], auto=False)
    bad = [r for r in rows if not r[-1]]
    assert not bad, bad
    assert len(rows) == 10


def test_fitted_sensor_json_loads_and_resimulation_matches(fitted):
    sensor = ss.Sensor.from_json(fitted.sensor.to_json())
    assert sensor == fitted.sensor and isinstance(sensor.noise, ss.noise.PhysicalNoise)
    fit = fitted.data["goodness_of_fit"]
    assert set(fit["regions"]) == {"dark", "flat 0 (I=0.15)", "flat 1 (I=0.4)", "flat 2 (I=0.8)"}
    for name, reg in fit["regions"].items():
        # per-pixel rate distributions: KS distance below the α = 0.001 critical value
        assert reg["rate"]["ks"] < reg["rate"]["ks_critical"], name
        assert reg["rate"]["resim_mean"] == pytest.approx(reg["rate"]["capture_mean"], rel=0.1)
        assert reg["isi"]["resim_mean"] == pytest.approx(reg["isi"]["capture_mean"], rel=0.1)
        assert reg["isi"]["resim_sd"] == pytest.approx(reg["isi"]["capture_sd"], rel=0.15)


def test_goodness_of_fit_detects_a_wrong_model(capture, fitted):
    stream, dark, flats, _ = capture
    rate = stream.firing_rate()
    wrong = fitted.sensor.replace(noise=fitted.sensor.noise.replace(
        dark_current_rel=3 * fitted.sensor.noise.dark_current_rel, prnu=0.15))
    fit = goodness_of_fit(stream, wrong, rate, dark, flats, LEVELS,
                          np.zeros(rate.shape, bool), n_readouts=3000)
    assert fit["regions"]["dark"]["rate"]["ks"] > 3 * fit["regions"]["dark"]["rate"][
        "ks_critical"]
    assert fit["regions"]["flat 2 (I=0.8)"]["rate"]["ks"] > fit["regions"]["flat 2 (I=0.8)"][
        "rate"]["ks_critical"]


def test_ks_distance_reference():
    a = np.array([1.0, 2.0, 3.0, 4.0])
    assert ks_distance(a, a) == 0.0
    assert ks_distance(a, a + 10) == 1.0
    assert ks_distance(np.array([1.0, 2.0]), np.array([2.0, 3.0])) == 0.5
    assert ks_critical(100, 100) == pytest.approx(1.949 * np.sqrt(0.02))


def test_automatic_regions(capture):
    stream, dark, flats, truth = capture
    res = calibrate(stream, check=False)
    assert res.data["regions"]["detected"]
    assert not np.any(res.dark_mask & ~dark)  # detected dark pixels are truly dark
    assert res.dark_mask.sum() > 0.7 * dark.sum()
    assert len(res.flat_masks) == 3
    for found, true in zip(res.flat_masks, flats, strict=True):
        assert not np.any(found & ~true) and found.sum() > 0.5 * true.sum()
    # unknown radiances: the brightest band is full scale
    assert res.flat_levels[-1] == 1.0
    assert res.data["parameters"]["full_scale_rate"] == pytest.approx(0.6 * 0.8, rel=0.02)
    assert res.flat_levels[0] == pytest.approx(0.15 / 0.8, rel=0.05)


def test_calibrate_from_files_and_cli(capture, tmp_path):
    stream, dark, flats, _ = capture
    spikes = stream.unpack(start=0, stop=4000)
    write_dat(tmp_path / "cap.dat", spikes)
    from_dat = calibrate(tmp_path / "cap.dat", height=64, width=64, dark_mask=dark,
                         flat_masks=flats, flat_levels=LEVELS, check=False)
    from_arr = calibrate(spikes, dark_mask=dark, flat_masks=flats, flat_levels=LEVELS,
                         check=False)
    assert from_dat.data["parameters"] == from_arr.data["parameters"]
    labels = np.zeros((64, 64), np.int64)
    for k, m in enumerate(flats, 1):
        labels[m] = k
    np.save(tmp_path / "dark.npy", dark)
    np.save(tmp_path / "flats.npy", labels)
    out = tmp_path / "report"
    code = main(["analyze", "calibrate", str(tmp_path / "cap.dat"), "--height", "64", "--width",
                 "64", "--dark-mask", str(tmp_path / "dark.npy"), "--flat-masks",
                 str(tmp_path / "flats.npy"), "--levels", "0.15,0.4,0.8", "--out", str(out),
                 "--no-check", "--no-progress"])
    assert code == 0
    sensor = ss.Sensor.from_json((out / "sensor.json").read_text())
    assert sensor.full_scale_rate == pytest.approx(from_arr.sensor.full_scale_rate)
    report = json.loads((out / "calibration.json").read_text())
    assert report["parameters"]["prnu"] == pytest.approx(from_arr.data["parameters"]["prnu"])
    assert (out / "calibration.md").read_text().startswith("# Calibration")


def test_bad_inputs(capture):
    stream, dark, flats, _ = capture
    spikes = stream.unpack(start=0, stop=1200)
    with pytest.raises(SpikeSimValueError, match="capture length.*199 readouts.*at least 200"):
        calibrate(spikes[:199], dark_mask=dark, flat_masks=flats)
    with pytest.raises(SpikeSimValueError, match="capture length.*150 readouts.*at least 200"):
        calibrate(spikes, dark_mask=dark, flat_masks=flats, max_readouts=150)
    with pytest.raises(SpikeSimValueError, match=r"dark_mask.shape=\(64, 32\)"):
        calibrate(spikes, dark_mask=dark[:, :32], flat_masks=flats)
    with pytest.raises(SpikeSimValueError, match=r"flat_masks\[1\].shape"):
        calibrate(spikes, dark_mask=dark, flat_masks=[flats[0], flats[1][:10]])
    with pytest.raises(SpikeSimTypeError, match="dark_mask"):
        calibrate(spikes, dark_mask=dark.astype(float), flat_masks=flats)
    with pytest.raises(SpikeSimValueError, match="dark_mask.*at least one pixel"):
        calibrate(spikes, dark_mask=np.zeros_like(dark), flat_masks=flats)
    with pytest.raises(SpikeSimValueError, match=r"flat_masks\[0\].*empty"):
        calibrate(spikes, dark_mask=dark, flat_masks=[np.zeros_like(dark)])
    with pytest.raises(SpikeSimValueError, match="disjoint"):
        calibrate(spikes, dark_mask=dark, flat_masks=[flats[0] | dark])
    with pytest.raises(SpikeSimValueError, match="flat_levels"):
        calibrate(spikes, dark_mask=dark, flat_masks=flats, flat_levels=(0.1, 0.2))
    # an all-saturated region: every pixel fires every readout
    sat = spikes.copy()
    sat[:, flats[2]] = 1
    with pytest.raises(SpikeSimValueError, match=r"flat_masks\[2\].*saturation"):
        calibrate(sat, dark_mask=dark, flat_masks=flats, check=False)
    # the same as a label image: the error names the label, not the position
    labels = np.zeros(dark.shape, np.int32)
    for k, f in zip((3, 7, 9), flats, strict=True):
        labels[f] = k
    with pytest.raises(SpikeSimValueError, match="flat_masks label 9.*saturation"):
        calibrate(sat, dark_mask=dark, flat_masks=labels, check=False)
    # a region too dark for this capture length (dark pixels: ~4 spikes in 1200 readouts)
    with pytest.raises(SpikeSimValueError, match=r"flat_masks\[0\].*at least 4 spikes per pixel"):
        calibrate(spikes, flat_masks=[dark], check=False)
    # nothing flat to find: calibrated without a flat region, and the notes say so
    noise = (np.random.default_rng(0).random((1200, 16, 16)) < np.linspace(
        0.01, 0.9, 16)[None, None, :]).astype(np.uint8)
    res = calibrate(noise, check=False, cfa="mono")
    assert res.data["regions"]["detected"] == "none" and not res.flat_masks
    assert any(n.startswith("no flat region found") for n in res.notes)
    assert res.data["status"]["prnu"].startswith("not identified")
    with pytest.raises(SpikeSimValueError, match="flat_levels.*no flat region was found"):
        calibrate(noise, check=False, cfa="mono", flat_levels=[0.5])


def _bands_capture(reset, n_readouts, dim=0.0, seed=3, dark_rows=0):
    """A 64 × 128 mono chip with a dark (or ``dim``: dark in its top ``dark_rows``
    rows, then 8 rows at 0.5 between dark and dim) band and flat bands at 0.1, 0.25
    and 0.5, non-default noise, ``reset`` mode: (stream, image)."""
    noise = ss.noise.PhysicalNoise(threshold_mismatch=0.07, prnu=0.09, dark_current_rel=0.012,
                                   electrons_per_threshold=300.0, fpn_seed=5)
    img = np.full((64, 128), dim, np.float32)
    if dark_rows:
        img[:dark_rows, :32] = 0.0
        img[dark_rows: dark_rows + 8, :32] = 0.5
    for k, level in enumerate((0.1, 0.25, 0.5), 1):
        img[:, 32 * k: 32 * k + 32] = level
    sensor = ss.Sensor(height=64, width=128, cfa=None, noise=noise, full_scale_rate=0.4,
                       reset=reset)
    return ss.simulate(ss.scenes.Static(img), sensor, n_readouts, seed=seed), img


def test_reset_mode_is_kept_and_zero_reset_refused():
    """The fitted sensor keeps the capture's reset mode (recorded, given or
    modulo with a note); a zero-reset capture, which the fit's model does not
    describe, is refused instead of fitted wrongly."""
    stream, img = _bands_capture("subtract", 300)
    masks = dict(dark_mask=img == 0, flat_masks=[img == v for v in (0.1, 0.25, 0.5)],
                 flat_levels=[0.1, 0.25, 0.5], check=False)
    assert calibrate(stream, **masks).sensor.reset == "subtract"
    unknown = calibrate(stream.unpack(), **masks)
    assert unknown.sensor.reset == "modulo"
    assert any("reset mode unknown" in n for n in unknown.notes)
    assert calibrate(stream.unpack(), reset="subtract", **masks).sensor.reset == "subtract"
    with pytest.raises(SpikeSimValueError, match="reset='modulo'.*capture's own reset mode "
                                                 "'subtract'"):
        calibrate(stream, reset="modulo", **masks)
    zero, _ = _bands_capture("zero", 300)
    with pytest.raises(SpikeSimValueError, match="reset mode.*'zero'.*no zero-reset form"):
        calibrate(zero, **masks)
    with pytest.raises(SpikeSimValueError, match="reset='zero'.*modulo' or 'subtract"):
        calibrate(zero.unpack(), reset="zero", **masks)


def test_detected_regions_too_dim_are_left_out():
    """Without masks, a detected flat region with fewer than 4 spikes per pixel
    is left out with a note (it used to abort the calibration); at the minimum
    capture length of 200 readouts a band of 8 spikes per pixel is fitted."""
    stream, _ = _bands_capture("modulo", 250, dim=0.02, dark_rows=24)  # 3 spikes per pixel
    res = calibrate(stream, check=False)
    assert len(res.flat_masks) == 3 and res.dark_mask.sum() > 400
    assert any("left out" in n and "fewer than the fit's 4" in n for n in res.notes)
    res = calibrate(_bands_capture("modulo", 300)[0].unpack()[:200], check=False)
    assert len(res.flat_masks) == 3  # 0.04 spikes per readout: 8 spikes per pixel
    assert not any("fewer than the fit's" in n for n in res.notes)


def test_dark_mask_alone_detects_the_flat_regions():
    stream, img = _bands_capture("modulo", 300)
    res = calibrate(stream, dark_mask=img == 0, check=False)
    assert np.array_equal(res.dark_mask, img == 0)
    assert len(res.flat_masks) == 3
    for found, level in zip(res.flat_masks, (0.1, 0.25, 0.5), strict=True):
        assert not np.any(found & (img != level))
    assert "regions dark region from dark_mask, flat regions detected" in res.notes[0]
    assert "reset_charge_loss) is not fitted and is held at 0" in res.notes[1]
    with pytest.raises(SpikeSimValueError, match="flat_masks.*detect=True"):
        calibrate(stream, dark_mask=img == 0, detect=False, check=False)


def test_mask_types_are_checked():
    stream, img = _bands_capture("modulo", 300)
    labels = np.select([img == v for v in (0.1, 0.25, 0.5)], [1, 2, 3], 0).astype(np.int32)
    with pytest.raises(SpikeSimValueError, match="dark_mask='integers from 0 to 3'.*boolean"):
        calibrate(stream, dark_mask=labels, check=False)
    with pytest.raises(SpikeSimTypeError, match="flat_masks must be an .H, W. integer label "
                                                "image .0 = none. or boolean"):
        calibrate(stream, flat_masks=labels.astype(float), check=False)
    res = calibrate(stream, dark_mask=(img == 0).astype(np.uint8), flat_masks=labels,
                    check=False)  # 0/1 integers are a mask
    assert res.dark_mask.sum() == 64 * 32


@pytest.mark.slow
def test_calibration_accuracy_all_settings():
    res = calibration_accuracy(seed=0)
    bad = [r for r in res.tables[0][2] if not r[-1]]
    assert res.data["all_within"] and not bad, bad
    assert len({r[0] for r in res.tables[0][2]}) == len(CALIBRATION_SETTINGS) >= 4
