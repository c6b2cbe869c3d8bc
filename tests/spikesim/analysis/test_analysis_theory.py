"""Closed forms and streaming statistics of spikesim.analysis against independent references."""

from __future__ import annotations

import numpy as np
import pytest

from spikesim.analysis import theory
from spikesim.analysis.capture import as_capture, pixel_counts, pixel_intervals
from spikesim.errors import SpikeSimTypeError, SpikeSimValueError


def test_pixel_intervals_match_naive_diffs_across_blocks():
    rng = np.random.default_rng(0)
    spikes = (rng.random((2500, 3, 5)) < 0.07).astype(np.uint8)  # 3 blocks of 1024
    spikes[:, 0, 0] = 0  # a silent pixel
    spikes[1000:1100, 1, 1] = 1  # a burst crossing a block edge
    mom = pixel_intervals(as_capture(spikes), keep={"row2": np.eye(3, 5, dtype=bool)})
    naive = []
    for y in range(3):
        for x in range(5):
            t = np.flatnonzero(spikes[:, y, x])
            d = np.diff(t)
            assert mom.n[y, x] == d.size
            assert mom.s1[y, x] == d.sum() and mom.s2[y, x] == (d.astype(float) ** 2).sum()
            assert mom.first[y, x] == (t[0] if t.size else -1)
            if y == x:
                naive.append(d)
    assert sorted(mom.samples["row2"].tolist()) == sorted(np.concatenate(naive).tolist())
    assert (pixel_counts(as_capture(spikes)) == spikes.sum(axis=0)).all()


def test_frac_variance_matches_monte_carlo():
    rng = np.random.default_rng(1)
    for mean, sd in [(4.762, 0.238), (3.3, 0.05), (10.2, 2.0), (0.4, 0.0)]:
        x = mean + sd * rng.standard_normal(400_000)
        f = x - np.floor(x)
        mc = np.mean(f * (1 - f))
        assert abs(float(theory.frac_variance(mean, sd)) - mc) < 2e-3


def test_rate_theory_reset_modes():
    q = np.array([0.0, 0.3, 0.5, 0.25, 0.9, 1.0, 2.0])
    assert np.allclose(theory.rate_theory(q, "modulo"), np.minimum(q, 1))
    assert np.allclose(theory.rate_theory(q, "zero"), [0, 0.25, 0.5, 0.25, 0.5, 1, 1])


def test_isi_clean_pmf_mean_is_one_over_q():
    for q in (0.3, 0.07, 0.5, 0.85):
        pmf = theory.isi_clean_pmf(q)
        assert sum(pmf.values()) == pytest.approx(1)
        assert sum(k * p for k, p in pmf.items()) == pytest.approx(1 / q)


def test_capture_rejects_bad_arrays():
    with pytest.raises(SpikeSimValueError, match="capture.shape"):
        as_capture(np.zeros((4, 4), np.uint8))
    with pytest.raises(SpikeSimTypeError, match="dtype"):
        as_capture(np.zeros((4, 4, 4), np.float32))
    with pytest.raises(SpikeSimTypeError):
        as_capture(3.0)


def _clocked_clean(q, f, reset, n=20_000, a0=0.37):
    """Independent slow model: exact rationals are not needed, a float loop of
    the clocked pixel with charge loss f in the readout after each firing."""
    a, after, spikes = a0, False, []
    for _ in range(n):
        a += q * (1.0 - f) if after else q
        fire = a >= 1.0
        if fire:
            a = a - np.floor(a) if reset == "modulo" else (a - 1.0 if reset == "subtract" else 0.0)
        after = fire
        spikes.append(fire)
    return np.array(spikes)


@pytest.mark.parametrize("reset", ["modulo", "subtract", "zero"])
@pytest.mark.parametrize("q", [0.013, 0.21, 0.55, 0.93])
@pytest.mark.parametrize("f", [0.0, 0.002, 0.35])
def test_rate_and_mean_interval_with_charge_loss_match_a_slow_loop(q, f, reset):
    s = _clocked_clean(q, f, reset)
    n = s.size
    assert abs(s.sum() - n * theory.rate_theory(q, reset, f)) <= 2
    if reset != "zero":
        t = np.flatnonzero(s)
        assert abs(np.diff(t).mean() - theory.isi_mean_theory(q, f)) < 2.5 / (t.size - 1)
    if f == 0.0:
        np.testing.assert_allclose(theory.rate_theory(q, reset, f), theory.rate_theory(q, reset))
