"""Automatic regions next to moving content, the charge-noise misfit note, CLI option names.

The captures reproduce a user's report: 96 × 128 pixels, 400 readouts,
physical noise, mono, full_scale_rate 0.5; columns 0–63 hold static vertical
bands (dark, then radiance 0.1, 0.3 and 0.7, 16 columns each), columns
64–127 a crop of ``skimage.data.camera()`` (scaled to [0, 1]) sliding
horizontally at 2000 px/s (40 pixels over the capture).  Fixed seeds.
"""

from __future__ import annotations

import numpy as np
import pytest

import spikesim as ss
from spikesim.analysis import calibrate, theory
from spikesim.analysis.capture import IntervalMoments
from spikesim.analysis.regions import find_regions
from spikesim.analysis.temporal_fit import MIN_Z, fit_temporal
from spikesim.cli import main
from spikesim.errors import SpikeSimValueError
from spikesim.io import write_dat

H, W, N = 96, 128, 400
LEVELS = (0.0, 0.1, 0.3, 0.7)
RATE = 0.5  # full_scale_rate: spikes per readout at radiance 1
BANDS = [np.zeros((H, W), bool) for _ in LEVELS]
for _k, _band in enumerate(BANDS):
    _band[:, 16 * _k: 16 * _k + 16] = True


