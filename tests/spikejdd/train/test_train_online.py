"""Training data that covers what the model will see, simulation in the loader, chunked runs."""

from __future__ import annotations

import inspect
import json

import numpy as np
import pytest
import torch

from spikejdd.cli import main
from spikejdd.models import load_checkpoint
from spikejdd.train import TEST_PICTURES, TRAIN_PICTURES, VALIDATION_PICTURES, TrainConfig, train
from spikejdd.train.online import OnlineSpikeDataset, draw_noise, simulate_sample
from spikejdd.train.pictures import PICTURES, picture_path
from spikejdd.train.scenes import SLOW_PX_S, draw_scene, draw_speed
from spikejdd.train.validation import validation_frames
from spikesim.errors import SpikeSimValueError
from tests.support.sjdd_helpers import TINY


def _benchmark_pictures() -> set[str]:
    """Every picture the benchmark scores on, read from the code that builds its scenes."""
    from spikejdd.evaluate import SWEEP_SETS
    from spikesim.scenes.layered import RotatingDisk, Sprites

    names = {name for scenes in SWEEP_SETS.values() for name, motion in scenes if motion}
    for cls in (Sprites, RotatingDisk):
        for p in inspect.signature(cls).parameters.values():
            if p.name in ("background", "texture"):
                names.add(p.default)
            if p.name == "sprite_images":
                names.update(p.default)
    return names


def test_benchmark_pictures_are_kept_out_of_training():
    test = _benchmark_pictures()
    assert {"astronaut", "coffee", "chelsea", "rocket"} <= test
    assert test <= set(TEST_PICTURES)
    assert not set(TRAIN_PICTURES) & (test | set(VALIDATION_PICTURES))
    assert len(TRAIN_PICTURES) >= 15
    for name in PICTURES:
        assert picture_path(name).is_file(), name
    with pytest.raises(SpikeSimValueError, match="picture"):
        picture_path("nope")


def test_speeds_cover_static_slow_and_fast():
    rng = np.random.default_rng(0)
    speeds = np.array([draw_speed(rng)[1] for _ in range(4000)])
    px_per_window = speeds * 39 / 20_000.0
    assert np.mean(px_per_window <= 1.0) >= 0.4
    assert np.mean(speeds == 0) >= 0.15
    assert speeds.max() >= 3000 and speeds.max() <= 4000
    assert SLOW_PX_S == pytest.approx(20_000 / 39)


def test_noise_draws_follow_the_evaluation_ranges():
    from spikejdd.evaluate import GPN_RANGE

    rng = np.random.default_rng(1)
    draws = [draw_noise(rng) for _ in range(2000)]
    gn = np.array([d[1:] for d in draws if d[0] == "GN"])
    gpn = np.array([d[1:] for d in draws if d[0] == "GPN"])
    assert 800 < len(gn) < 1200
    assert gn[:, 0].min() >= 0 and gn[:, 0].max() <= 15 and gn[:, 0].max() > 14
    assert not gn[:, 1].any()
    assert gpn[:, 0].max() <= GPN_RANGE["sigma_g"][1] and gpn[:, 1].max() <= GPN_RANGE["sigma_p"][1]
    assert gpn[:, 1].max() > 0.9 * GPN_RANGE["sigma_p"][1]


def test_scenes_are_exact_and_move_as_described():
    kinds = set()
    for i in range(14):
        scene, desc = draw_scene(np.random.default_rng([3, i]), (16, 24))
        kinds.add(desc["kind"])
        a, b = scene.radiance(0.0), scene.radiance(39 / 20_000.0)
        assert a.shape == (16, 24, 3) and np.isfinite(a).all() and a.min() >= 0
        assert set(desc["content"]) <= set(TRAIN_PICTURES) | {"texture", "dead-leaves"}
        if desc["speed_bin"] == "static":
            np.testing.assert_allclose(a, b, atol=1e-5)
        elif desc["speed_px_s"] > 1000:
            assert np.abs(a - b).max() > 1e-3
    assert len(kinds) >= 3


def test_samples_are_reproducible_from_seed_and_index():
    a, b = simulate_sample(7, 3, 8, window=9), simulate_sample(7, 3, 8, window=9)
    assert a["spikes"].shape == (9, 8, 8) and a["mask"].shape == (4, 8, 8)
    assert a["gt"].shape == (3, 8, 8)
    for k in ("spikes", "mask", "gt"):
        torch.testing.assert_close(a[k], b[k], rtol=0, atol=0)
    assert a["meta"] == b["meta"]
    c = simulate_sample(7, 4, 8, window=9)
    assert not torch.equal(a["spikes"], c["spikes"]) or a["meta"] != c["meta"]


