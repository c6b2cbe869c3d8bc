"""Training: synthesised data, the noise-map target, resume equivalence, the CLI."""

from __future__ import annotations

import json
import shutil
from dataclasses import asdict

import numpy as np
import pytest
import torch

import spikejdd as sj
from spikejdd.cli import main
from spikejdd.models import SJDDNet, load_checkpoint, load_model, save_checkpoint
from spikejdd.train import EpochSampler, TrainConfig, noise_map_target, synthesize, train
from spikesim.errors import SpikeSimValueError
from tests.support.sjdd_helpers import TINY


@pytest.fixture(scope="module")
def tiny_data(tmp_path_factory):
    root = tmp_path_factory.mktemp("sjdd_data")
    info = synthesize(root, n_sequences=2, sizes=((16, 20),), n_readouts=21, gt_every=3,
                      window=TINY.n_readouts, seed=5, progress=False)
    return root, info


def _cfg(data, out, **kw):
    base = dict(data=str(data), out=str(out), model="lite", model_overrides=TINY.to_dict(),
                steps=7, batch_size=2, crop=12, lr=1e-3, lr_step=3, gamma=0.5,
                noise_weight=0.1, eval_every=100, eval_frames=2, checkpoint_every=100,
                progress=False, seed=11)
    base.update(kw)
    return TrainConfig.from_dict(base)


def test_synthesized_set_is_described(tiny_data):
    root, info = tiny_data
    assert len(info["sequences"]) == 2
    assert info["sequences"][0]["sigma_p"] == 0.0  # GN
    assert 0 <= info["sequences"][1]["sigma_p"] <= 1  # GPN, the evaluation's range
    used = {c for s in info["sequences"] for c in s["content"]}
    assert used <= set(info["pictures"]) | {"texture", "dead-leaves"}
    assert not {"astronaut", "coffee", "chelsea", "rocket"} & set(info["pictures"])
    assert json.loads((root / "synth.json").read_text())["seed"] == 5


def test_noise_map_target():
    gt = torch.full((2, 3, 2, 2), 0.5)
    t = noise_map_target({"sigma_g": torch.tensor([10.0, 3.0]),
                          "sigma_p": torch.tensor([0.0, 2.0])}, gt)
    torch.testing.assert_close(t[0], torch.full((1, 2, 2), 10.0 / 255))
    torch.testing.assert_close(t[1], torch.full((1, 2, 2), float(np.sqrt(9 + 4 * 127.5) / 255)))


def test_epoch_sampler_is_deterministic_and_splits_ranks():
    a = EpochSampler(10, seed=1, epoch=2).indices
    assert a == EpochSampler(10, seed=1, epoch=2).indices
    assert a != EpochSampler(10, seed=1, epoch=3).indices
    r0, r1 = EpochSampler(10, 1, 2, 0, 2).indices, EpochSampler(10, 1, 2, 1, 2).indices
    assert sorted(r0 + r1) == sorted(a) and not set(r0) & set(r1)
    assert EpochSampler(10, 1, 2, skip=4).indices == a[4:]


def test_resume_reproduces_an_uninterrupted_run(tiny_data, tmp_path):
    root, _ = tiny_data
    full = train(_cfg(root, tmp_path / "full"))
    assert full["steps_done"] == 7
    train(_cfg(root, tmp_path / "split", steps=3))
    part = load_checkpoint(tmp_path / "split" / "last.pt")
    assert part["train"]["step"] == 3
    resumed = train(_cfg(root, tmp_path / "split", resume="auto"))
    assert resumed["steps_done"] == 7 and resumed["resumed_at_step"] == 3
    # the log goes on as if uninterrupted: the same running loss, time counted over both calls
    log = [json.loads(x) for x in (tmp_path / "split" / "log.jsonl").read_text().splitlines()]
    log_full = [json.loads(x) for x in (tmp_path / "full" / "log.jsonl").read_text().splitlines()]
    assert [r["step"] for r in log] == [3, 7]
    assert log[-1]["train_loss"] == log_full[-1]["train_loss"]
    assert resumed["minutes"] >= log[0]["minutes"] + resumed["minutes_this_call"]
    a = load_checkpoint(tmp_path / "full" / "last.pt")["state_dict"]
    b = load_checkpoint(tmp_path / "split" / "last.pt")["state_dict"]
    assert a.keys() == b.keys()
    for k in a:
        torch.testing.assert_close(a[k], b[k], rtol=0, atol=0, msg=k)
    run = json.loads((tmp_path / "full" / "run.json").read_text())
    assert run["seed"] == 11 and run["data"]["sequences"] == 2
    assert "synthesis" in run["data"] and run["history"]
    blob = load_checkpoint(tmp_path / "full" / "best.pt")
    assert blob["seed"] == 11 and "psnr_linear" in blob["eval"]


