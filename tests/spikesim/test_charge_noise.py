"""Accumulating charge noise (physical mode): a Gaussian charge of σ_e electrons
added to every readout.  Checked bit for bit against the NumPy reference and
against the interval and count theory of ``spikesim.analysis.theory``: its
interval CV² grows with the interval length (κ² + σ_q²·m), unlike per-cycle noise."""

from __future__ import annotations

import numpy as np
import pytest

import spikesim as ss
from spikesim.analysis import theory
from spikesim.errors import SpikeSimValueError
from spikesim.reference import reference_simulate
from tests.support.core_helpers import Keyframes, counts, flat_rows

W = 256


def _only_charge(sigma_e, e=1000.0, **kw):
    base = dict(electrons_per_threshold=e, shot_noise=False, dark_current_rel=0.0,
                dark_current_spread=0.0, threshold_mismatch=0.0, prnu=0.0,
                temporal_threshold_noise=0.0, hot_pixel_fraction=0.0,
                charge_noise_electrons=sigma_e)
    base.update(kw)
    return ss.noise.PhysicalNoise(**base)


@pytest.mark.parametrize("reset", ["modulo", "subtract", "zero"])
def test_charge_noise_matches_reference(reset):
    """With fixed patterns, comparator jitter and a moving scene, in every reset mode."""
    rng = np.random.default_rng(11)
    noise = ss.noise.PhysicalNoise(shot_noise=False, temporal_threshold_noise=0.02,
                                   charge_noise_electrons=40.0)
    sensor = ss.Sensor(height=4, width=130, cfa="RGGB", clock_hz=500.0, reset=reset,
                       noise=noise)
    imgs = [(rng.random((4, 130, 3)) * 1.3).astype(np.float32) for _ in range(3)]
    scene = Keyframes(np.array([0.0, 17.25, 41.5]) / 500.0, imgs)
    got = ss.simulate(scene, sensor, 70, seed=3, chunk_readouts=11).packed
    np.testing.assert_array_equal(got, reference_simulate(scene, sensor, 70, seed=3))
    quiet = sensor.replace(noise=noise.replace(charge_noise_electrons=0.0))
    assert not np.array_equal(got, ss.simulate(scene, quiet, 70, seed=3).packed)


def _isis(spikes):
    """Inter-spike intervals of every pixel (readouts), pooled."""
    out = []
    for x in range(spikes.shape[1]):
        t = np.flatnonzero(spikes[:, x])
        out.append(np.diff(t[1:]))  # the first interval starts at the random initial phase
    return np.concatenate(out)


def test_interval_variance_and_cv_grow_with_interval_length():
    """Var(ISI) = κ² m² + σ_q² m³ + E[frac(τ)(1 − frac(τ))] per rate; the CV²
    of the cycle rises linearly with m = 1/q (per-cycle noise alone keeps it flat)."""
    sigma_e, e = 40.0, 1000.0
    sq2 = (sigma_e / e) ** 2
    noise = _only_charge(sigma_e, e)
    assert theory.charge_noise_var(noise) == pytest.approx(sq2)
    levels = [0.05 / 0.6, 0.1 / 0.6, 0.25 / 0.6]  # q = 0.05, 0.1, 0.25
    sensor = ss.Sensor(height=len(levels), width=W, cfa=None, noise=noise)
    n = 6000
    st = ss.simulate(ss.scenes.Static(flat_rows(levels, W)), sensor, n, seed=8)
    spikes = st.unpack()
    cv2 = []
    for row, level in enumerate(levels):
        q = 0.6 * float(np.float32(level))
        isi = _isis(spikes[:, row, :]).astype(np.float64)
        var_t = theory.isi_var_theory(q, 0.0, sq2)
        se = np.sqrt(np.mean((isi - isi.mean()) ** 4) - isi.var() ** 2) / np.sqrt(isi.size)
        assert abs(isi.mean() - 1 / q) < 5 * np.sqrt(isi.var() / isi.size) + 0.01
        assert abs(isi.var() - var_t) < 5 * se + 0.02 * var_t, (q, isi.var(), var_t)
        cv2.append(theory.isi_cv2_theory(q, 0.0, sq2))
    assert cv2[0] > 4 * cv2[2]  # m = 20 against m = 4: five times the CV²
    assert np.allclose(theory.isi_cv2_theory([0.05, 0.25], 0.01, 0.0), 0.01)


def test_count_variance_adds_sigma_squared_per_readout():
    """Var(count over N) = N·σ_q² + E[frac(X)(1 − frac(X))] whatever the charge."""
    noise = _only_charge(30.0)
    sensor = ss.Sensor(height=1, width=W, cfa=None, noise=noise)
    n = 3000
    c = counts(ss.scenes.Static(flat_rows([0.5], W)), sensor, n, seed=9)
    q = 0.6 * 0.5
    v1 = theory.charge_variance_per_readout(q, noise, 0.6)
    assert v1 == pytest.approx(0.03**2)
    var_theory = theory.count_variance(q, n, v1)
    assert abs(c.mean() - n * q) < 4 * np.sqrt(var_theory / W)
    assert abs(c.var(ddof=1) / var_theory - 1) < 4 * np.sqrt(2 / (W - 1))


def test_charge_noise_is_off_by_default_and_validated():
    assert ss.noise.PhysicalNoise().charge_noise_electrons == 0.0
    assert not _only_charge(0.0).per_readout and _only_charge(5.0).per_readout
    with pytest.raises(SpikeSimValueError, match="charge_noise_electrons"):
        ss.noise.PhysicalNoise(charge_noise_electrons=-1.0)
    d = _only_charge(7.0).to_dict()
    assert ss.noise.noise_from_dict(d).charge_noise_electrons == 7.0