def test_loader_stream_is_the_same_for_any_worker_count_and_resumes():
    ds = OnlineSpikeDataset(batch_size=2, crop=8, window=9, seed=4, start_step=1, stop_step=4)
    one = list(torch.utils.data.DataLoader(ds, batch_size=None, num_workers=0))
    two = list(torch.utils.data.DataLoader(ds, batch_size=None, num_workers=2,
                                           multiprocessing_context="spawn"))
    assert len(one) == len(two) == 3
    for step, (x, y) in enumerate(zip(one, two, strict=True), start=1):
        ref = ds.batch(step)
        for k in ("spikes", "mask", "gt"):
            torch.testing.assert_close(x[k], y[k], rtol=0, atol=0)
            torch.testing.assert_close(x[k], ref[k], rtol=0, atol=0)
        assert x["meta"]["index"].tolist() == [2 * step, 2 * step + 1]
    with pytest.raises(SpikeSimValueError, match="crop"):
        OnlineSpikeDataset(batch_size=2, crop=1)
    # odd crops, as file data allows: the mask follows each sample's pattern
    odd = OnlineSpikeDataset(batch_size=2, crop=7, window=9, seed=4).batch(0)
    assert odd["spikes"].shape == (2, 9, 7, 7) and odd["mask"].shape == (2, 4, 7, 7)
    assert torch.all(odd["mask"].sum(dim=1) == 1)


def test_a_loader_worker_simulates_on_one_thread_and_the_main_process_keeps_its_own(
        monkeypatch):
    import types

    import cv2
    import numba

    before = numba.get_num_threads(), cv2.getNumThreads()
    ds = OnlineSpikeDataset(batch_size=1, crop=8, window=9, seed=4, stop_step=1)
    try:
        next(iter(ds))  # this process: threads untouched
        assert (numba.get_num_threads(), cv2.getNumThreads()) == before
        monkeypatch.setattr(torch.utils.data, "get_worker_info",
                            lambda: types.SimpleNamespace(id=0, num_workers=1))
        batch = next(iter(ds))  # as a worker: one thread for numba and OpenCV
        assert (numba.get_num_threads(), cv2.getNumThreads()) == (1, 1)
        torch.testing.assert_close(batch["spikes"], ds.batch(0)["spikes"], rtol=0, atol=0)
    finally:
        numba.set_num_threads(before[0])
        cv2.setNumThreads(before[1])


def test_validation_sweep_has_static_and_slow_scenes_on_held_out_pictures():
    frames = validation_frames(size=(8, 12), speeds=(0.0, 150.0, 3000.0),
                               levels=["GN10", "GPN-rand"], context=11)
    assert len(frames) == 2 * 6 * 3
    groups = [f.group for f in frames]
    assert {g["speed_px_s"] for g in groups} == {0.0, 150.0, 3000.0}
    assert {g["set"] for g in groups} == {"object", "camera"}
    assert {g["noise"] for g in groups} == {"GN10", "GPN-rand"}
    assert frames[0].spikes.shape == (11, 8, 12) and frames[0].gt.shape == (8, 12, 3)
    with pytest.raises(SpikeSimValueError, match="val_levels"):
        validation_frames(size=(8, 8), levels=["GN7"])


def test_default_schedule_is_the_authors_scaled_to_steps():
    cfg = TrainConfig(online=True)
    assert (cfg.lr, cfg.gamma, cfg.batch_size, cfg.crop) == (5e-4, 0.8, 8, 64)
    assert cfg.lr_step_for(cfg.epoch_steps) == 50 * 240 == 12_000
    assert cfg.lr_step_for(37) == 50 * 37
    assert TrainConfig(online=True, lr_step=7).lr_step_for(240) == 7
    assert cfg.validation_kind() == "sweep" and TrainConfig(data="x").validation_kind() == "files"
    TrainConfig(online=True, crop=9).validate()  # odd crops, as with file data
    with pytest.raises(SpikeSimValueError, match="crop"):
        TrainConfig(online=True, crop=0).validate()
    with pytest.raises(SpikeSimValueError, match="val_size"):
        TrainConfig(online=True, val_size=[7, 8]).validate()