class BandsAndPicture(ss.scenes.Scene):
    """Static bands on the left, ``camera()[r0:r0 + H, c0:]`` sliding right to left."""

    def __init__(self, r0: int, c0: int, speed: float = 2000.0):
        from skimage import data

        self.height, self.width = H, W
        self.key_interval_s = 1.0 / speed  # one pixel of motion between key frames
        self.speed = speed
        self.picture = data.camera()[r0: r0 + H, c0:].astype(np.float64) / 255.0
        self.base = np.zeros((H, W), np.float32)
        for band, level in zip(BANDS, LEVELS, strict=True):
            self.base[band] = level

    def grey(self, t: float) -> np.ndarray:
        shift = self.speed * t
        i0, f = int(np.floor(shift)), shift - np.floor(shift)
        cols = np.arange(W // 2) + i0
        img = self.base.copy()
        img[:, W // 2:] = (1 - f) * self.picture[:, cols] + f * self.picture[:, cols + 1]
        return img

    def radiance(self, t: float) -> np.ndarray:
        return np.repeat(self.grey(t)[..., None], 3, axis=2)

    def describe(self) -> dict:
        return {"kind": "bands and a sliding camera() crop"}


def _capture(r0: int, c0: int):
    sensor = ss.Sensor(height=H, width=W, cfa=None, full_scale_rate=RATE,
                       noise=ss.noise.PhysicalNoise())
    return ss.simulate(BandsAndPicture(r0, c0), sensor, N, seed=0)


@pytest.fixture(scope="module")
def band_next_to_motion():
    """The picture's bright content next to the 0.7 band joins it in one candidate."""
    return _capture(100, 0)


@pytest.fixture(scope="module")
def dim_moving_content():
    """The picture's dark coat (radiance ≈ 0.02) slides in the right half."""
    return _capture(260, 0)


def _assert_bands_found(res):
    assert len(res.flat_masks) == 3
    for found, band in zip(res.flat_masks, BANDS[1:], strict=True):
        assert not np.any(found & ~band) and found.sum() > 0.5 * band.sum()
    assert not np.any(res.dark_mask & ~BANDS[0]) and res.dark_mask.sum() > 0.6 * BANDS[0].sum()


def test_static_band_next_to_moving_content_is_found(band_next_to_motion):
    """The 0.7 band touches moving content of similar rates: their joint
    candidate fails the tests, its uniform, static part (the band) is kept and
    the rest is named in a note (it used to vanish without one)."""
    res = calibrate(band_next_to_motion, check=False)
    _assert_bands_found(res)
    # radiances unknown: the brightest band (0.7) is full scale
    assert res.sensor.full_scale_rate == pytest.approx(RATE * 0.7, rel=0.03)
    left_out = [n for n in res.notes if "candidate region of" in n and "was left out" in n]
    assert any("columns 51-" in n and "part of it" in n and "kept as a flat region" in n
               for n in left_out), left_out
    known = calibrate(band_next_to_motion, flat_levels=LEVELS[1:], check=False)
    assert known.sensor.full_scale_rate == pytest.approx(RATE, rel=0.03)


def test_dim_moving_content_does_not_count_as_dark(dim_moving_content):
    """Dim content of the moving half (rate ≈ 0.01, below ``dark_rate``) is not
    dark: four times the dark band's rate.  It is tested as a flat region and
    left out with a note (its moving texture gives it twice the bands' response
    spread); the dark rate is the dark band's."""
    res = calibrate(dim_moving_content, check=False)
    _assert_bands_found(res)
    true_dark = RATE * ss.noise.PhysicalNoise().dark_current_rel
    assert res.data["diagnostics"]["dark_rate"] == pytest.approx(true_dark, rel=0.15)
    assert not res.data["diagnostics"]["charge_noise_fitted"]  # no charge noise in the truth
    import re

    left = [re.search(r"columns (\d+)-", n) for n in res.notes
            if n.startswith("left out as moving or textured content") and "median rate" in n]
    assert left and all(m and int(m[1]) >= W // 2 for m in left), res.notes  # the moving half


def _halves(lam1, lam2, n=N, seed=0):
    """Synthetic per-half Poisson counts: (rate, (2, H, W) half rates), spikes per readout."""
    rng = np.random.default_rng(seed)
    c1, c2 = rng.poisson(lam1 * n / 2), rng.poisson(lam2 * n / 2)
    return (c1 + c2) / n, np.stack([c1, c2]) / (n / 2)


def _dark_split(right_first, right_second):
    """(H, W) rates, per half, of a dark left part, a static flat gap and the given right part."""
    lam1 = np.full((H, W), 0.005)
    lam1[:, 56:72] = 0.3
    lam2 = lam1.copy()
    lam1[:, 72:], lam2[:, 72:] = right_first, right_second
    return _halves(lam1, lam2)


def test_moving_dim_candidate_is_not_dark():
    """The motion test applies to dark candidates: dim content whose counts
    change together between the halves is left out of the dark mask, with its
    reason."""
    x, y = np.meshgrid(np.arange(W - 72), np.arange(H))
    wave = 0.004 * np.sin(2 * np.pi * x / 24) * np.cos(2 * np.pi * y / 32)
    rate, halves = _dark_split(0.005 + wave, 0.005 - wave)
    found = find_regions(rate, N, halves=halves)
    assert found.dark is not None and not found.dark[:, 72:].any()
    assert found.dark[:, :56].sum() > 0.7 * H * 56
    moving = [d for d in found.dropped if d.kind == "dark"]
    assert len(moving) == 1 and moving[0].reason.startswith("not static")
    assert "is not dark" in moving[0].describe() and "columns 7" in moving[0].describe()


def test_static_dim_candidate_is_not_dark():
    """A static region four times brighter than the darkest one, though below
    ``dark_rate``, is dim light: a flat candidate, not dark current."""
    rate, halves = _dark_split(0.02, 0.02)
    found = find_regions(rate, N, halves=halves)
    assert found.dark is not None and not found.dark[:, 56:].any()
    assert any(f[:, 72:].sum() > 0.7 * f.sum() for f in found.flats)


def test_a_ramp_still_gives_no_flat_region():
    """The split of rejected candidates finds no uniform part in a ramp."""
    rng = np.random.default_rng(1)
    q = np.linspace(0.02, 0.6, 256)[None, :] * np.ones((96, 1))
    c1, c2 = rng.binomial(1000, q), rng.binomial(1000, q)
    found = find_regions((c1 + c2) / 2000, 2000, halves=np.stack([c1, c2]) / 1000)
    assert found.flats == [] and found.dark is None
    assert [d.reason.split(" (")[0] for d in found.dropped] == ["not uniform"]


def _moments(cv2):
    """IntervalMoments of 500 pixels, mean intervals ``m`` = 5–25 readouts, 100
    intervals each, of variance ``cv2(m)·m²`` plus the clock's rounding term."""
    m = np.repeat(np.linspace(5.0, 25.0, 20), 25).reshape(20, 25)
    n = np.full(m.shape, 100)
    s1 = n * m
    var = cv2(m) * m**2 + theory.frac_variance(m, np.sqrt(cv2(m)) * m)
    s2 = var * (n - 1) + s1**2 / n
    return IntervalMoments(n, s1, s2, np.zeros(m.shape, int), np.zeros(m.shape, int), {})


def test_significantly_negative_charge_noise_is_a_misfit():
    """A CV² that falls with the interval length is many standard errors below
    the model (whose CV² can only grow): the note says misfit, not 'not
    significant', and σ_q² stays 0."""
    mom = _moments(lambda m: 0.05 * (1 - (m - 5) / 40))
    fit = fit_temporal(mom, np.ones(mom.n.shape, bool))
    assert fit.sigma_q2 == 0.0 and not fit.charge_noise_fitted
    assert fit.sigma_q2_estimate < -MIN_Z * fit.sigma_q2_se
    assert "falls with the interval length" in fit.reason and "model misfit" in fit.reason
    assert "standard errors below 0" in fit.reason and "not significant" not in fit.reason
    flat = fit_temporal(_moments(lambda m: 0.05 + 0 * m), np.ones(mom.n.shape, bool))
    assert "not significant" in flat.reason


def test_cli_names_its_options_in_errors(band_next_to_motion, tmp_path, capsys):
    """--levels with the wrong count names --levels, not the API's flat_levels."""
    write_dat(tmp_path / "cap.dat", band_next_to_motion.unpack())
    np.save(tmp_path / "flats.npy", np.stack(BANDS[1:]))
    code = main(["analyze", "calibrate", str(tmp_path / "cap.dat"), "--height", str(H),
                 "--width", str(W), "--flat-masks", str(tmp_path / "flats.npy"), "--levels",
                 "0.1,0.3", "--no-check", "--no-progress", "--out", str(tmp_path / "cal")])
    err = capsys.readouterr().err
    assert code != 0 and "--levels=[0.1, 0.3] is invalid: expected 3 finite radiances" in err
    assert "flat_levels" not in err
    with pytest.raises(SpikeSimValueError, match="flat_levels=.0.1, 0.3. is invalid"):
        calibrate(band_next_to_motion, flat_masks=BANDS[1:], flat_levels=[0.1, 0.3],
                  check=False)
    with pytest.raises(SpikeSimValueError, match="--reset='subtract' is invalid.*leave --reset"):
        calibrate(band_next_to_motion, reset="subtract", check=False,
                  option_names={"reset": "--reset"})
