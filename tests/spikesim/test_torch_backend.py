"""The torch backend gives the numba kernel's bits (docs/torch.md).

The acceptance grid of issue 51 — (RGGB, mono) × (modulo, subtract, zero) ×
(no noise, GN σ = 10, GPN σ_g = σ_p = 2.5) × (moving procedural, static),
72 × 104, 300 readouts, one seed — through ``simulate(..., backend="torch")``
on CPU tensors against the numba kernel; then the pieces each case leans on
(the random numbers, the square root, chunking, the clean twin, saturation),
the batch simulator, and the errors.  CUDA tests are marked ``gpu``.
"""

from __future__ import annotations

import sys

import numpy as np
import pytest

import spikesim as ss
from spikesim.errors import SpikeSimValueError

torch = pytest.importorskip("torch")

H, W, N, SEED = 72, 104, 300, 11
NOISES = {"off": None, "GN10": ss.noise.PaperNoise(10.0, 0.0),
          "GPN2.5": ss.noise.PaperNoise(2.5, 2.5)}


def _static_image(h: int, w: int) -> np.ndarray:
    """Random radiance with a bright band (charges above one threshold: the
    whole part, subtract's backlog and the general step all take part)."""
    img = np.random.default_rng(5).random((h, w, 3)).astype(np.float32)
    img[:, : w // 3] *= 2.5
    return img


@pytest.fixture(scope="module")
def scenes():
    return {"moving": ss.scenes.procedural("astronaut", motion="pan", size=(H, W), speed=1500.0),
            "static": ss.scenes.Static(_static_image(H, W))}


@pytest.mark.parametrize("scene_name", ["moving", "static"])
@pytest.mark.parametrize("noise", list(NOISES))
@pytest.mark.parametrize("reset", ["modulo", "subtract", "zero"])
@pytest.mark.parametrize("cfa", ["RGGB", None], ids=["RGGB", "mono"])
def test_same_bits_as_numba(scenes, cfa, reset, noise, scene_name):
    scene = scenes[scene_name]
    sensor = ss.Sensor(height=H, width=W, cfa=cfa, reset=reset, noise=NOISES[noise])
    want = ss.simulate(scene, sensor, N, seed=SEED)
    got = ss.simulate(scene, sensor, N, seed=SEED, backend="torch", device="cpu")
    assert 0.05 < want.unpack().mean() < 0.95  # a stream with spikes and silences
    np.testing.assert_array_equal(got.packed, want.packed)
    np.testing.assert_array_equal(got.gt, want.gt)
    np.testing.assert_array_equal(got.gt_index, want.gt_index)
    assert got.meta == want.meta


@pytest.mark.parametrize("chunk", [1, 7, 64])
def test_chunks_clean_twin_and_ground_truth(scenes, chunk):
    sensor = ss.Sensor(height=H, width=W, cfa="GRBG", reset="subtract",
                       noise=ss.noise.PaperNoise(4.0, 1.5))
    kw = dict(seed=3, clean_twin=True, gt_readouts=[0, 50, 119])
    want = ss.simulate(scenes["moving"], sensor, 120, **kw)
    run = ss.simulate_chunks(scenes["moving"], sensor, 120, chunk_readouts=chunk,
                             backend="torch", device="cpu", **kw)
    chunks = list(run)
    assert len(chunks) == -(-120 // chunk)
    np.testing.assert_array_equal(np.concatenate([c.packed for c in chunks]), want.packed)
    np.testing.assert_array_equal(np.concatenate([c.clean_packed for c in chunks]),
                                  want.clean_packed)
    np.testing.assert_array_equal(np.concatenate([c.gt for c in chunks]), want.gt)
    assert not np.array_equal(want.packed, want.clean_packed)


@pytest.mark.parametrize("cfa", ["BGGR", "GBRG"])
@pytest.mark.parametrize("init", ["uniform", "zero"])
def test_other_patterns_odd_sizes_grey_scenes_and_zero_init(cfa, init):
    rng = np.random.default_rng(2)
    h, w = 5, 37  # W not a multiple of 8
    grey = ss.scenes.Static((rng.random((h, w)) * 1.8).astype(np.float32))
    frames = [(rng.random((h, w, 3)) * 1.4).astype(np.float32) for _ in range(4)]
    keys = ss.scenes.Keyframes(np.array([0.0, 3.25, 3.75, 40.0]) / 1000.0, frames)
    for scene in (grey, keys):
        for c in (cfa, None):
            sensor = ss.Sensor(height=h, width=w, cfa=c, clock_hz=1000.0, init=init,
                               reset="zero", noise=ss.noise.PaperNoise(3.0, 2.0))
            want = ss.simulate(scene, sensor, 60, seed=9, chunk_readouts=25)
            got = ss.simulate(scene, sensor, 60, seed=9, chunk_readouts=25, backend="torch",
                              device="cpu")
            np.testing.assert_array_equal(got.packed, want.packed)
            np.testing.assert_array_equal(got.gt, want.gt)


@pytest.mark.parametrize("reset", ["modulo", "subtract", "zero"])
def test_saturating_light(reset):
    """Charges far above one threshold, up to float32's largest radiance: the
    whole part saturates at Q_WHOLE_MAX and subtract's backlog grows; the bits
    and the pixels still firing after the light goes are the numba kernel's."""
    img = np.zeros((2, 16, 3), np.float32)
    img[0, :4] = [[3.0] * 3, [1e6] * 3, [1e30] * 3, [3.4e38] * 3]
    img[1] = 1.7
    scene = ss.scenes.Keyframes(np.array([0.0, 20.0, 21.0]) / 1000.0,
                                [img, img, np.zeros_like(img)])
    sensor = ss.Sensor(height=2, width=16, cfa=None, clock_hz=1000.0, reset=reset)
    want = ss.simulate(scene, sensor, 80, seed=1, chunk_readouts=30)
    got = ss.simulate(scene, sensor, 80, seed=1, chunk_readouts=30, backend="torch",
                      device="cpu")
    np.testing.assert_array_equal(got.packed, want.packed)
    if reset == "subtract":  # the backlog keeps the brightest pixels firing in the dark
        assert want.unpack()[-1, 0, 1:4].all() and not want.unpack()[-1, 1].any()


def test_normals_and_hashes_equal_the_numpy_twin():
    from spikesim.reference_rng import mix64_np, normal_np
    from spikesim.torch_backend import _rng

    g = np.random.default_rng(0)
    words = g.integers(0, 2**64 - 1, size=200_000, dtype=np.uint64, endpoint=True)
    words[:4000] >>= np.uint64(8)  # lower tail bins
    words[4000:8000] = ~(words[4000:8000] >> np.uint64(8))  # upper tail bins
    words[8000:8500] >>= np.uint64(17)  # exact inversion (u < 2**-16)
    words[8500:9000] = ~(words[8500:9000] >> np.uint64(17))
    words[9000:9002] = [0, 2**64 - 1]  # the extreme uniforms
    t = torch.from_numpy(words.view(np.int64))
    np.testing.assert_array_equal(_rng.mix64(t).numpy().view(np.uint64), mix64_np(words))
    np.testing.assert_array_equal(_rng.normal(t).numpy().view(np.int64),
                                  normal_np(words).view(np.int64))


def test_square_root_is_correctly_rounded():
    from spikesim.torch_backend._rng import sqrt_rn

    g = np.random.default_rng(1)
    x = np.concatenate([g.random(500_000) * s for s in (1e-3, 1.0, 255.0, 1e8, 1e40)]
                       + [[0.0, 1.0, 2.0, 4.0, 0.25, 2.0**-900, 2.0**900]])
    np.testing.assert_array_equal(sqrt_rn(torch.from_numpy(x)).numpy(), np.sqrt(x))


def test_batch_samples_equal_their_own_simulations():
    """Each sample of ``simulate_batch`` (own seed, pattern and noise level) is the
    numba kernel's stream of its key-frame scene."""
    from spikesim.torch_backend import simulate_batch

    rng = np.random.default_rng(4)
    b, k, h, w, n, clock = 5, 6, 6, 19, 40, 1000.0
    frames = (rng.random((b, k, 3, h, w)) * 1.6).astype(np.float32)
    key = np.array([0.0, 2.5, 9.0, 9.25, 17.0, 30.0])  # readouts (exact in seconds and back)
    assert np.array_equal((key / clock) * clock, key)
    seeds, cfas = [0, 1, 2**40, 7, 2**64 - 1], ["RGGB", "GBRG", None, "BGGR", "GRBG"]
    sg, sp = [0.0, 10.0, 2.5, 0.0, 15.0], [0.0, 0.0, 2.5, 1.0, 0.3]
    for reset in ("modulo", "subtract", "zero"):
        spikes = simulate_batch(torch.from_numpy(frames), key, n, seeds, cfas, sg, sp,
                                reset=reset)
        assert spikes.shape == (b, n, h, w) and spikes.dtype == torch.bool
        for i in range(b):
            scene = ss.scenes.Keyframes(key / clock, [f.transpose(1, 2, 0) for f in frames[i]])
            noise = ss.noise.PaperNoise(sg[i], sp[i]) if sg[i] or sp[i] else None
            sensor = ss.Sensor(height=h, width=w, cfa=cfas[i], clock_hz=clock, reset=reset,
                               noise=noise)
            want = ss.simulate(scene, sensor, n, seed=seeds[i])
            np.testing.assert_array_equal(
                np.packbits(spikes[i].numpy(), axis=-1, bitorder="little"), want.packed)


def test_batch_inputs_are_checked():
    from spikesim.torch_backend import simulate_batch

    frames = torch.zeros((2, 1, 3, 4, 4))
    with pytest.raises(SpikeSimValueError, match="frames.shape"):
        simulate_batch(torch.zeros((2, 3, 4, 4)), [0.0], 5, [0, 1])
    with pytest.raises(SpikeSimValueError, match="frames"):
        simulate_batch(frames - 1.0, [0.0], 5, [0, 1])
    with pytest.raises(SpikeSimValueError, match="key_readouts"):
        simulate_batch(frames, [0.0, 1.0], 5, [0, 1])
    with pytest.raises(SpikeSimValueError, match="seeds"):
        simulate_batch(frames, [0.0], 5, [0, 1, 2])
    with pytest.raises(SpikeSimValueError, match="sigma_g"):
        simulate_batch(frames, [0.0], 5, [0, 1], sigma_g=[1.0, -1.0])
    with pytest.raises(SpikeSimValueError, match="cfa"):
        simulate_batch(frames, [0.0], 5, [0, 1], cfa="RGBW")


def test_physical_noise_and_bad_backends_are_one_line_errors():
    sensor = ss.Sensor(height=4, width=8, cfa=None, noise=ss.noise.PhysicalNoise())
    scene = ss.scenes.Static(np.full((4, 8), 0.5))
    with pytest.raises(SpikeSimValueError, match="backend='torch'") as err:
        ss.simulate(scene, sensor, 10, backend="torch", device="cpu")
    assert "\n" not in str(err.value) and "PaperNoise" in str(err.value)
    ideal = ss.Sensor(height=4, width=8, cfa=None)
    with pytest.raises(SpikeSimValueError, match="backend"):
        ss.simulate(scene, ideal, 10, backend="cupy")
    with pytest.raises(SpikeSimValueError, match="device"):
        ss.simulate(scene, ideal, 10, device="cpu")  # a torch setting without the backend
    with pytest.raises(SpikeSimValueError, match="device"):
        ss.simulate(scene, ideal, 10, backend="torch", device="tpu:0")
    if not torch.cuda.is_available():
        with pytest.raises(SpikeSimValueError, match="no CUDA"):
            ss.simulate(scene, ideal, 10, backend="torch", device="cuda")


def test_without_torch_the_backend_is_a_one_line_error(monkeypatch):
    scene = ss.scenes.Static(np.full((4, 8), 0.5))
    sensor = ss.Sensor(height=4, width=8, cfa=None)
    monkeypatch.setitem(sys.modules, "torch", None)  # ``import torch`` raises ImportError
    for call in (lambda: ss.simulate(scene, sensor, 10, backend="torch"),
                 lambda: ss.simulate_chunks(scene, sensor, 10, backend="torch")):
        with pytest.raises(SpikeSimValueError, match=r"spikesim\[torch\]") as err:
            call()
        assert "\n" not in str(err.value)
    assert ss.simulate(scene, sensor, 10).packed.shape == (10, 4, 1)  # numba needs no torch


@pytest.mark.gpu
@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
@pytest.mark.parametrize("noise", list(NOISES))
@pytest.mark.parametrize("reset", ["modulo", "subtract", "zero"])
def test_cuda_gives_the_same_bits(scenes, reset, noise):
    for cfa in ("RGGB", None):
        sensor = ss.Sensor(height=H, width=W, cfa=cfa, reset=reset, noise=NOISES[noise])
        for name in ("moving", "static"):
            want = ss.simulate(scenes[name], sensor, N, seed=SEED)
            got = ss.simulate(scenes[name], sensor, N, seed=SEED, backend="torch",
                              device="cuda")
            np.testing.assert_array_equal(got.packed, want.packed)


@pytest.mark.gpu
@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
def test_cuda_batches_give_the_cpu_bits():
    from spikesim.torch_backend import simulate_batch

    frames = torch.rand((6, 3, 3, 24, 40), generator=torch.Generator().manual_seed(0)) * 1.5
    args = ([0.0, 4.5, 39.0], 39, [0, 1, 2, 3, 4, 5], ["RGGB", "GRBG", None, "BGGR", "GBRG",
                                                       "RGGB"],
            [0.0, 10.0, 2.5, 15.0, 0.0, 5.0], [0.0, 0.0, 2.5, 1.0, 1.0, 0.0])
    for reset in ("modulo", "subtract", "zero"):
        cpu = simulate_batch(frames, *args, reset=reset)
        gpu = simulate_batch(frames.cuda(), *args, reset=reset)
        assert torch.equal(gpu.cpu(), cpu)