def _chunk(out, steps, extra=()):
    cfg = {"model": "lite", "model_overrides": TINY.to_dict(), "batch_size": 2, "crop": 8,
           "eval_every": 2, "checkpoint_every": 100, "val_size": [12, 12],
           "val_speeds": [0.0, 3000.0], "val_levels": ["GN10"], "bench_methods": ["tfp+bilinear"],
           "lr_step": 2, "gamma": 0.5}
    path = out.parent / f"{out.name}.json"
    path.write_text(json.dumps(cfg))
    return main(["train", "--online", "--config", str(path), "--out", str(out), "--steps",
                 str(steps), "--seed", "3", "--resume", "auto", "--threads", "1", "--quiet",
                 *extra])


def test_two_chunks_equal_one_uninterrupted_run(tmp_path):
    """The GPU command sequence on the CPU: chunks through --resume auto and a time limit."""
    assert _chunk(tmp_path / "full", 4) == 0
    # chunk 1 stops on its time limit after its first step, chunk 2 finishes the run
    assert _chunk(tmp_path / "split", 4, ["--time-limit-min", "1e-6"]) == 0
    first = load_checkpoint(tmp_path / "split" / "last.pt")["train"]["step"]
    assert 1 <= first < 4
    assert _chunk(tmp_path / "split", 4) == 0
    a = load_checkpoint(tmp_path / "full" / "last.pt")
    b = load_checkpoint(tmp_path / "split" / "last.pt")
    assert b["train"]["step"] == a["train"]["step"] == 4
    for k in a["state_dict"]:
        torch.testing.assert_close(a["state_dict"][k], b["state_dict"][k], rtol=0, atol=0, msg=k)
    # every chunk ends with a validation and a benchmark row
    rows = [json.loads(x) for x in (tmp_path / "split" / "bench.jsonl").read_text().splitlines()]
    assert [r["step"] for r in rows] == [first, 4]
    assert {"delta_db", "best_classical", "delta_by_speed"} <= set(rows[-1])
    assert set(rows[-1]["delta_by_speed"]) == {"0.0", "3000.0"}
    log = [json.loads(x) for x in (tmp_path / "split" / "log.jsonl").read_text().splitlines()]
    assert log[-1]["step"] == 4 and "by_speed" in log[-1]
    size = sum(p.stat().st_size for p in (tmp_path / "split").iterdir() if p.suffix != ".pt"
               or p.name == "last.pt")
    assert size < 64 * 2**20
    assert "optimizer" not in load_checkpoint(tmp_path / "split" / "best.pt")["train"]
    run = json.loads((tmp_path / "split" / "run.json").read_text())
    assert run["config"]["online"] and run["data"]["validation"] == "sweep"


def test_set_up_time_is_not_counted_as_training_time(tmp_path, monkeypatch, capsys):
    """A cold first run compiles the simulation kernels (a minute or more) before its
    first batch: log.jsonl's ``minutes`` counted it as training. It is set-up now, in
    ``setup_minutes`` (log rows, run.json, last.pt), summed over the chunks of a run."""
    import time

    from spikejdd.train.trainer import Trainer

    delay, real = 4.0, Trainer.batches

    def slow_batches(self):
        time.sleep(delay)  # as the kernels' compilation before the first batch
        yield from real(self)

    monkeypatch.setattr(Trainer, "batches", slow_batches)
    assert _chunk(tmp_path / "run", 2) == 0
    row = json.loads((tmp_path / "run" / "log.jsonl").read_text().splitlines()[-1])
    assert row["step"] == 2 and row["minutes"] * 60 < delay  # (old code: delay and more)
    assert delay <= row["setup_minutes"] * 60
    assert "min of set-up" in capsys.readouterr().out
    first = json.loads((tmp_path / "run" / "run.json").read_text())
    assert first["minutes"] * 60 < delay <= first["setup_minutes"] * 60
    assert load_checkpoint(tmp_path / "run" / "last.pt")["train"]["setup_minutes"] * 60 >= delay
    assert _chunk(tmp_path / "run", 3) == 0
    second = json.loads((tmp_path / "run" / "run.json").read_text())
    assert delay <= second["setup_minutes_this_call"] * 60
    assert second["setup_minutes"] == pytest.approx(first["setup_minutes"]
                                                    + second["setup_minutes_this_call"])
    assert second["minutes"] * 60 < 2 * delay


