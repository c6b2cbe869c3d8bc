"""Characterisation curves: exact on noise-free streams, moving as predicted with one source on.

Statistical tolerances are about 4 standard errors of the statistic (fixed seeds).
"""

from __future__ import annotations

import numpy as np
import pytest

import spikesim as ss
from spikesim.analysis import isi_statistics, snr_curve, theory, transfer_curve
from spikesim.errors import SpikeSimValueError


def only(**kw):
    base = dict(shot_noise=False, dark_current_rel=0.0, dark_current_spread=0.0,
                threshold_mismatch=0.0, prnu=0.0, temporal_threshold_noise=0.0,
                hot_pixel_fraction=0.0)
    base.update(kw)
    return ss.noise.PhysicalNoise(**base)


MONO = ss.Sensor(cfa=None)
LEVELS = (0.0, 0.02, 0.3, 0.7, 1.2, 2.0, 3.0)


@pytest.fixture(scope="module")
def clean_transfer():
    return transfer_curve(MONO, LEVELS, n_readouts=1000, size=(16, 16), window=50)


def test_transfer_noise_free_matches_theory(clean_transfer):
    d = clean_transfer.data
    r = MONO.full_scale_rate
    for level, m, ideal, fpn, tsd, tsd_th in zip(d["levels"], d["mean_rate"], d["ideal_rate"],
                                                 d["fpn_sd"], d["temporal_sd"],
                                                 d["temporal_sd_theory"], strict=True):
        assert ideal == min(r * level, 1.0)
        # count over N readouts is floor(a0 + N·q) − floor(a0): mean within 1/N of q
        assert abs(m - ideal) <= 1.0 / 1000 + 1e-12
        assert fpn <= 1.0 / 1000 + 1e-12  # per-pixel means differ by at most one count
        # window-count variance f(1−f), f = frac(50·q) (compare variances: f can be ~1e-6)
        v, vt = (tsd * 50) ** 2, (tsd_th * 50) ** 2
        assert abs(v - vt) <= 0.15 * vt + 0.01
    assert d["mean_rate"][-1] == 1.0 and d["mean_rate"][0] == 0.0


def test_transfer_prnu_raises_fixed_pattern_not_temporal(clean_transfer):
    prnu = 0.05
    res = transfer_curve(MONO.replace(noise=only(prnu=prnu)), (0.3, 0.7), n_readouts=1000,
                         size=(16, 16), window=50)
    for i, level in enumerate((0.3, 0.7)):
        j = LEVELS.index(level)
        # FPN ≈ r·I·prnu (256 pixels: sd of the sd ≈ 4.4 %)
        assert res.data["fpn_sd"][i] == pytest.approx(0.6 * level * prnu, rel=0.2)
        assert res.data["fpn_sd"][i] == pytest.approx(res.data["fpn_sd_theory"][i], rel=0.05)
        # no temporal noise is added: the window count stays within quantization
        # (sd ≤ 1/2 count); spreading q over pixels only spreads the phase f(1−f)
        assert res.data["temporal_sd"][i] <= 0.5 / 50
        assert res.data["temporal_sd"][i] == pytest.approx(
            res.data["temporal_sd_theory"][i], rel=0.1)
        assert clean_transfer.data["fpn_sd"][j] < res.data["fpn_sd"][i] / 10


def test_transfer_shot_noise_raises_temporal_as_predicted(clean_transfer):
    res = transfer_curve(MONO.replace(noise=only(shot_noise=True, electrons_per_threshold=20.0)),
                         (0.3, 0.7), n_readouts=2000, size=(16, 16), window=50)
    for i, level in enumerate((0.3, 0.7)):
        q = 0.6 * level
        assert res.data["temporal_sd"][i] > 2 * clean_transfer.data["temporal_sd"][
            LEVELS.index(level)]
        # Var(count_w) = w·q/E + E[f(1−f)]; 256 px × 40 windows → sd of sd ≈ 1 %
        assert res.data["temporal_sd"][i] == pytest.approx(res.data["temporal_sd_theory"][i],
                                                           rel=0.06)
        assert res.data["temporal_sd_theory"][i] > np.sqrt(50 * q / 20) / 50


