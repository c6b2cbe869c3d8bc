"""Quantization against the ideal reference, and the per-source noise budget."""

from __future__ import annotations

import numpy as np
import pytest

import spikesim as ss
from spikesim.analysis import noise_budget, noise_sources, quantization_study, saturation_recovery
from spikesim.analysis.budget import make_reconstructor, psnr
from spikesim.errors import SpikeSimValueError

MONO = ss.Sensor(cfa=None)


def test_quantization_noise_free():
    res = quantization_study(MONO, (0.1, 0.5, 1.2, 2.5), n_readouts=820, size=(8, 8), window=41)
    d = res.data
    assert d["agreement"] == [1.0] * 4  # clocked bits = ideal crossings mapped to readouts
    for lost, th in zip(d["lost_per_readout"], d["lost_theory"], strict=True):
        assert lost == pytest.approx(th, abs=2e-3)  # crossings beyond one per readout
    for m, s in zip(d["timing_mean"], d["timing_sd"], strict=True):
        assert abs(m - 0.5) < 0.03 and abs(s - 1 / np.sqrt(12)) < 0.02
    for i in range(3):  # below saturation: TFP unbiased, rms = tfp_std theory
        assert abs(d["tfp_bias"][i]) < 1e-3
        assert d["tfp_rms"][i] == pytest.approx(d["tfp_rms_theory"][i], rel=0.05)
    assert d["tfp_bias"][3] == pytest.approx(1 / 0.6 - 2.5, abs=1e-3)  # saturated
    for m in ("modulo", "subtract", "zero"):
        assert d["reset_rates"][m] == pytest.approx(d["reset_rates_theory"][m], abs=2e-3)
    assert d["reset_rates"]["zero"][1] == pytest.approx(1 / 4, abs=2e-3)  # q = 0.3 → 1/⌈3.33⌉


def test_subtract_reset_recovery_hard_case():
    sub = saturation_recovery(MONO.replace(reset="subtract"), 2.0, 0.2, n_readouts=600)
    # N1 (q1 − 1)/(1 − q2) = 300·0.2/0.88 readouts of continuous firing after the step
    assert sub["run_theory"] == pytest.approx(300 * 0.2 / 0.88, rel=1e-6)
    assert abs(sub["run_mean"] - sub["run_theory"]) <= 2
    mod = saturation_recovery(MONO, 2.0, 0.2, n_readouts=600)
    assert mod["run_mean"] < 0.5


def test_quantization_rejects_per_readout_noise():
    with pytest.raises(SpikeSimValueError, match="sensor.noise"):
        quantization_study(ss.Sensor.preset("sjdd-gn"), (0.5,))


def _budget(seed=3, **kw):
    noise = ss.noise.PhysicalNoise(electrons_per_threshold=30.0, temporal_threshold_noise=0.05,
                                   prnu=0.1, hot_pixel_fraction=0.0)
    sensor = ss.Sensor(cfa=None, noise=noise)
    scene = ss.scenes.procedural("ramp", size=(16, 32), low=0.1, high=0.9)
    return noise_budget(scene, sensor, n_readouts=200, seed=seed, n_centers=3, **kw)


def test_budget_reproducible_and_sums():
    a, b = _budget(), _budget()
    assert a.data["costs"] == b.data["costs"] and a.data["mse"] == b.data["mse"]
    c = _budget(seed=4)
    assert c.data["mse"] != a.data["mse"]
    d = a.data
    assert set(d["costs"]) == {"shot noise", "dark current", "threshold mismatch", "PRNU",
                               "temporal threshold noise"}
    assert d["psnr_none"] > d["psnr_all"]
    assert d["total_cost_db"] == pytest.approx(d["psnr_none"] - d["psnr_all"])
    shares = sum(v["share"] for v in d["costs"].values())
    # excess MSE is additive up to the stated interaction term
    assert shares + d["interaction_mse"] / d["total_excess_mse"] == pytest.approx(1.0)
    assert abs(d["interaction_mse"]) < 0.25 * d["total_excess_mse"]
    assert d["costs"]["PRNU"]["cost_db"] > 0.5  # the dominant source here
    assert d["costs"]["PRNU"]["cost_db"] > d["costs"]["dark current"]["cost_db"]


def test_budget_callable_method_and_errors():
    calls = []

    def mean_rate(spikes, cfa, center, rate):
        calls.append(center)
        return spikes[center - 10: center + 11].mean(axis=0) / rate

    res = _budget(method=mean_rate)
    assert res.data["method"] == "mean_rate" and len(calls) == 3 * 7  # 6 runs + clean twin

    def no_rate(spikes, cfa, center):  # spikejdd's protocol: rate is optional
        return spikes[center - 10: center + 11].mean(axis=0) / 0.6

    assert _budget(method=no_rate).data["method"] == "no_rate"
    with pytest.raises(SpikeSimValueError, match="noise"):
        noise_budget("flat", ss.Sensor(cfa=None), n_readouts=100, size=(8, 8))
    assert noise_sources(ss.noise.PaperNoise(sigma_g=3.0)) == {"gaussian (sigma_g)":
                                                               {"sigma_g": 0.0}}
    assert psnr(np.full((2, 2), 0.5), np.full((2, 2), 0.6)) == pytest.approx(20.0)


def test_budget_finds_methods_through_the_entry_point_group(monkeypatch):
    """spikesim imports no reconstruction package: names resolve through entry points
    (spikejdd's is declared in setup.cfg and installed with it)."""
    from importlib import metadata

    import spikesim.analysis.budget as budget

    offered = {"ep": metadata.EntryPoint("spikejdd", "spikejdd.registry:reconstructor",
                                         budget.RECONSTRUCTOR_GROUP)}
    real = metadata.entry_points
    monkeypatch.setattr(metadata, "entry_points", lambda group=None, **kw: (
        list(offered.values()) if group == budget.RECONSTRUCTOR_GROUP else real(group=group,
                                                                                **kw)))
    res = _budget(method="tfp+bilinear")
    assert res.data["method"] == "tfp+bilinear" and np.isfinite(res.data["psnr_all"])
    with pytest.raises(SpikeSimValueError, match="spikejdd: .*no-such-method"):
        make_reconstructor("no-such-method")
    offered.clear()
    with pytest.raises(SpikeSimValueError, match="no reconstruction package"):
        make_reconstructor("tfp+bilinear")


def test_spikejdd_declares_its_reconstructor_entry_point():
    import configparser
    from pathlib import Path

    cfg = configparser.ConfigParser()
    cfg.read(Path(__file__).parents[3] / "setup.cfg")
    group = cfg["options.entry_points"]["spikesim.reconstructors"]
    assert "spikejdd = spikejdd.registry:reconstructor" in group
