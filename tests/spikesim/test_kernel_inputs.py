"""The kernel's typed inputs: one numba type per bundle, whatever the noise."""

import sys

import numba
import numpy as np
import pytest

import spikesim as ss
from spikesim import _kernels
from spikesim.schedule import build_schedule
from spikesim.simulate import _kernel_inputs, _unused_inputs

NOISES = [None, ss.noise.PaperNoise(sigma_g=10.0), ss.noise.PaperNoise(sigma_g=2.0, sigma_p=3.0),
          ss.noise.PhysicalNoise(), ss.noise.PhysicalNoise(charge_noise_electrons=2.0),
          ss.noise.PhysicalNoise(reset_charge_loss=0.01, threshold_mismatch=0.0, prnu=0.0,
                                 dark_current_rel=0.0)]


@pytest.mark.parametrize("reset", ["modulo", "subtract", "zero"])
def test_every_noise_model_encodes_to_the_same_kernel_types(reset):
    """A noise model changes values, never types: the kernel compiles once for
    every model, for the clean twin and for its placeholder."""
    models, states = set(), set()
    for noise in NOISES:
        sensor = ss.Sensor(height=3, width=70, cfa="RGGB", noise=noise, reset=reset)
        for event in (True, False):
            model, state = _kernel_inputs(sensor, 7, noise, event)
            assert isinstance(model, _kernels.PixelModel)
            models.add(numba.typeof(model))
            states.add(numba.typeof(state))
    model, state = _unused_inputs()
    models.add(numba.typeof(model))
    states.add(numba.typeof(state))
    assert len(models) == 1 and len(states) == 1


def test_physical_model_keeps_its_parameters_and_keys():
    noise = ss.noise.PhysicalNoise(temporal_threshold_noise=0.03, reset_charge_loss=0.002)
    sensor = ss.Sensor(height=2, width=5, cfa=None, noise=noise, reset="zero")
    model, state = _kernel_inputs(sensor, 11, noise)
    assert model.reset == _kernels.RESET_ZERO
    assert model.jitter == 0.03 and model.loss == 0.002
    assert not model.fast_ok  # charge loss acts per readout
    assert model.key_shot == ss.rng.stream_key(11, ss.rng.STREAM_SHOT)
    assert state.frac.shape == (2, 64) and state.aux.shape == (4, 2, 64)


def test_schedule_is_a_run_schedule_of_fixed_dtypes():
    runs = build_schedule(np.array([0.0, 2.5, 7.0]), 0, 10)
    assert isinstance(runs, _kernels.RunSchedule)
    assert runs.kind.dtype == np.int8 and runs.start.dtype == np.int64
    assert runs.start[0] == 0 and runs.stop[-1] == 10
    # readout 2 contains key time 2.5: its own run, two pieces
    pieces = [r for r in range(len(runs.kind)) if runs.kind[r] == _kernels.RUN_PIECES]
    assert [int(runs.start[r]) for r in pieces] == [2]
    assert runs.p1[pieces[0]] - runs.p0[pieces[0]] == 2


def test_array_pool_reuses_by_shape_and_dtype_within_its_budget():
    from spikesim._memory import ArrayPool

    pool = ArrayPool(max_bytes=3 << 20, min_bytes=1 << 10)
    a = pool.take((1024, 128), np.float64)  # 1 MiB, fresh
    pool.give(a)
    assert pool.take((1024, 128), np.int64) is not a  # other dtype: fresh
    assert pool.take((1024, 128), np.float64) is a
    pool.give(np.ones(4))  # too small to keep
    assert pool.take((4,), np.float64, zeros=True).sum() == 0
    arrays = [np.empty((1024, 128)) for _ in range(4)]
    pool.give(*arrays)  # 4 MiB over a 3 MiB budget: the oldest is dropped
    kept = [pool.take((1024, 128), np.float64) for _ in range(4)]
    assert [any(k is a for a in arrays[1:]) for k in kept] == [True, True, True, False]


