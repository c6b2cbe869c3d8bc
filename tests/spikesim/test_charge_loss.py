"""Charge loss at reset (``PhysicalNoise.reset_charge_loss`` f): the readout
after each firing collects (1 − f) of its charge.  Checked bit for bit against
the NumPy reference on the per-readout path and against the rate and interval
theory of ``spikesim.analysis.theory``."""

from __future__ import annotations

import numpy as np
import pytest

import spikesim as ss
from spikesim.analysis import theory
from spikesim.errors import SpikeSimValueError
from spikesim.reference import reference_simulate
from tests.support.core_helpers import Keyframes, counts, flat_rows

W = 512


def _only_loss(f, **kw):
    base = dict(shot_noise=False, dark_current_rel=0.0, dark_current_spread=0.0,
                threshold_mismatch=0.0, prnu=0.0, temporal_threshold_noise=0.0,
                hot_pixel_fraction=0.0, reset_charge_loss=f)
    base.update(kw)
    return ss.noise.PhysicalNoise(**base)


@pytest.mark.parametrize("reset", ["modulo", "subtract", "zero"])
def test_charge_loss_on_the_per_readout_path_matches_reference(reset):
    """Without shot noise (comparator jitter, fixed patterns, moving scene)."""
    rng = np.random.default_rng(3)
    noise = ss.noise.PhysicalNoise(shot_noise=False, temporal_threshold_noise=0.03,
                                   reset_charge_loss=0.2)
    sensor = ss.Sensor(height=3, width=100, cfa="GRBG", clock_hz=500.0, reset=reset,
                       noise=noise)
    imgs = [(rng.random((3, 100, 3)) * 2.0).astype(np.float32) for _ in range(2)]
    scene = Keyframes(np.array([3.25, 51.5]) / 500.0, imgs)
    got = ss.simulate(scene, sensor, 60, seed=2, chunk_readouts=9).packed
    np.testing.assert_array_equal(got, reference_simulate(scene, sensor, 60, seed=2))
    lossless = sensor.replace(noise=noise.replace(reset_charge_loss=0.0))
    assert not np.array_equal(got, ss.simulate(scene, lossless, 60, seed=2).packed)


@pytest.mark.parametrize("reset", ["modulo", "subtract", "zero"])
def test_noise_free_rate_with_charge_loss(reset):
    """Rate q/(1 + f·q) (modulo, subtract) or 1/⌈1/q + f⌉ (zero): counts over n
    readouts within 2 of n·rate (phase and the cycle in progress)."""
    f = 0.3
    levels = [0.05, 0.3, 0.9, 1.5]  # q = 0.03 … 0.9
    sensor = ss.Sensor(height=len(levels), width=64, cfa=None, reset=reset, noise=_only_loss(f))
    n = 4000
    c = counts(ss.scenes.Static(flat_rows(levels, 64)), sensor, n, seed=1)
    for row, level in enumerate(levels):
        q = 0.6 * float(np.float32(level))
        want = n * theory.rate_theory(q, reset, f)
        assert np.all(np.abs(c[row] - want) <= 2), (reset, q, c[row].min(), c[row].max(), want)
        if f * q > 0.01 and reset != "zero":  # distinguishable from the lossless rate
            assert abs(c[row].mean() - n * min(q, 1.0)) > 5


def test_intervals_with_shot_noise_and_charge_loss_follow_theory():
    """Event-driven shot noise, modulo: interval mean 1/q + f, variance
    κ²/q² + E[frac(τ)(1 − frac(τ))] with E[τ] = 1/q + f (the loss shifts,
    does not spread); the per-readout sampler agrees."""
    e, f = 300.5, 0.4
    noise = _only_loss(f, shot_noise=True, electrons_per_threshold=e)
    k2 = theory.cycle_cv2(noise)
    levels = [0.1, 0.6]
    w, n = 2048, 2500
    sensor = ss.Sensor(height=len(levels), width=w, cfa=None, noise=noise)
    spikes = ss.simulate(ss.scenes.Static(flat_rows(levels, w)), sensor, n, seed=5).unpack()
    for row, level in enumerate(levels):
        q = 0.6 * float(np.float32(level))
        isi = []
        for x in range(w):
            t = np.flatnonzero(spikes[:, row, x])
            isi.append(t[5] - t[4])
        isi = np.array(isi, np.float64)
        v = theory.isi_var_theory(q, k2, 0.0, f)
        mean_t = theory.isi_mean_theory(q, f)
        assert mean_t == pytest.approx(1 / q + f)
        assert abs(isi.mean() - mean_t) < 4 * np.sqrt(v / w), (q, isi.mean(), mean_t)
        assert abs(isi.var(ddof=1) / v - 1) < 5 * np.sqrt(2 / (w - 1)), (q, isi.var(), v)
    cv2 = theory.isi_cv2_theory(np.array([0.06, 0.36]), k2, 0.0, f)
    np.testing.assert_allclose(cv2, k2 * (1 / (1 + f * np.array([0.06, 0.36]))) ** 2)


def test_charge_loss_cannot_make_the_cv_grow_like_charge_noise():
    """SCSim's 0.998 retention (f = 0.002) at intervals of 17 and 38 readouts:
    the cycle CV changes by ≤ f/m ≈ 1.2e-4 relative; charge noise of 30 e⁻ per readout
    (E = 1000) raises it with the interval length."""
    k2 = 1 / 1000 + 0.006**2
    q = np.array([1 / 17, 1 / 38])
    with_loss = np.sqrt(theory.isi_cv2_theory(q, k2, 0.0, 0.002))
    assert np.all(np.abs(with_loss / np.sqrt(k2) - 1) < 1.2e-4)  # f/m = 1.18e-4 at m = 17
    charge = np.sqrt(theory.isi_cv2_theory(q, k2, (30 / 1000) ** 2))
    assert charge[1] > 1.3 * charge[0]


def test_charge_loss_is_off_by_default_validated_and_serialised():
    assert ss.noise.PhysicalNoise().reset_charge_loss == 0.0
    assert _only_loss(0.1).per_readout and not _only_loss(0.0).per_readout
    for bad in (-0.1, 1.0, float("nan"), "0.1", None):
        with pytest.raises(SpikeSimValueError, match="reset_charge_loss"):
            ss.noise.PhysicalNoise(reset_charge_loss=bad)
    d = _only_loss(0.002).to_dict()
    assert ss.noise.noise_from_dict(d).reset_charge_loss == 0.002
    old = {k: v for k, v in d.items() if k != "reset_charge_loss"}  # files from before
    assert ss.noise.noise_from_dict(old).reset_charge_loss == 0.0


def test_ideal_reference_rejects_charge_loss():
    sensor = ss.Sensor(height=2, width=8, cfa=None, noise=_only_loss(0.1))
    with pytest.raises(SpikeSimValueError, match="reset_charge_loss"):
        ss.ideal_spike_times(ss.scenes.Static(np.full((2, 8), 0.5, np.float32)), sensor, 10)


def test_the_model_doc_example_agrees_with_its_theory(capsys):
    """docs/model.md's charge-loss example prints 1/rate next to 1/q + f: they agree."""
    from tests.docs.test_code_blocks import ROOT, parse_blocks

    blocks = parse_blocks((ROOT / "docs" / "model.md").read_text(encoding="utf-8"))
    block = next(b for b in blocks if "isi_mean_theory" in b.code)
    exec(compile(block.code, "docs/model.md", "exec"), {"__name__": "__doc_example__"})
    simulated, predicted = map(float, capsys.readouterr().out.split()[-2:])
    assert simulated == pytest.approx(predicted, rel=2e-3)
