"""Training batches rendered and simulated on the training device (``--online --device-sim``)."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest

torch = pytest.importorskip("torch")

import spikesim as ss  # noqa: E402
from spikejdd.cli import main  # noqa: E402
from spikejdd.models import load_checkpoint  # noqa: E402
from spikejdd.train import TrainConfig  # noqa: E402
from spikejdd.train.device_scenes import render  # noqa: E402
from spikejdd.train.device_sim import (  # noqa: E402
    CLOCK_HZ,
    DeviceBatches,
    device_batch,
    device_sample_params,
)
from spikejdd.train.pictures import TRAIN_PICTURES  # noqa: E402
from spikesim.errors import SpikeSimValueError  # noqa: E402
from tests.support.sjdd_helpers import TINY  # noqa: E402


def test_stream_is_a_function_of_seed_and_index_and_resumes():
    ds = DeviceBatches(batch_size=2, crop=8, window=9, seed=4, start_step=1, stop_step=3)
    got = list(ds)
    assert len(got) == 2
    for step, batch in enumerate(got, start=1):
        assert batch["spikes"].shape == (2, 9, 8, 8) and batch["spikes"].dtype == torch.float32
        assert batch["mask"].shape == (2, 4, 8, 8) and batch["gt"].shape == (2, 3, 8, 8)
        assert batch["meta"]["index"].tolist() == [2 * step, 2 * step + 1]
        again = ds.batch(step)
        for k in ("spikes", "mask", "gt"):
            torch.testing.assert_close(batch[k], again[k], rtol=0, atol=0)
    # a sample does not depend on the batch it is in
    four = device_batch(4, range(2, 6), 8, 9, "cpu")
    for k in ("spikes", "mask", "gt"):
        torch.testing.assert_close(four[k][:2], got[0][k], rtol=0, atol=0)
    with pytest.raises(SpikeSimValueError, match="crop"):
        DeviceBatches(batch_size=2, crop=1)


def test_samples_cover_the_training_distribution():
    params = [device_sample_params(9, i, 16) for i in range(120)]
    kinds = {p["scene"]["kind"] for p in params}
    assert kinds == {"picture", "texture", "sprites", "disk"}
    assert {p["scene"]["speed_bin"] for p in params} == {"static", "slow", "fast"}
    assert {p["cfa"] for p in params} == {"RGGB", "GRBG", "GBRG", "BGGR"}
    assert {p["noise"] for p in params} == {"GN", "GPN"}
    shown = {p["scene"]["background"]["content"] for p in params}
    assert shown <= set(TRAIN_PICTURES) | {"texture"} and len(shown) >= 5
    batch = device_batch(9, range(12), 16, 9, "cpu")
    gt = batch["gt"]
    assert float(gt.min()) >= 0.0 and float(gt.max()) <= 1.0 and float(gt.mean()) > 0.05
    assert torch.all(batch["mask"].sum(dim=1) == 1)


def test_a_sample_is_the_simulation_of_its_scene_with_exact_ground_truth():
    """The spikes of a device sample are ``spikesim.simulate``'s (numba) of the scene
    whose key frames were rendered at the readout boundaries; the ground truth is
    the scene rendered at the middle of the centre readout (not interpolated)."""
    crop, window = 12, 9
    batch = device_batch(2, range(3), crop, window, "cpu")
    for j in range(3):
        p = device_sample_params(2, j, crop)
        times = np.arange(window + 1, dtype=np.float64) / CLOCK_HZ
        frames = render(p["scene"], times, (crop, crop), "cpu").numpy()
        scene = ss.scenes.Keyframes(times, [f.transpose(1, 2, 0) for f in frames])
        noise = ss.noise.PaperNoise(p["sigma_g"], p["sigma_p"])
        sensor = ss.Sensor(height=crop, width=crop, cfa=p["cfa"], clock_hz=CLOCK_HZ,
                           full_scale_rate=0.6, noise=noise)
        want = ss.simulate(scene, sensor, window, seed=p["sim_seed"]).unpack()
        np.testing.assert_array_equal(batch["spikes"][j].numpy(), want)
        gt = render(p["scene"], [(window // 2 + 0.5) / CLOCK_HZ], (crop, crop), "cpu")[0]
        torch.testing.assert_close(batch["gt"][j], gt, rtol=0, atol=0)
        if p["scene"]["speed_bin"] == "fast":  # the key frames around it differ from it
            assert not torch.equal(torch.from_numpy(frames[window // 2]), gt)


def test_config_requires_online_and_refuses_clips(tmp_path):
    with pytest.raises(SpikeSimValueError, match="device_sim"):
        TrainConfig(data="x", device_sim=True).validate()
    clip = tmp_path / "clip"
    clip.mkdir()
    with pytest.raises(SpikeSimValueError, match="clips"):
        TrainConfig(online=True, device_sim=True, clips=[str(clip)]).validate()


def _chunk(out, steps, extra=()):
    cfg = {"model": "lite", "model_overrides": TINY.to_dict(), "batch_size": 2, "crop": 8,
           "eval_every": 2, "checkpoint_every": 100, "val_size": [12, 12],
           "val_speeds": [0.0, 3000.0], "val_levels": ["GN10"], "bench_methods": ["tfp+bilinear"],
           "lr_step": 2, "gamma": 0.5}
    path = out.parent / f"{out.name}.json"
    path.write_text(json.dumps(cfg))
    return main(["train", "--online", "--device-sim", "--config", str(path), "--out", str(out),
                 "--steps", str(steps), "--seed", "3", "--resume", "auto", "--threads", "1",
                 "--quiet", *extra])


def test_two_chunks_equal_one_uninterrupted_run(tmp_path):
    assert _chunk(tmp_path / "full", 3) == 0
    assert _chunk(tmp_path / "split", 3, ["--time-limit-min", "1e-6"]) == 0
    first = load_checkpoint(tmp_path / "split" / "last.pt")["train"]["step"]
    assert 1 <= first < 3
    assert _chunk(tmp_path / "split", 3) == 0
    a = load_checkpoint(tmp_path / "full" / "last.pt")
    b = load_checkpoint(tmp_path / "split" / "last.pt")
    assert b["train"]["step"] == a["train"]["step"] == 3
    for k in a["state_dict"]:
        torch.testing.assert_close(a["state_dict"][k], b["state_dict"][k], rtol=0, atol=0, msg=k)
    run = json.loads((tmp_path / "full" / "run.json").read_text())
    assert run["data"]["generator"] == "spikejdd.train.device_sim"


def test_training_with_device_simulation_runs_no_numba_kernel(tmp_path):
    """In a fresh process, training steps, the validation sweep and its benchmark row
    compile or load no numba function of spikesim beyond those its import runs (a
    table of ``spikesim._poisson`` is built at import)."""
    script = textwrap.dedent(f"""
        import json, sys
        from pathlib import Path
        from numba.core.dispatcher import Dispatcher
        from spikejdd.cli import main
        from tests.support.sjdd_helpers import TINY

        def used():
            return {{f"{{m}}.{{k}}" for m, mod in list(sys.modules.items())
                    if m.startswith(("spikesim", "spikejdd"))
                    for k, v in vars(mod).items() if isinstance(v, Dispatcher) and v.overloads}}

        at_import = used()
        cfg = {{"model": "lite", "model_overrides": TINY.to_dict(), "batch_size": 2, "crop": 8,
               "eval_every": 2, "val_size": [12, 12], "val_speeds": [0.0, 3000.0],
               "val_levels": ["GN10"], "bench_methods": ["tfp+bilinear"]}}
        path = Path({str(tmp_path)!r}) / "cfg.json"
        path.write_text(json.dumps(cfg))
        assert main(["train", "--online", "--device-sim", "--config", str(path), "--out",
                     str(Path({str(tmp_path)!r}) / "run"), "--steps", "2", "--threads", "1",
                     "--quiet"]) == 0
        print("USED", sorted(used() - at_import))
    """)
    res = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         timeout=900, cwd=str(__import__("pathlib").Path(__file__).parents[3]))
    assert res.returncode == 0, res.stderr[-3000:]
    assert "USED []" in res.stdout, res.stdout[-2000:]