def test_clip_samples_are_cut_from_cached_video_key_frames(tmp_path):
    """A frame folder becomes samples: still, slowed or sped up; its scene is cached."""
    import imageio.v3 as iio

    from spikejdd.train import clips as clips_mod
    from spikejdd.train.clips import ClipWindow, clip_scene

    rng = np.random.default_rng(0)
    base = (rng.random((24, 32, 3)) * 255).astype(np.uint8)
    folder = tmp_path / "clip"
    folder.mkdir()
    for i in range(4):
        iio.imwrite(folder / f"{i:05d}.png", np.roll(base, i, axis=1))
    a = simulate_sample(2, 5, 8, window=9, clips=[str(folder)], clip_fraction=1.0)
    b = simulate_sample(2, 5, 8, window=9, clips=[str(folder)], clip_fraction=1.0)
    assert a["meta"]["kind"] == "clip" and a["spikes"].shape == (9, 8, 8)
    torch.testing.assert_close(a["spikes"], b["spikes"], rtol=0, atol=0)
    assert clip_scene(str(folder)) is clips_mod._CACHE[str(folder)]  # one scene per clip
    scene = clip_scene(str(folder))
    still = ClipWindow(scene, (2, 3, 8, 8), 1 / scene.fps, 0.0)
    assert still.is_static and list(still.key_times(0.0, 1.0)) == [0.0]
    np.testing.assert_allclose(still.radiance(0.5), scene.radiance(1 / scene.fps)[2:10, 3:11])
    fast = ClipWindow(scene, (0, 0, 8, 8), 0.0, 4.0)
    keys = fast.key_times(0.0, 1 / scene.fps)
    assert keys[0] == 0.0 and keys[-1] >= 1 / scene.fps
    with pytest.raises(SpikeSimValueError, match="box"):
        ClipWindow(scene, (20, 0, 8, 8), 0.0, 1.0)
    with pytest.raises(SpikeSimValueError, match="clips"):
        TrainConfig(online=True, clips=[str(tmp_path / "missing")]).validate()


def test_trainer_owns_step_validate_save_and_resume(tmp_path):
    from spikejdd.train import Trainer, TrainState

    cfg = TrainConfig(online=True, model="lite", model_overrides=TINY.to_dict(), batch_size=2,
                      crop=8, val_size=[12, 12], val_speeds=[0.0], val_levels=["GN0"],
                      out=str(tmp_path), seed=1, progress=False)
    tr = Trainer(cfg)
    assert tr.lr_step == 50 * 240 and tr.state == TrainState()
    before = {k: v.clone() for k, v in tr.model.state_dict().items()}
    loss = tr.step(next(tr.batches()))
    assert np.isfinite(loss) and tr.state.step == 1
    assert any(not torch.equal(before[k], v) for k, v in tr.model.state_dict().items())
    res = tr.validate()
    assert res["frames"] == 6 and set(res["by_speed"]) == {"0.0"}
    tr.state.history.append(res)
    tr.save("last.pt")
    other = Trainer(cfg)
    other.resume(tmp_path / "last.pt")
    assert other.state.step == 1 and other.state.history[-1]["frames"] == 6
    for k, v in tr.model.state_dict().items():
        torch.testing.assert_close(other.model.state_dict()[k], v, rtol=0, atol=0)
    assert other.optimizer.state_dict()["state"].keys() == tr.optimizer.state_dict()["state"].keys()


def test_batches_mix_clip_and_procedural_samples():
    """A clip sample carries its playback rate, a procedural one does not: a batch of
    both keeps every field (None where a sample lacks it) instead of failing."""
    from spikejdd.train.online import collate

    def sample(meta):
        return {"spikes": torch.zeros(3, 4, 4), "mask": torch.zeros(4, 4, 4),
                "gt": torch.zeros(3, 4, 4), "meta": meta}

    batch = collate([sample({"kind": "clip", "sigma_g": 1.0, "rate": 2.0}),
                     sample({"kind": "procedural", "sigma_g": 3.0})])
    assert batch["meta"]["rate"] == [2.0, None]
    torch.testing.assert_close(batch["meta"]["sigma_g"], torch.tensor([1.0, 3.0],
                                                                      dtype=torch.float64))