def test_isi_noise_free_only_floor_and_ceil():
    res = isi_statistics(MONO, (0.05, 0.35, 0.8), n_readouts=2000, size=(8, 8))
    d = res.data
    assert d["clean_fraction"] == [1.0, 1.0, 1.0]
    for m, mt, v, vt in zip(d["mean"], d["mean_theory"], d["within_var"],
                            d["within_var_theory"], strict=True):
        assert m == pytest.approx(mt, rel=2e-3)
        assert abs(v - vt) < 0.02  # p(1−p), intervals take two values only


def test_isi_jitter_broadens_within_pixel_as_predicted():
    sig = 0.05
    res = isi_statistics(MONO.replace(noise=only(temporal_threshold_noise=sig)),
                         (0.02, 0.1, 0.35), n_readouts=4000, size=(8, 8))
    d = res.data
    assert d["kappa2"] == pytest.approx(sig**2)
    for v, vt, n in zip(d["within_var"], d["within_var_theory"],
                        [r[1] for r in res.tables[0][2]], strict=True):
        assert vt > 0.2  # above the noise-free p(1−p) ≤ 1/4 … or near it
        assert v == pytest.approx(vt, rel=4 * np.sqrt(2 / n) + 0.02)


def test_isi_and_tfi_theory_include_charge_noise_and_charge_loss():
    """Accumulating charge noise (σ_q²/q³ grows with the interval) and the charge loss
    at reset (mean 1/q + f) enter the ISI and TFI theory columns, which then follow
    the simulation as closely as for per-cycle noise; without them the theory of
    the dimmest level would be 15× too small (σ_e = 10 e⁻, E = 382)."""
    noise = only(shot_noise=True, electrons_per_threshold=382.0, charge_noise_electrons=10.0,
                 reset_charge_loss=0.05)
    res = isi_statistics(MONO.replace(noise=noise), (0.02, 0.1, 0.5), n_readouts=5000,
                         size=(8, 8))
    d = res.data
    assert d["sigma_q2"] == pytest.approx((10.0 / 382.0) ** 2)
    assert d["reset_charge_loss"] == 0.05
    for m, mt in zip(d["mean"], d["mean_theory"], strict=True):
        assert m == pytest.approx(mt, rel=0.01)
    counts = [r[1] for r in res.tables[0][2]]
    for v, vt, n in zip(d["within_var"], d["within_var_theory"], counts, strict=True):
        assert v == pytest.approx(vt, rel=4 * np.sqrt(2 / n) + 0.03)
    assert d["within_var_theory"][0] > 150  # σ_q²/q³ at q = 0.012: the dominant term
    snr = snr_curve(MONO.replace(noise=noise), (0.05, 0.3), (41,), n_readouts=3220,
                    size=(16, 16), tfi_stride=40).data
    for m, t in zip(snr["tfi_snr"], snr["tfi_snr_theory"], strict=True):
        assert m == pytest.approx(t, rel=0.08)


