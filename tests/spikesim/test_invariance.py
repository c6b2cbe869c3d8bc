"""Same bits whatever the chunk size or the number of threads."""

from __future__ import annotations

import numba
import numpy as np
import pytest

import spikesim as ss
from tests.support.core_helpers import Keyframes

NOISES = [
    None,
    ss.noise.PaperNoise(sigma_g=6.0, sigma_p=2.0),
    ss.noise.PhysicalNoise(hot_pixel_fraction=0.01),
]


def _scene():
    rng = np.random.default_rng(0)
    imgs = [rng.random((13, 70, 3)).astype(np.float32) * s for s in (0.5, 2.0, 0.1)]
    return Keyframes(np.array([0.0, 0.0217, 0.05]), imgs)


@pytest.mark.parametrize("noise", NOISES, ids=["ideal", "paper", "physical"])
def test_chunk_sizes_give_same_bits(noise):
    sensor = ss.Sensor(height=13, width=70, clock_hz=1000.0, noise=noise)
    scene = _scene()
    whole = ss.simulate(scene, sensor, 64, seed=4, clean_twin=True, chunk_readouts=64)
    for chunk in (1, 7):
        part = ss.simulate(scene, sensor, 64, seed=4, clean_twin=True, chunk_readouts=chunk)
        np.testing.assert_array_equal(part.packed, whole.packed)
        np.testing.assert_array_equal(part.clean_packed, whole.clean_packed)


def test_streaming_and_keeping_chunks_give_same_bits():
    """Output memory is recycled only once a consumer has dropped a chunk: a
    consumer that keeps every chunk and one that copies and drops each see
    the same bits (with the clean twin, whose arrays come from the same pool)."""
    sensor = ss.Sensor(height=13, width=70, clock_hz=1000.0,
                       noise=ss.noise.PaperNoise(sigma_g=6.0))
    kept = list(ss.simulate_chunks(_scene(), sensor, 64, seed=4, clean_twin=True,
                                   chunk_readouts=8))
    copied = []
    for chunk in ss.simulate_chunks(_scene(), sensor, 64, seed=4, clean_twin=True,
                                    chunk_readouts=8):
        copied.append((chunk.packed.copy(), chunk.clean_packed.copy()))
        del chunk
    arrays = [a for c in kept for a in (c.packed, c.clean_packed)]
    assert not any(np.shares_memory(a, b) for i, a in enumerate(arrays)
                   for b in arrays[i + 1:])  # nothing shared
    for k, (packed, clean) in zip(kept, copied, strict=True):
        np.testing.assert_array_equal(k.packed, packed)
        np.testing.assert_array_equal(k.clean_packed, clean)


@pytest.mark.parametrize("noise", NOISES, ids=["ideal", "paper", "physical"])
def test_thread_count_gives_same_bits(noise):
    """In one process: numba's thread count changes between runs, the bits do not."""
    most = numba.config.NUMBA_NUM_THREADS
    if most < 2:
        pytest.skip("one CPU thread available: nothing to vary")
    rng = np.random.default_rng(0)
    imgs = [rng.random((40, 130, 3)).astype(np.float32) * s for s in (0.5, 2.0)]
    scene = Keyframes(np.array([0.0, 0.03]), imgs)
    sensor = ss.Sensor(height=40, width=130, clock_hz=1000.0, noise=noise)
    before = numba.get_num_threads()
    outs = []
    try:
        for threads in sorted({1, 2, most}):
            numba.set_num_threads(threads)
            st = ss.simulate(scene, sensor, 50, seed=1, clean_twin=True)
            outs.append((threads, st.packed, st.clean_packed))
    finally:
        numba.set_num_threads(before)
    for threads, packed, clean in outs[1:]:
        np.testing.assert_array_equal(packed, outs[0][1], err_msg=f"{threads} threads")
        np.testing.assert_array_equal(clean, outs[0][2], err_msg=f"{threads} threads")


@pytest.mark.parametrize("name,motion", [("astronaut", "pan"), ("fan", None), ("coffee", "zoom")])
def test_procedural_scenes_are_chunk_invariant(name, motion):
    """Moving scenes' key frames lie on a global grid, so chunking cannot change the bits."""
    scene = ss.scenes.procedural(name, motion=motion, size=(24, 40), speed=3000)
    sensor = ss.Sensor(height=24, width=40, noise=ss.noise.PaperNoise(5.0, 1.0))
    whole = ss.simulate(scene, sensor, 200, seed=3, chunk_readouts=200).packed
    np.testing.assert_array_equal(ss.simulate(scene, sensor, 200, seed=3, chunk_readouts=7).packed,
                                  whole)