def test_bad_clips_and_a_run_folder_are_refused_before_step_one(tmp_path, capsys):
    """A clip that is no readable video or frame folder is refused up front (not when the
    loader first draws it), and a folder holding a run is not trained over from scratch;
    neither writes anything."""
    (tmp_path / "afile").write_text("not a video")
    (tmp_path / "empty").mkdir()
    base = ["train", "--online", "--model", "lite", "--steps", "1", "--crop", "16",
            "--batch-size", "2", "--threads", "1", "--quiet"]
    for clip in ("afile", "empty"):
        out = tmp_path / f"run-{clip}"
        assert main(base + ["--clip", str(tmp_path / clip), "--out", str(out)]) == 1
        err = capsys.readouterr().err
        assert "--clip=" in err and len(err.strip().splitlines()) == 1
        assert not out.exists()
    # errors name the flags given, not the config fields behind them
    (tmp_path / "afile.pt").write_text("not a folder")
    for extra, flag in ((["--out", str(tmp_path / "afile.pt")], "--out="),
                        (["--crop", "0", "--out", str(tmp_path / "r0")], "--crop=0"),
                        (["--init", "nothere.pt", "--out", str(tmp_path / "r1")], "--init=")):
        assert main(base + extra) == 1  # (the last --crop given counts)
        err = capsys.readouterr().err
        assert f"error: {flag}" in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "r0").exists() and not (tmp_path / "r1").exists()
    run = tmp_path / "run"
    run.mkdir()
    (run / "last.pt").write_bytes(b"a run's checkpoint")
    assert main(base + ["--out", str(run)]) == 1
    assert "holds one (last.pt)" in capsys.readouterr().err
    assert (run / "last.pt").read_bytes() == b"a run's checkpoint"


def test_online_training_refuses_data_it_would_ignore(tmp_path, capsys):
    """--data with --online would be ignored (every sample is simulated) unless it is the
    validation set: an error that says how to validate on files; a missing --weights of
    reconstruct is refused before any work."""
    with pytest.raises(SpikeSimValueError, match="data=.*None with online"):
        TrainConfig(online=True, data=str(tmp_path)).validate()
    TrainConfig(online=True, data=str(tmp_path), validation="files").validate()
    assert main(["reconstruct", str(tmp_path / "x.h5"), "--methods", "sjdd", "--weights",
                 "nothere.pt", "--out", str(tmp_path / "r")]) == 1
    assert "--weights='nothere.pt' is invalid" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


def test_a_stopped_run_keeps_its_steps_and_resumes_as_if_uninterrupted(tmp_path, capsys,
                                                                        monkeypatch):
    """Ctrl-C during a step waits for the step's end, then last.pt is saved at that step
    (not the last scheduled checkpoint) and the message says how to go on; the resumed
    run ends bit-identical to an uninterrupted one, its log without repeated steps."""
    import os
    import signal

    from spikejdd.train.trainer import Trainer

    real = Trainer.step

    def step_with_ctrl_c(self, batch):
        if self.state.step == 2:  # Ctrl-C arrives in the middle of step 3
            os.kill(os.getpid(), signal.SIGINT)
        return real(self, batch)

    monkeypatch.setattr(Trainer, "step", step_with_ctrl_c)
    assert _chunk(tmp_path / "run", 6, ["--checkpoint-every", "100"]) == 130
    err = capsys.readouterr().err
    assert f"kept {tmp_path / 'run' / 'last.pt'} (step 3)" in err and "--resume auto" in err
    assert load_checkpoint(tmp_path / "run" / "last.pt")["train"]["step"] == 3
    monkeypatch.setattr(Trainer, "step", real)
    with open(tmp_path / "run" / "log.jsonl", "a") as log:  # as a run killed after step 4 left it
        log.write('{"step": 4, "psnr_linear": 1.0}\n{"step": 5, "psn')
    assert _chunk(tmp_path / "run", 6) == 0
    assert _chunk(tmp_path / "full", 6) == 0
    a = load_checkpoint(tmp_path / "full" / "last.pt")
    b = load_checkpoint(tmp_path / "run" / "last.pt")
    for k in a["state_dict"]:
        torch.testing.assert_close(a["state_dict"][k], b["state_dict"][k], rtol=0, atol=0, msg=k)
    rows = [json.loads(x) for x in (tmp_path / "run" / "log.jsonl").read_text().splitlines()]
    steps = [r["step"] for r in rows]
    assert steps == sorted(set(steps)), steps


def test_init_with_weights_of_another_preset_names_it(tmp_path):
    """Shipped lite weights given to a run of the default model: the error says which
    preset they are, not only the fields that differ; nothing is left behind."""
    cfg = TrainConfig(online=True, init="sjdd-lite", out=str(tmp_path / "run"), steps=1,
                      progress=False)
    with pytest.raises(SpikeSimValueError, match=r"init='sjdd-lite'.*they are --model lite "
                       r"weights; it has"):
        train(cfg)
    assert not (tmp_path / "run").exists()