def test_paper_mode_theory_is_the_rectified_charge_and_its_random_walk():
    """Paper-mode noise (GN σ_g = 10): each readout's charge r·max(I + s·z, 0) is a
    rectified normal, whose mean exceeds r·I near the dark (a dark rate) and whose
    variance accumulates like a charge noise; the ISI, transfer and SNR theory follow
    the simulation (noise-free theory was 12× too small in the within-pixel variance
    at I = 0.1 and gave no dark rate)."""
    noise = ss.noise.PaperNoise(sigma_g=10.0)
    rng = np.random.default_rng(0)
    for level in (0.0, 0.02, 0.5):  # against Monte Carlo of the rectified charge
        s = 10.0 / 255.0
        draws = 0.6 * np.maximum(level + s * rng.standard_normal(1_000_000), 0.0)
        mean, var = theory.paper_charge(noise, 0.6, level)
        assert mean == pytest.approx(draws.mean(), rel=3e-3)
        assert var == pytest.approx(draws.var(), rel=3e-3)
    gn = MONO.replace(noise=noise, full_scale_rate=0.6)
    res = isi_statistics(gn, (0.02, 0.1, 0.5), n_readouts=3000, size=(16, 16))
    d, counts = res.data, [r[1] for r in res.tables[0][2]]
    assert d["kappa2"] == 0 and len(d["sigma_q2"]) == 3 and "Paper-mode noise" in res.notes[0]
    for m, mt in zip(d["mean"], d["mean_theory"], strict=True):
        assert m == pytest.approx(mt, rel=0.01)
    for v, vt, n in zip(d["within_var"], d["within_var_theory"], counts, strict=True):
        assert v == pytest.approx(vt, rel=4 * np.sqrt(2 / n) + 0.03)
    t = transfer_curve(gn, (0.0, 0.02, 0.5), n_readouts=2000, size=(32, 32), window=50).data
    assert t["model_rate"][0] == pytest.approx(0.6 * 10 / 255 / np.sqrt(2 * np.pi))
    for key, meas, rel in (("model_rate", "mean_rate", 0.02),
                           ("temporal_sd_theory", "temporal_sd", 0.08)):
        for a, b in zip(t[key], t[meas], strict=True):
            assert a == pytest.approx(b, rel=rel), key
    snr = snr_curve(gn, (0.0, 0.1), (41,), n_readouts=3220, size=(16, 16), tfi_stride=40)
    assert snr.data["dark"]["model_rate"] == pytest.approx(snr.data["dark"]["rate_per_readout"],
                                                           rel=0.03)
    for a, b in (("tfp_snr_w41", "tfp_snr_theory_w41"), ("tfi_snr", "tfi_snr_theory")):
        for m, th in zip(snr.data[a], snr.data[b], strict=True):
            assert m == pytest.approx(th, rel=0.08), a


def test_tfp_and_transfer_theory_include_the_charge_loss_and_stop_where_it_fails():
    """With a charge loss at reset the TFP SNR and transfer theory follow the renewal
    count (mean 1/q + f per cycle); with accumulating charge noise the theory is not
    given (NaN, '–' in the report) in the dark, where diffusion alone fires, nor near
    saturation; a saturated ISI level is named in a note."""
    lossy = MONO.replace(noise=only(shot_noise=True, electrons_per_threshold=400.0,
                                    reset_charge_loss=0.05))
    d = snr_curve(lossy, (0.2, 1.0), (11, 41), n_readouts=2000, size=(32, 32)).data
    for w in (11, 41):
        for m, t in zip(d[f"tfp_snr_w{w}"], d[f"tfp_snr_theory_w{w}"], strict=True):
            assert m == pytest.approx(t, rel=0.05)  # without f: 16 % off at I = 0.5
    walk = MONO.replace(noise=only(shot_noise=True, charge_noise_electrons=8.0,
                                   reset_charge_loss=0.05))
    t = transfer_curve(walk, (0.0, 0.5, 1.66), n_readouts=2000, size=(32, 32),
                       window=50).data
    assert t["mean_rate"][0] > 0 and np.isnan(t["model_rate"][0])  # diffusion fires
    assert t["model_rate"][1] == pytest.approx(t["mean_rate"][1], rel=0.01)
    assert t["temporal_sd"][1] == pytest.approx(t["temporal_sd_theory"][1], rel=0.06)
    for key in ("model_rate", "fpn_sd_theory", "temporal_sd_theory"):
        assert np.isnan(t[key][0]) and np.isnan(t[key][2]), key
    res = isi_statistics(MONO, (0.05, 2.0), n_readouts=500, size=(8, 8))
    assert list(res.data["levels"]) == [0.05] and "left out: [2.0]" in res.notes[-1]


def test_isi_fixed_pattern_broadens_pooled_not_within():
    res = isi_statistics(MONO.replace(noise=only(prnu=0.08)), (0.05,), n_readouts=4000,
                         size=(8, 8))
    d = res.data
    assert d["pooled_var"][0] > 5 * d["within_var"][0]
    assert d["pooled_var"][0] == pytest.approx(d["pooled_var_theory"][0], rel=0.1)
    assert d["within_var"][0] < 0.3


def test_isi_too_short_capture_raises():
    with pytest.raises(SpikeSimValueError, match="n_readouts"):
        isi_statistics(MONO, (0.01,), n_readouts=300, size=(4, 4))


