"""Clocked readout = ideal asynchronous firing times rounded up to the next readout."""

from __future__ import annotations

import numpy as np
import pytest

import spikesim as ss
from tests.support.core_helpers import Keyframes


@pytest.mark.parametrize("cfa", ["RGGB", None])
def test_clocked_equals_ideal_rounded_up(cfa):
    rng = np.random.default_rng(8)
    imgs = [rng.random((9, 33, 3)).astype(np.float32) * s for s in (0.3, 1.0, 0.05, 0.8)]
    scene = Keyframes(np.array([0.0, 0.0313, 0.0705, 0.1]), imgs)  # non-integer readout times
    sensor = ss.Sensor(height=9, width=33, cfa=cfa, clock_hz=1000.0)
    n = 120
    st = ss.simulate(scene, sensor, n, seed=12)
    ideal = ss.ideal_spike_times(scene, sensor, n, seed=12)
    np.testing.assert_array_equal(st.unpack(), ideal.clocked(n))


def test_ideal_counts_exceed_clocked_only_when_saturating():
    """Quantization: the clock collapses several firings of one period into one bit."""
    sensor = ss.Sensor(height=1, width=8, cfa=None, clock_hz=1000.0)
    scene = ss.scenes.Static(np.full((1, 8), 3.0, np.float32))  # r·I = 1.8 per readout
    ideal = ss.ideal_spike_times(scene, sensor, 100, seed=0)
    assert np.all(ideal.count >= 179)
    assert ss.simulate(scene, sensor, 100).unpack().sum(axis=0).max() == 100


def test_ideal_rejects_per_readout_noise():
    sensor = ss.Sensor.preset("sjdd-gn", height=4, width=4)
    with pytest.raises(ValueError, match="sensor.noise"):
        ss.ideal_spike_times(ss.scenes.Static(np.ones((4, 4))), sensor, 10)