@pytest.mark.parametrize("noise", [None, ss.noise.PhysicalNoise(reset_charge_loss=0.01)])
def test_pooled_memory_from_earlier_runs_changes_no_bit(noise):
    """Runs take their state from a pool of earlier runs' arrays: poisoned state
    arrays and a reused key buffer (width 70: padding lanes) give the bits of a
    run on fresh memory."""
    sim = sys.modules["spikesim.simulate"]
    rng = np.random.default_rng(5)
    scene = ss.scenes.Static(rng.random((9, 70, 3)).astype(np.float32))
    sensor = ss.Sensor(height=9, width=70, cfa="RGGB", noise=noise, reset="subtract")
    pools = (sim._STATE_POOL, sim._KEY_POOL)
    for pool in pools:
        pool.clear()
        pool.min_bytes = 0  # keep this test's small arrays
    try:
        fresh = ss.simulate(scene, sensor, 50, seed=2, clean_twin=True).unpack()
        keys = sim._KEY_POOL.take((9, 2, 1, 64), np.float32)  # the run's, given back
        assert keys[:, 1, 0, :6].all() and not keys[:, 1, 0, 6:].any()  # x = 64..69, padding
        sim._KEY_POOL.give(keys)
        sim._STATE_POOL.clear()
        for dtype in (np.uint64, np.int64):
            for _ in range(2):
                sim._STATE_POOL.give(np.full((9, 128), 0x7F, dtype))
        sim._STATE_POOL.give(np.full((4, 9, 128), 3.0))
        again = ss.simulate(scene, sensor, 50, seed=2, clean_twin=True)
        third = ss.simulate(scene, sensor, 50, seed=2, clean_twin=True)
    finally:
        for pool in pools:
            pool.min_bytes = 1 << 16
            pool.clear()
    np.testing.assert_array_equal(again.unpack(), fresh)
    np.testing.assert_array_equal(third.unpack(), fresh)


def test_fixed_pattern_is_drawn_once_per_chip_and_size():
    sim = sys.modules["spikesim.simulate"]
    sim._PATTERNS.clear()
    noise = ss.noise.PhysicalNoise()
    first = sim._charge_constants(noise, 6, 70, 0.6)
    assert sim._charge_constants(ss.noise.PhysicalNoise(), 6, 70, 0.6) is first
    other = sim._charge_constants(noise.replace(prnu=0.05), 6, 70, 0.6)
    assert other is not first and not np.array_equal(other[0], first[0])
    assert sim._charge_constants(noise, 6, 71, 0.6) is not first
    assert len(sim._PATTERNS) == 2  # the oldest of three is dropped
    sim._PATTERNS.clear()
    rebuilt = sim._charge_constants(noise, 6, 70, 0.6)
    for a, b in zip(first, rebuilt, strict=True):
        np.testing.assert_array_equal(a, b)


def test_chunks_a_consumer_keeps_are_never_reused_by_later_runs():
    sim = sys.modules["spikesim.simulate"]
    scene = ss.scenes.Static(np.random.default_rng(1).random((8, 64, 3)).astype(np.float32))
    sensor = ss.Sensor(height=8, width=64, cfa="RGGB", noise=ss.noise.PaperNoise(sigma_g=5.0))
    sim._OUTPUT_POOL.min_bytes = 0
    try:
        kept = list(ss.simulate_chunks(scene, sensor, 40, seed=1, chunk_readouts=10))
        copies = [c.packed.copy() for c in kept]
        for seed in (2, 3):  # later runs of the same size whose chunks are dropped
            for chunk in ss.simulate_chunks(scene, sensor, 40, seed=seed, chunk_readouts=10):
                chunk = None
        assert len(sim._OUTPUT_POOL._free) > 0  # the dropped chunks were recycled
        for chunk, copy in zip(kept, copies, strict=True):
            np.testing.assert_array_equal(chunk.packed, copy)
        again = ss.simulate(scene, sensor, 40, seed=1, chunk_readouts=10).packed
        np.testing.assert_array_equal(again, np.concatenate(copies))
    finally:
        sim._OUTPUT_POOL.min_bytes = 1 << 16
        sim._OUTPUT_POOL.clear()


def _rows_of(n):
    f = _kernels._aligned_rows(n, np.float64)
    u = _kernels._aligned_rows(n + 1, np.uint64)
    f[:] = 1.5
    u[:] = 7
    return f.ctypes.data % 64, u.ctypes.data % 64, f, u


def test_work_rows_start_on_a_cache_line():
    """The block's work rows are (n, 64) C-contiguous lanes starting at a
    multiple of 64 bytes, so every 8-lane part of a row is one cache line,
    whatever address the allocator gave (numpy aligns to 16 or 32 bytes only)."""
    rows = _kernels._work_rows(5)
    assert all(r.ctypes.data % 64 == 0 for r in rows[:3]) and rows[-1].shape == (5,)
    assert (rows[2] == 0.0).all()  # the event state starts at zero
    for n in range(1, 40):
        f_off, u_off, f, u = _rows_of(n)
        assert (f_off, u_off) == (0, 0)
        assert f.shape == (n, 64) and u.shape == (n + 1, 64)
        assert f.flags.c_contiguous and u.flags.c_contiguous
        assert (f == 1.5).all() and (u == 7).all()