def test_resume_with_another_model_is_refused(tiny_data, tmp_path):
    root, _ = tiny_data
    train(_cfg(root, tmp_path / "r", steps=1))
    other = dict(TINY.to_dict(), stages=2)
    with pytest.raises(SpikeSimValueError, match=r"same model configuration \(it has "
                       r"stages=\d+ where this run has 2: give the --model and --set"):
        train(_cfg(root, tmp_path / "r", resume="auto", model_overrides=other))


def test_resume_with_other_settings_is_refused(tiny_data, tmp_path, monkeypatch):
    """A resumed run keeps its optimizer, schedule and data order, so changed data,
    crops or learning rates would be silently ignored or mixed in: they are refused,
    naming each; how long and how fast it runs may change, and the same data given
    by another path is the same."""
    root, _ = tiny_data
    train(_cfg(root, tmp_path / "r", steps=1))
    with pytest.raises(SpikeSimValueError, match=r"resume=.*these differ: crop=16 \(the run "
                       r"has 12\), lr=0\.002 \(the run has 0\.001\)"):
        train(_cfg(root, tmp_path / "r", resume="auto", crop=16, lr=2e-3))
    other = shutil.copytree(root, tmp_path / "copy")  # another dataset, the same files
    with pytest.raises(SpikeSimValueError, match=r"data=.*copy.* \(the run has"):
        train(_cfg(other, tmp_path / "r", resume="auto"))
    monkeypatch.chdir(root.parent)
    done = train(_cfg(root.name, tmp_path / "r", resume="auto", steps=2, eval_every=1,
                      checkpoint_every=1, threads=1))
    assert done["steps_done"] == 2


def test_resume_allows_differences_in_settings_without_effect(tiny_data, tmp_path):
    """--epoch-steps sizes the decay interval only without an explicit --lr-step (and
    only online): a resume that changes it under --lr-step was refused as a change of
    settings. Settings that have no effect in either run may differ; the same setting
    where it has an effect is still refused."""
    root, _ = tiny_data
    train(_cfg(root, tmp_path / "r", steps=1))  # lr_step=3, file data
    done = train(_cfg(root, tmp_path / "r", resume="auto", steps=2, epoch_steps=99,
                      lr_step_epochs=7, clip_fraction=0.5, val_size=[20, 20]))
    assert done["steps_done"] == 2
    with pytest.raises(SpikeSimValueError, match=r"these differ: lr_step=None \(the run has "
                       r"3\) \(its run"):  # (last.pt now holds the settings it was given)
        train(_cfg(root, tmp_path / "r", resume="auto", steps=3, lr_step=None,
                   lr_step_epochs=7, epoch_steps=99))
    online = TrainConfig(online=True, lr_step=5, epoch_steps=240, validation="auto")
    same = dict(asdict(online), epoch_steps=99, flips=False, validation="sweep",
                eval_frames=3)
    assert online.resume_differences(same) == []
    unset = TrainConfig(online=True, epoch_steps=240)  # here it sets the decay interval
    assert unset.resume_differences(dict(asdict(unset), epoch_steps=99)) == [
        "epoch_steps=240 (the run has 99)"]


def test_train_says_where_it_validates_and_names_its_split_flags(tiny_data, tmp_path,
                                                                 capsys):
    """Without --eval-data the run validates on its training data: a note says so; a
    dataset root with several splits given as --eval-data names --eval-split."""
    root, _ = tiny_data
    both = tmp_path / "root"
    both.mkdir()
    for split in ("train", "eval"):
        (both / split).symlink_to(root, target_is_directory=True)
    base = ["train", "--model", "lite", "--steps", "1", "--batch-size", "2", "--crop", "12",
            "--quiet", "--threads", "1"]
    assert main([*base, "--data", str(both), "--split", "train", "--eval-data", str(both),
                 "--out", str(tmp_path / "a")]) == 1
    err = capsys.readouterr().err
    assert "pick one with --eval-split NAME" in err and len(err.strip().splitlines()) == 1
    cfg = tmp_path / "tiny.json"
    cfg.write_text(json.dumps({"model_overrides": TINY.to_dict(), "eval_frames": 2}))
    assert main([*base, "--config", str(cfg), "--data", str(both), "--split", "train",
                 "--out", str(tmp_path / "b")]) == 0
    assert "note: validating on the training data" in capsys.readouterr().err


