"""The kernel equals the independent NumPy float64 reference bit for bit.

The reference accumulates in float64, the kernel in exact fixed point; they can
only differ when the charge lands within ~1e-15 θ of the threshold, which
random inputs of this size never do (the tests would show it).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import spikesim as ss
from spikesim.reference import reference_simulate
from tests.support.core_helpers import Keyframes

CFAS = ["RGGB", "BGGR", "GRBG", "GBRG", None]
RESETS = ["modulo", "subtract", "zero"]


def _scene(rng, h, w, n_keys, clock, n_readouts, bright):
    imgs = [(rng.random((h, w, 3)) * bright).astype(np.float32) for _ in range(n_keys)]
    if n_keys == 1:
        return ss.scenes.Static(imgs[0])
    # arbitrary (non-integer) readout times, some inside one readout period
    t = np.sort(rng.uniform(-2, n_readouts + 2, n_keys))
    t = np.unique(np.round(t, 3))
    if len(t) < n_keys:
        t = np.arange(n_keys) * 3.3 + 0.25
    return Keyframes(t / clock, imgs[: len(t)])


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    h=st.integers(1, 7),
    w=st.integers(1, 80),
    n_keys=st.integers(1, 5),
    cfa=st.sampled_from(CFAS),
    reset=st.sampled_from(RESETS),
    init=st.sampled_from(["uniform", "zero"]),
    bright=st.sampled_from([0.3, 1.0, 3.0]),
    sigma=st.sampled_from([(0.0, 0.0), (8.0, 0.0), (2.0, 3.0)]),
    seed=st.integers(0, 2**32),
    chunk=st.integers(1, 40),
)
def test_random_cases_match_reference(h, w, n_keys, cfa, reset, init, bright, sigma, seed, chunk):
    rng = np.random.default_rng(seed)
    clock = 1000.0
    n = 30
    noise = ss.noise.PaperNoise(*sigma) if sigma != (0.0, 0.0) else None
    sensor = ss.Sensor(height=h, width=w, cfa=cfa, clock_hz=clock, reset=reset, init=init,
                       noise=noise)
    scene = _scene(rng, h, w, n_keys, clock, n, bright)
    got = ss.simulate(scene, sensor, n, seed=seed, chunk_readouts=chunk).packed
    np.testing.assert_array_equal(got, reference_simulate(scene, sensor, n, seed=seed))


@pytest.mark.parametrize("reset", RESETS)
@pytest.mark.parametrize("cfa", CFAS)
def test_every_reset_and_cfa_with_fixed_patterns(reset, cfa):
    rng = np.random.default_rng(3)
    noise = ss.noise.PhysicalNoise(shot_noise=False, temporal_threshold_noise=0.0,
                                   hot_pixel_fraction=0.05)
    sensor = ss.Sensor(height=6, width=21, cfa=cfa, clock_hz=500.0, reset=reset, noise=noise)
    scene = _scene(rng, 6, 21, 3, 500.0, 50, 2.0)
    got = ss.simulate(scene, sensor, 50, seed=9, chunk_readouts=17).packed
    np.testing.assert_array_equal(got, reference_simulate(scene, sensor, 50, seed=9))


@pytest.mark.parametrize("sigma", [(10.0, 0.0), (2.5, 2.5)])
@pytest.mark.parametrize("n_keys", [1, 4])
def test_paper_noise_fast_and_general_blocks_match_reference(sigma, n_keys):
    """Paper-mode noise has a vector fast path for blocks whose noisy charge is
    provably below one threshold, and the general step otherwise.  The left
    two 64-pixel blocks here are dark enough for the fast path, the right
    ones are not; every block must equal the reference bit for bit."""
    from spikesim.rng import NORMAL_ABS_MAX

    h, w, clock, n = 5, 250, 1000.0, 60
    rng = np.random.default_rng(11)
    imgs = []
    for _ in range(n_keys):
        img = rng.random((h, w, 3)) * 0.4
        img[:, 128:] += 1.2  # bright half: the bound fails there
        imgs.append(img.astype(np.float32))
    sensor = ss.Sensor(height=h, width=w, cfa="RGGB", clock_hz=clock,
                       noise=ss.noise.PaperNoise(*sigma))
    sd_top = np.sqrt(sigma[0] ** 2 + sigma[1] ** 2 * 255 * 0.4) / 255
    assert sensor.full_scale_rate * (0.4 + sd_top * NORMAL_ABS_MAX) < 1.0  # dark half fits
    assert sensor.full_scale_rate * 1.2 >= 0.7  # bright half can reach 1 θ with noise
    scene = (ss.scenes.Static(imgs[0]) if n_keys == 1
             else Keyframes(np.array([0.0, 17.3, 31.0, 52.6]) / clock, imgs))
    got = ss.simulate(scene, sensor, n, seed=4, chunk_readouts=23).packed
    np.testing.assert_array_equal(got, reference_simulate(scene, sensor, n, seed=4))


@pytest.mark.parametrize("reset", RESETS)
def test_temporal_threshold_noise_matches_reference(reset):
    """Comparator jitter (physical mode): after each firing the next threshold is
    θ(1 + ε); the kernel applies it in fixed point to the lanes that fired."""
    rng = np.random.default_rng(5)
    noise = ss.noise.PhysicalNoise(shot_noise=False, temporal_threshold_noise=0.05)
    sensor = ss.Sensor(height=5, width=150, cfa="RGGB", clock_hz=500.0, reset=reset,
                       noise=noise)
    scene = _scene(rng, 5, 150, 3, 500.0, 60, 1.5)
    got = ss.simulate(scene, sensor, 60, seed=2, chunk_readouts=13).packed
    np.testing.assert_array_equal(got, reference_simulate(scene, sensor, 60, seed=2))
    quiet = ss.Sensor(height=5, width=150, cfa="RGGB", clock_hz=500.0, reset=reset,
                      noise=ss.noise.PhysicalNoise(shot_noise=False,
                                                   temporal_threshold_noise=0.0))
    assert not np.array_equal(got, ss.simulate(scene, quiet, 60, seed=2).packed)



@pytest.mark.parametrize("reset", RESETS)
@pytest.mark.parametrize("fixed_pattern", [False, True], ids=["ideal", "fixed-pattern"])
@pytest.mark.parametrize("kind", ["static", "after the last key"])
def test_holds_match_reference_where_blocks_fall_back(reset, fixed_pattern, kind):
    """A chunk of one hold (a static scene's, or any after the last key frame)
    runs a noise-free block without the general block function when its
    charges are below 1 θ and its whole part is 0.  Here one block's charges
    reach 3 θ, another's in one lane; after the last key the light drops below
    1 θ everywhere while subtract still holds the bright readouts' backlog.
    Chunks of 1, 7, 140 and all readouts (zero reset counts runs of 128
    readouts and more down, ``spikesim._zero_period``), and the clean twin of
    a physical stream, which runs the same holds after the noisy stream's
    block with the same work rows (the noisy bits must not change)."""
    rng = np.random.default_rng(11)
    h, w, n, clock = 5, 200, 150, 1000.0
    img = rng.random((h, w, 3)) * 0.9
    bright = img.copy()
    bright[:, :64] *= 3.4  # block 0: charges up to ~3 θ
    bright[2, 100] = 2.5  # block 1: one bright lane
    if kind == "static":
        scene = ss.scenes.Static(bright.astype(np.float32))
    else:  # bright until readout 5, dim after
        scene = Keyframes(np.array([0.0, 5.0]) / clock,
                          [bright.astype(np.float32), img.astype(np.float32)])
    noise = (ss.noise.PhysicalNoise(shot_noise=False, temporal_threshold_noise=0.0,
                                    hot_pixel_fraction=0.02) if fixed_pattern else None)
    sensor = ss.Sensor(height=h, width=w, cfa="RGGB", clock_hz=clock, reset=reset, noise=noise)
    want = reference_simulate(scene, sensor, n, seed=5)
    noisy = ss.Sensor(height=h, width=w, cfa="RGGB", clock_hz=clock, reset=reset,
                      noise=ss.noise.PhysicalNoise())  # shot noise per spike
    for chunk in (1, 7, 140, n):
        got = ss.simulate(scene, sensor, n, seed=5, chunk_readouts=chunk).packed
        np.testing.assert_array_equal(got, want)
        if not fixed_pattern:  # the twin shares the noisy stream's work rows
            twin = ss.simulate(scene, noisy, n, seed=5, chunk_readouts=chunk, clean_twin=True)
            np.testing.assert_array_equal(twin.clean_packed, want)
            alone = ss.simulate(scene, noisy, n, seed=5, chunk_readouts=chunk).packed
            np.testing.assert_array_equal(twin.packed, alone)
    assert ss.bits.unpack(want, w)[:, :, 64:].mean() < 0.9  # the dim blocks do not saturate
