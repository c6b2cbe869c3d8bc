"""Saturating light (r·I ≥ 1): one spike per readout at most, bounded or growing state."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

import spikesim as ss
from tests.support.core_helpers import Keyframes, initial_fraction

CLOCK = 1000.0


def _bright_then_dark(level, n_bright, width=16, height=1):
    """Radiance `level` until readout n_bright, dark from readout n_bright + 1 on."""
    bright = np.full((height, width), level, np.float32)
    dark = np.zeros((height, width), np.float32)
    return Keyframes(np.array([n_bright, n_bright + 1]) / CLOCK, [bright, dark])


@pytest.mark.parametrize("reset", ["modulo", "zero", "subtract"])
@pytest.mark.parametrize("level", [1.7, 2.0, 1e3, 1e6])
def test_every_readout_fires_under_saturation(reset, level):
    sensor = ss.Sensor(height=1, width=16, cfa=None, reset=reset, clock_hz=CLOCK)
    st = ss.simulate(ss.scenes.Static(np.full((1, 16), level, np.float32)), sensor, 300)
    assert st.unpack().all()


@pytest.mark.parametrize("reset", ["modulo", "zero"])
@pytest.mark.parametrize("level", [2.0, 1e6])
def test_bounded_modes_stop_when_light_stops(reset, level):
    """The accumulator stays below θ: after the light goes out nothing more fires."""
    sensor = ss.Sensor(height=1, width=16, cfa=None, reset=reset, clock_hz=CLOCK)
    st = ss.simulate(_bright_then_dark(level, 100), sensor, 400, seed=2)
    spikes = st.unpack()[:, 0, :]
    assert spikes[:100].all()
    assert not spikes[102:].any()


def test_subtract_mode_backlog_grows_as_documented():
    """Subtract mode: after N saturated readouts the accumulator holds A0 + N·(q − 1)
    thresholds, paid back one spike per readout once the light is gone."""
    level, n_bright, n = 10.0, 100, 900
    sensor = ss.Sensor(height=1, width=16, cfa=None, reset="subtract", clock_hz=CLOCK)
    st = ss.simulate(_bright_then_dark(level, n_bright), sensor, n, seed=3)
    spikes = st.unpack()[:, 0, :]
    # charges as the sensor integrates them (float64), then exact rational bookkeeping
    i_bright = float(np.float32(level))
    ramp = Fraction(0.6 * (i_bright + (0.0 - i_bright) * 0.5))  # the readout [N, N+1)
    charges = [Fraction(0.6 * i_bright)] * n_bright + [ramp]
    charges += [Fraction(0)] * (n - n_bright - 1)
    a0 = initial_fraction(sensor, 3)[0]
    for x in range(16):
        acc = Fraction(int(a0[x]), 2**64)
        want = []
        for n_i, q in enumerate(charges):
            acc += q
            fire = acc >= 1
            want.append(int(fire))
            if fire:
                acc -= 1
            if n_i == n_bright - 1:
                # documented growth: A0 + N (q - 1)
                assert acc == Fraction(int(a0[x]), 2**64) + n_bright * (charges[0] - 1)
        np.testing.assert_array_equal(spikes[:, x], want)
    # the backlog (~500 readouts) keeps firing long after the light went out
    assert spikes[n_bright + 1 : n_bright + 400].all()
    assert not spikes[-100:].any()


_EXTREME = [  # (radiance, full_scale_rate): charges of 6e16, 6e29 and 1e19 thresholds, and ∞
    (1e17, 0.6), (1e30, 0.6), (1.0, 1e19), (3e38, 1e300)]
_NOISES = {"none": None, "paper": ss.noise.PaperNoise(sigma_g=10.0, sigma_p=2.0),
           "physical": ss.noise.PhysicalNoise()}


@pytest.mark.parametrize("noise", sorted(_NOISES))
@pytest.mark.parametrize("reset", ["modulo", "zero", "subtract"])
@pytest.mark.parametrize("level, rate", _EXTREME)
def test_unrepresentable_charges_saturate(level, rate, reset, noise):
    """Charges of ≥ 2⁶³ thresholds per readout (and infinite ones) fire at every
    readout; after the light goes out the bounded modes stop, subtract keeps
    paying back its (bounded) backlog."""
    sensor = ss.Sensor(height=2, width=70, cfa=None, reset=reset, clock_hz=CLOCK,
                       full_scale_rate=rate, noise=_NOISES[noise])
    scene = _bright_then_dark(level, 200, width=70, height=2)
    st = ss.simulate(scene, sensor, 400, seed=5, chunk_readouts=64)
    spikes = st.unpack()
    assert spikes[:200].all()
    if reset == "subtract":
        assert spikes[201:].all()
    elif noise == "none":  # noise fires a dark pixel now and then
        assert not spikes[202:].any()


def test_subtract_backlog_saturates_without_overflow():
    """Subtract reset at radiance 1e17 for 1000 readouts: the backlog would be
    6e19 thresholds (> 2⁶³); it stops at WHOLE_MAX, every readout fires."""
    from spikesim import _kernels

    sensor = ss.Sensor(height=1, width=64, cfa=None, reset="subtract", clock_hz=CLOCK)
    st = ss.simulate(ss.scenes.Static(np.full((1, 64), 1e17, np.float32)), sensor, 1000)
    assert st.unpack().all()
    q = 0.6 * float(np.float32(1e17))
    assert 1000 * q > 2**63 > _kernels.WHOLE_MAX + _kernels.Q_WHOLE_MAX + 1


@pytest.mark.parametrize("level", [1e39, 1e300, float(np.finfo(np.float64).max)])
def test_float64_radiance_beyond_float32_saturates(level):
    """A finite float64 radiance beyond float32's range is stored as float32's
    largest value (no overflow warning, no 'contains inf' error) and fires at
    every readout like any saturating input."""
    import warnings

    from spikesim.scenes.static import FLOAT32_MAX, validate_radiance

    image = np.full((2, 70), level)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        checked = validate_radiance(image)
        st = ss.simulate(ss.scenes.Static(image), ss.Sensor(height=2, width=70, cfa=None),
                         40, seed=1)
    assert checked.dtype == np.float32 and (checked == np.float32(FLOAT32_MAX)).all()
    assert st.unpack().all()
    with pytest.raises(ss.errors.SpikeSimValueError, match="contains inf"):
        validate_radiance(np.full((2, 70), np.inf))