def test_init_starts_from_weights_with_a_fresh_schedule(tiny_data, tmp_path):
    root, _ = tiny_data
    train(_cfg(root, tmp_path / "a", steps=2))
    start = tmp_path / "a" / "last.pt"
    tuned = train(_cfg(root, tmp_path / "b", steps=1, lr=1e-12, init=str(start)))
    assert tuned["steps_done"] == 1
    a = load_checkpoint(start)["state_dict"]
    b = load_checkpoint(tmp_path / "b" / "last.pt")
    assert b["train"]["step"] == 1  # a fresh state, not the start's step 2
    for k in a:  # a tiny learning rate: one step barely moves the start weights
        torch.testing.assert_close(b["state_dict"][k], a[k], rtol=0, atol=1e-6, msg=k)
    scratch = load_checkpoint(tmp_path / "a" / "best.pt")["state_dict"]
    fresh = SJDDNet(TINY).state_dict()
    assert any(not torch.equal(scratch[k], fresh[k]) for k in fresh)  # so the check above bites
    other = dict(TINY.to_dict(), stages=2)
    with pytest.raises(SpikeSimValueError, match="init"):
        train(_cfg(root, tmp_path / "c", steps=1, init=str(start), model_overrides=other))


def test_bad_train_config():
    with pytest.raises(SpikeSimValueError, match="data"):
        TrainConfig().validate()
    with pytest.raises(SpikeSimValueError, match="train config keys"):
        TrainConfig.from_dict({"data": "x", "learning_rate": 1})
    with pytest.raises(SpikeSimValueError, match="model"):
        TrainConfig(data="x", model="huge").model_config()


def test_refused_runs_leave_no_output_folder(tiny_data, tmp_path, capsys):
    root, _ = tiny_data
    for data, extra, message in (
            (tmp_path / "nosuch", [], "no such dataset folder"),
            (root, [], "window=39 is invalid")):  # the full model on 21-readout data
        out = tmp_path / "a" / "run"
        assert main(["train", "--data", str(data), "--out", str(out), "--steps", "1", "--quiet",
                     *extra]) == 1
        assert message in capsys.readouterr().err
        assert not (tmp_path / "a").exists()


def test_cli_train_and_reconstruct(tiny_data, tmp_path, capsys):
    root, _ = tiny_data
    cfg = tmp_path / "run.json"
    cfg.write_text(json.dumps({"model": "lite", "model_overrides": TINY.to_dict(),
                               "steps": 2, "batch_size": 2, "crop": 12, "eval_frames": 1}))
    out = tmp_path / "run"
    assert main(["train", "--data", str(root), "--config", str(cfg), "--out", str(out),
                 "--set", "stages=2", "--quiet"]) == 0
    assert "trained 2 steps" in capsys.readouterr().out
    assert main(["train", "--data", str(root), "--config", str(cfg), "--out",
                 str(tmp_path / "one"), "--set", "stages=2", "--steps", "1", "--quiet"]) == 0
    assert "trained 1 step in" in capsys.readouterr().out
    weights = out / "last.pt"
    assert load_model(weights).config.stages == 2
    # reconstruct an HDF5 sequence (its GT readouts) and a .dat capture
    pngs = tmp_path / "png"
    h5 = sorted(root.glob("*.h5"))[0]
    assert main(["reconstruct", str(h5), "--method", "sjdd", "--weights", str(weights),
                 "--out", str(pngs), "--context", "11"]) == 0
    import cv2

    files = sorted(pngs.glob("*.png"))
    assert len(files) == 5
    img = cv2.imread(str(files[0]))
    assert img.shape == (16, 20, 3) and img.dtype == np.uint8
    import spikesim as ss

    spikes = ss.io.open_h5(h5).read_window(0, 21)
    dat = tmp_path / "cap.dat"
    ss.io.write_dat(dat, spikes, flip=True)
    assert main(["reconstruct", str(dat), "--method", "sjdd", "--weights", str(weights),
                 "--out", str(tmp_path / "dat"), "--height", "16", "--width", "20",
                 "--cfa", "RGGB", "--centers", "5,10"]) == 0
    assert len(list((tmp_path / "dat").glob("*.png"))) == 2
    # classical methods go through the same command
    assert main(["reconstruct", str(dat), "--method", "tfp11+bilinear", "--out",
                 str(tmp_path / "dat2"), "--height", "16", "--width", "20"]) == 0


