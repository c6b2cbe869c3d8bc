"""Noise-free counts equal the integrate-and-fire theory exactly (docs/model.md)."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

import spikesim as ss
from tests.support.core_helpers import counts, flat_rows, initial_fraction

# ~20 intensities: 0, 1, values where r·I is an exact binary fraction, and generic ones.
LEVELS = [0.0, 1.0, 0.5, 0.25, 0.125, 0.0625, 0.75, 0.375, 1 / 3, 0.1, 0.2, 0.3, 0.45, 0.6,
          0.7, 0.9, 0.999, 1e-3, 1e-5, 0.8125]


def theory_counts(levels_f32, rate, a0_fixed, n):
    """floor(A0/θ + N·r·I) in exact rational arithmetic.

    r·I is the float64 product (the charge the sensor integrates); A0 is the
    exact initial accumulator (a multiple of 2**-64 θ).
    """
    out = np.zeros(a0_fixed.shape, np.int64)
    for y in range(a0_fixed.shape[0]):
        q = Fraction(float(rate) * float(levels_f32[y]))
        for x in range(a0_fixed.shape[1]):
            a0 = Fraction(int(a0_fixed[y, x]), 2**64)
            out[y, x] = int(a0 + n * q) // 1
    return out


@pytest.mark.parametrize("rate", [0.6, 0.5])
@pytest.mark.parametrize("init", ["uniform", "zero"])
def test_counts_equal_theory(rate, init):
    width, n = 24, 3000
    img = flat_rows(LEVELS, width)
    sensor = ss.Sensor(height=len(LEVELS), width=width, cfa=None, full_scale_rate=rate,
                       init=init)
    # monochrome sees luminance; equal channels give the level back exactly in float32
    got = counts(ss.scenes.Static(img), sensor, n, seed=11, chunk=700)
    lum = ss.cfa.mosaic(img, None)[:, 0]
    want = theory_counts(lum.astype(np.float32), rate, initial_fraction(sensor, 11), n)
    np.testing.assert_array_equal(got, want)


def test_no_drift_over_a_million_readouts():
    width, n = 16, 1_000_000
    img = flat_rows(LEVELS, width)
    sensor = ss.Sensor(height=len(LEVELS), width=width, cfa=None, full_scale_rate=0.6)
    got = counts(ss.scenes.Static(img), sensor, n, seed=5, chunk=65536)
    lum = ss.cfa.mosaic(img, None)[:, 0].astype(np.float32)
    want = theory_counts(lum, 0.6, initial_fraction(sensor, 5), n)
    np.testing.assert_array_equal(got, want)
    # float64 arithmetic (the formula as written) agrees away from integer boundaries
    a0 = initial_fraction(sensor, 5).astype(np.float64) * 2.0**-64
    approx = a0 + n * 0.6 * lum.astype(np.float64)[:, None]
    safe = np.abs(approx - np.round(approx)) > 1e-6
    np.testing.assert_array_equal(got[safe], np.floor(approx[safe]).astype(np.int64))


def test_exact_fraction_lands_on_boundaries():
    """r·I = 1/4 from zero charge fires exactly every 4th readout (≥ comparison)."""
    sensor = ss.Sensor(height=1, width=8, cfa=None, full_scale_rate=0.5, init="zero")
    st = ss.simulate(ss.scenes.Static(np.full((1, 8), 0.5, np.float32)), sensor, 16)
    spikes = st.unpack()[:, 0, 0]
    np.testing.assert_array_equal(np.flatnonzero(spikes), [3, 7, 11, 15])