def test_snr_noise_free_matches_theory_and_noise_lowers_it():
    levels = (0.0, 0.02, 0.2, 1.0)
    clean = snr_curve(MONO, levels, (11, 41), n_readouts=1640, size=(12, 12), tfi_stride=40)
    d = clean.data
    for w in (11, 41):
        for m, t in zip(d[f"tfp_snr_w{w}"][1:], d[f"tfp_snr_theory_w{w}"][1:], strict=True):
            assert m == pytest.approx(t, rel=0.1)
    assert d["dark"]["rate_per_readout"] == 0.0
    assert d["tfi_snr"][2] == pytest.approx(d["tfi_snr_theory"][2], rel=0.1)
    noisy = snr_curve(MONO.replace(noise=only(shot_noise=True, electrons_per_threshold=10.0,
                                              dark_current_rel=0.01)),
                      levels, (11, 41), n_readouts=1640, size=(12, 12), tfi_stride=40)
    n = noisy.data
    assert n["dark"]["rate_per_readout"] == pytest.approx(0.006, rel=0.1)
    assert n["dark"]["model_rate"] == pytest.approx(0.006)
    for i in (2, 3):
        assert n["tfp_snr_w41"][i] < d["tfp_snr_w41"][i]
        assert n["tfp_snr_w41"][i] == pytest.approx(n["tfp_snr_theory_w41"][i], rel=0.1)
    dr = d["dynamic_range"]
    # lowest radiance whose theoretical SNR (w = 41, no dark counts) reaches 1
    expected = min(lv for lv, t in zip(levels, d["tfp_snr_theory_w41"], strict=True)
                   if lv > 0 and t >= 1)
    assert dr["i_min"] == expected and dr["i_max"] == 1.0
    assert dr["db"] == pytest.approx(20 * np.log10(1.0 / expected))


def test_bad_sweep_inputs():
    with pytest.raises(SpikeSimValueError, match="levels"):
        transfer_curve(MONO, (0.1, -1.0))
    with pytest.raises(SpikeSimValueError, match="n_readouts"):
        transfer_curve(MONO, (0.1,), n_readouts=100, window=100)
    with pytest.raises(SpikeSimValueError, match="windows"):
        snr_curve(MONO, (0.1,), windows=(0,))


@pytest.mark.parametrize("call,match", [
    (lambda t: t.rate_theory(0.1, reset="foo"), "reset='foo'"),
    (lambda t: t.rate_theory(-0.1), r"q=-0.1.*>= 0"),
    (lambda t: t.rate_theory(np.nan), "finite"),
    (lambda t: t.rate_theory(0.1, loss=1.0), "loss=1.0.*fraction"),
    (lambda t: t.isi_mean_theory(-1.0), r"q=-1.0.*\(0, 1\]"),
    (lambda t: t.isi_mean_theory(0.0), r"q=0.0.*\(0, 1\]"),
    (lambda t: t.isi_cv2_theory(1.5, 0.001), r"q=1.5.*\(0, 1\]"),
    (lambda t: t.isi_var_theory(0.1, kappa2=-1.0), "kappa2"),
    (lambda t: t.isi_var_theory(0.1, sigma_q2=np.inf), "sigma_q2"),
    (lambda t: t.isi_clean_pmf(2.0), r"q=2.0"),
    (lambda t: t.count_variance(0.1, 0), "window"),
    (lambda t: t.isi_mean_theory("0.5"), "q='0.5'.*real numbers"),
    (lambda t: t.count_variance(0.3, 41, v1=-1), "v1"),
    (lambda t: t.frac_variance(0.3, -1), "sd"),
    (lambda t: t.isi_clean_pmf(np.array([0.3, 0.4])), "one charge per readout"),
    (lambda t: t.cycle_cv2("x"), "noise='x'"),
    (lambda t: t.reset_loss(0.3), "noise=0.3"),
    (lambda t: t.charge_variance_per_readout(0.3, None, -1), "full_scale_rate"),
])
def test_theory_functions_refuse_what_they_do_not_describe(call, match):
    from spikesim.analysis import theory

    with pytest.raises(SpikeSimValueError, match=match):
        call(theory)