def test_registered_method_runs_through_reconstruct(tmp_path):
    torch.manual_seed(0)
    path = save_checkpoint(tmp_path / "t.pt", SJDDNet(TINY))
    rng = np.random.default_rng(0)
    spikes = (rng.random((15, 10, 12)) < 0.4).astype(np.uint8)
    out = sj.reconstruct(spikes, cfa="GRBG", method="sjdd", center=7, weights=str(path))
    assert out.shape == (10, 12, 3) and out.min() >= 0 and out.max() <= 1
    assert "sjdd" in sj.list_methods()
    with pytest.raises(SpikeSimValueError, match="at least 9 readouts"):
        sj.reconstruct(spikes[:5], cfa="RGGB", method="sjdd", center=2, weights=str(path))
    with pytest.raises(SpikeSimValueError, match="Bayer"):
        sj.reconstruct(spikes, cfa=None, method="sjdd", center=7, weights=str(path))


def test_cli_help_states_the_trainconfig_defaults(capsys):
    with pytest.raises(SystemExit):
        main(["train", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    d = TrainConfig()
    for name in ("steps", "batch_size", "crop", "lr", "lr_step", "gamma", "noise_weight",
                 "eval_every", "eval_frames", "checkpoint_every", "seed", "workers"):
        flag = "--" + name.replace("_", "-")
        assert f"{flag} {name.upper()} default {getattr(d, name)}" in text, name


@pytest.mark.slow
def test_torchrun_two_cpu_processes(tiny_data, tmp_path):
    """DDP through torch's launcher: two gloo processes on the CPU train together."""
    import os
    import subprocess
    import sys

    root, _ = tiny_data
    cfg = tmp_path / "cfg.json"
    cfg.write_text(json.dumps({"model": "lite", "model_overrides": TINY.to_dict(), "steps": 2,
                               "batch_size": 2, "crop": 12, "eval_frames": 1, "threads": 1,
                               "time_limit_min": 10}))
    env = dict(os.environ, OMP_NUM_THREADS="1")
    proc = subprocess.run(
        [sys.executable, "-m", "torch.distributed.run", "--nproc_per_node", "2",
         "--master_port", "29531", "-m", "spikejdd.cli", "train", "--data", str(root),
         "--config", str(cfg), "--out", str(tmp_path / "run"), "--quiet"],
        capture_output=True, text=True, timeout=300, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    run = json.loads((tmp_path / "run" / "run.json").read_text())
    assert run["world_size"] == 2 and run["steps_done"] == 2
    assert proc.stdout.count("trained 2 steps") == 1  # only rank 0 reports


def test_fine_tuning_advice_lowers_the_learning_rate():
    """docs/sjdd.md tells a user fine-tuning with --init to lower the learning rate, with
    the flag and a value (a tenth of the default at most), in prose and in its tested
    example."""
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[3] / "docs" / "sjdd.md").read_text()
    para = text[text.index("**Fine-tuning.**"):]
    para = para[:para.index("\n**", 1)]  # up to the next paragraph with a bold lead
    commands = [c for c in re.findall(r"spikejdd train[^`]*", para) if "--init" in c]
    assert len(commands) >= 2, commands
    for command in commands:
        lr = re.search(r"--lr (\S+)", command)
        assert lr and float(lr[1]) <= TrainConfig().lr / 10, command


@pytest.mark.parametrize("resume", [None, "auto"])
def test_a_fresh_start_over_results_without_last_pt_is_refused(tiny_data, tmp_path, resume):
    """A run killed before its first checkpoint leaves best.pt and log.jsonl but no
    last.pt: starting again there (``--resume auto`` finds nothing to resume) would
    overwrite them, so it is refused; files left untouched."""
    out = tmp_path / "run"
    out.mkdir()
    (out / "best.pt").write_bytes(b"weights of the earlier run")
    (out / "log.jsonl").write_text('{"step": 30}\n')
    with pytest.raises(SpikeSimValueError, match=r"holds best.pt and log.jsonl but no last.pt "
                                                 r"to resume from"):
        train(_cfg(tiny_data[0], out, resume=resume))
    assert (out / "best.pt").read_bytes() == b"weights of the earlier run"
    assert sorted(p.name for p in out.iterdir()) == ["best.pt", "log.jsonl"]
    (out / "best.pt").unlink()
    (out / "log.jsonl").write_text("")  # an empty log holds nothing to lose
    train(_cfg(tiny_data[0], out, resume=resume, steps=2))
    assert (out / "last.pt").exists()
