"""The trainer: owns the model, optimizer, schedule, data and state; ``step``,
``validate``, ``save`` and ``resume`` (after BasicSR's split of a thin ``train``
entry and a model object that optimizes, validates and saves itself).

* Loss: L2 on linear RGB plus ``noise_weight`` × L2 of the noise map against
  its target ``sqrt(σ_g² + σ_p²·y)/255`` (y = the GT's mean over colours in
  8-bit DN; the published ``σ/255`` for Gaussian noise).
* Adam with step decay (the authors' schedule, :mod:`spikejdd.train.config`).
* Data: simulated in the loader (:class:`spikejdd.train.online.OnlineSpikeDataset`,
  batch of step ``s`` from ``(seed, s)``) or files
  (:class:`spikejdd.data.SpikeWindowDataset`, a permutation per epoch from
  ``(seed, epoch)``, crops and flips from ``(seed, epoch, index)``).  Loader
  workers always start with ``spawn`` and exit when the training process dies
  (:mod:`spikejdd.train.workers`).
* Determinism: the run's seed fixes the initial weights and all data; the
  checkpoint carries the model, optimizer, scheduler and :class:`TrainState`,
  so a resumed run ends with the weights of an uninterrupted one.
* CPU or CUDA (bfloat16/float16 autocast; DCN and HQS kept in float32), and
  DistributedDataParallel under ``torchrun``.
"""

from __future__ import annotations

import functools
import json
import os
import threading
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch
import torch.distributed as dist
import torch.nn.functional as F

from spikejdd.models.checkpoints import load_checkpoint, save_checkpoint
from spikejdd.models.pretrained import resolve_weights
from spikejdd.models.sjdd import SJDDNet, count_parameters
from spikejdd.train.config import TrainConfig
from spikejdd.train.state import TrainState
from spikejdd.train.workers import watch_parent
from spikesim.errors import bad_value

__all__ = ["Trainer", "EpochSampler", "noise_map_target", "evaluate_psnr"]


def noise_map_target(meta: dict, gt: torch.Tensor) -> torch.Tensor:
    """(N, 1, H, W) target of the noise map: ``sqrt(σ_g² + σ_p²·y)/255``, y in 8-bit DN."""
    sg = torch.as_tensor(meta["sigma_g"], dtype=gt.dtype, device=gt.device).view(-1, 1, 1, 1)
    sp = torch.as_tensor(meta["sigma_p"], dtype=gt.dtype, device=gt.device).view(-1, 1, 1, 1)
    y = 255.0 * gt.mean(dim=1, keepdim=True).clamp_min(0)
    return torch.sqrt(sg**2 + sp**2 * y) / 255.0


class EpochSampler(torch.utils.data.Sampler):
    """Indices of one epoch: a permutation from ``(seed, epoch)``, this rank's share,
    starting after ``skip`` samples (resume)."""

    def __init__(self, n: int, seed: int, epoch: int, rank: int = 0, world: int = 1,
                 skip: int = 0):
        g = torch.Generator().manual_seed(int(seed) * 1_000_003 + int(epoch))
        perm = torch.randperm(n, generator=g).tolist()
        per_rank = n // world
        self.indices = perm[rank * per_rank:(rank + 1) * per_rank][skip:]

    def __iter__(self):
        return iter(self.indices)

    def __len__(self) -> int:
        return len(self.indices)


@torch.no_grad()
def evaluate_psnr(model, dataset, device, frames: int) -> dict:
    """Mean PSNR (linear light, peak 1, clamped) of ``model`` on up to ``frames`` samples."""
    from spikejdd.metrics import psnr

    model.eval()
    idx = np.unique(np.linspace(0, len(dataset) - 1, min(frames, len(dataset))).round()).astype(int)
    vals = []
    for i in idx:
        s = dataset[int(i)]
        spikes, mask = s["spikes"][None].to(device), s["mask"][None].to(device)
        out, _ = model(spikes, mask)
        gt = s["gt"].permute(1, 2, 0).numpy()
        vals.append(psnr(out[0].float().permute(1, 2, 0).cpu().numpy(), gt))
    model.train()
    return {"psnr_linear": float(np.mean(vals)), "frames": len(vals)}


def _device(name: str, local_rank: int) -> torch.device:
    if name == "auto":
        return torch.device(f"cuda:{local_rank}" if torch.cuda.is_available() else "cpu")
    dev = torch.device(name)
    if dev.type == "cuda" and not torch.cuda.is_available():
        raise bad_value("device", name, "'cpu' or 'auto' (no CUDA device here)")
    return dev


def _autocast(device: torch.device, enabled: bool):
    if device.type == "cuda" and enabled:  # pragma: no cover - CUDA only
        dtype = torch.bfloat16 if torch.cuda.is_bf16_supported() else torch.float16
        return torch.autocast("cuda", dtype=dtype), dtype
    return torch.autocast("cpu", enabled=False), None


def _range(values) -> list[float]:
    return [float(min(values)), float(max(values))] if values else []


def _check_clips(clips) -> None:
    """Open every clip before step 1: a bad one would otherwise fail only when the loader
    first draws a sample from it, which may be hours into a run."""
    from spikejdd.train.clips import clip_scene
    from spikesim.errors import SpikeSimError

    for c in clips:
        try:
            clip_scene(str(c))
        except SpikeSimError as exc:
            raise bad_value("clips", str(c), f"a readable video file or frame folder: {exc}") \
                from None


def config_difference(saved: dict, wanted: dict) -> str:
    """The model fields where a checkpoint's configuration ``saved`` differs from
    this run's ``wanted``: ``"it has width=32 where this run has 64, …"``, led by
    the preset it is when it is one (``"they are --model lite weights; …"``)."""
    from spikejdd.train.config import MODEL_PRESETS

    keys = [k for k in sorted(set(saved) | set(wanted)) if saved.get(k) != wanted.get(k)]
    preset = next((name for name, c in MODEL_PRESETS.items() if c.to_dict() == saved), None)
    lead = f"they are --model {preset} weights; " if preset else ""
    return lead + "it has " + ", ".join(
        f"{k}={saved.get(k)!r} where this run has {wanted.get(k)!r}" for k in keys)


class Trainer:
    """One run of ``cfg`` on this process (rank from the ``torchrun`` environment)."""

    def __init__(self, cfg: TrainConfig):
        self.cfg = cfg
        self.world = int(os.environ.get("WORLD_SIZE", "1"))
        self.rank = int(os.environ.get("RANK", "0"))
        self.device = _device(cfg.device, int(os.environ.get("LOCAL_RANK", "0")))
        if cfg.threads:
            torch.set_num_threads(int(cfg.threads))
        self.distributed = self.world > 1
        if self.distributed:
            if self.device.type == "cuda":  # pragma: no cover - multi-GPU only
                torch.cuda.set_device(self.device)
            dist.init_process_group("nccl" if self.device.type == "cuda" else "gloo")
        self.main = self.rank == 0
        self.out = Path(cfg.out)
        self.mcfg = cfg.model_config()
        torch.manual_seed(cfg.seed)
        self.model = SJDDNet(self.mcfg).to(self.device)
        if cfg.channels_last:
            self.model = self.model.to(memory_format=torch.channels_last)
        self.state = TrainState()
        self._setup_data()
        if self.main:  # only once the data checks passed: a refused run leaves no folder
            self.out.mkdir(parents=True, exist_ok=True)
        self.optimizer = torch.optim.Adam(self.model.parameters(), lr=cfg.lr)
        self.lr_step = cfg.lr_step_for(self.steps_per_epoch)
        self.scheduler = torch.optim.lr_scheduler.StepLR(self.optimizer, step_size=self.lr_step,
                                                         gamma=cfg.gamma)
        self.net = self.model
        if self.distributed:
            from torch.nn.parallel import DistributedDataParallel as DDP

            ids = [self.device.index] if self.device.type == "cuda" else None
            self.net = DDP(self.model, device_ids=ids)
        self.autocast, self.amp_dtype = _autocast(self.device, cfg.amp)
        self.scaler = torch.amp.GradScaler("cuda", enabled=self.amp_dtype == torch.float16)
        self._val_frames = None
        self.run_info = {"config": asdict(cfg), "model_config": self.mcfg.to_dict(),
                         "parameters": count_parameters(self.model), "seed": cfg.seed,
                         "world_size": self.world, "device": str(self.device),
                         "amp": str(self.amp_dtype), "data": self.data_desc,
                         "lr_step": self.lr_step, "torch": str(torch.__version__)}

    # --- data ------------------------------------------------------------------
    def _setup_data(self) -> None:
        cfg = self.cfg
        self.eval_ds = None
        if cfg.online:
            _check_clips(cfg.clips)
            self.train_ds = None
            self.steps_per_epoch = cfg.epoch_steps
            generator = "spikejdd.train.device_sim" if cfg.device_sim else "spikejdd.train.online"
            self.data_desc = {"train": "online", "generator": generator,
                              "crop": cfg.crop, "steps_per_epoch": cfg.epoch_steps,
                              "clips": list(cfg.clips),
                              "clip_fraction": cfg.clip_fraction if cfg.clips else 0.0}
        else:
            from spikejdd.data import SpikeWindowDataset

            ds = SpikeWindowDataset(cfg.data, window=self.mcfg.n_readouts, crop=cfg.crop,
                                    train=True, flips=cfg.flips, seed=cfg.seed)
            per_rank = len(ds) // self.world
            if per_rank < cfg.batch_size:
                raise bad_value("batch_size", cfg.batch_size,
                                f"at most the samples per process ({per_rank})")
            self.train_ds = ds
            self.steps_per_epoch = per_rank // cfg.batch_size
            infos = ds._infos.values()
            self.data_desc = {"train": str(cfg.data), "train_samples": len(ds),
                              "sequences": len(ds._infos),
                              "noise": sorted({f"{i.noise[0]}" for i in infos}),
                              "sigma_g_range": _range([i.noise[1] for i in infos]),
                              "sigma_p_range": _range([i.noise[2] for i in infos]),
                              "crop": cfg.crop, "flips": cfg.flips}
            info_path = Path(cfg.data) / "synth.json" if Path(cfg.data).is_dir() else None
            if info_path is not None and info_path.exists():
                self.data_desc["synthesis"] = json.loads(info_path.read_text())
        kind = cfg.validation_kind()
        self.data_desc["validation"] = kind
        if kind == "files":
            self.data_desc["eval"] = str(cfg.eval_data or cfg.data)
            if self.main:
                from spikejdd.data import SpikeWindowDataset

                self.eval_ds = SpikeWindowDataset(cfg.eval_data or cfg.data,
                                                  window=self.mcfg.n_readouts, crop=None,
                                                  train=False)
        else:
            self.data_desc["eval"] = {"sweep": "spikejdd.train.validation",
                                      "size": list(cfg.val_size), "speeds": list(cfg.val_speeds),
                                      "levels": cfg.val_levels}

    def _loader(self, dataset, **kw):
        """A loader of ``cfg.workers`` spawned processes (none: this one), each watching
        this process: a worker outlives a killed training by at most a second
        (:mod:`spikejdd.train.workers`)."""
        workers = self.cfg.workers
        watch = None
        if workers > 0:
            main_thread = threading.current_thread() is threading.main_thread()
            watch = functools.partial(watch_parent, os.getpid(), main_thread)
        return torch.utils.data.DataLoader(
            dataset, num_workers=workers, pin_memory=self.device.type == "cuda",
            multiprocessing_context="spawn" if workers > 0 else None,
            persistent_workers=False, worker_init_fn=watch, **kw)

    def batches(self):
        """Training batches from the current state onwards (endless)."""
        cfg, st = self.cfg, self.state
        if cfg.online and cfg.device_sim:  # rendered and simulated here: no loader processes
            from spikejdd.train.device_sim import DeviceBatches

            yield from DeviceBatches(cfg.batch_size, cfg.crop, self.mcfg.n_readouts, cfg.seed,
                                     self.device, start_step=st.step, rank=self.rank,
                                     world=self.world)
            return
        if cfg.online:
            from spikejdd.train.online import OnlineSpikeDataset

            ds = OnlineSpikeDataset(cfg.batch_size, cfg.crop, self.mcfg.n_readouts, cfg.seed,
                                    start_step=st.step, rank=self.rank, world=self.world,
                                    clips=cfg.clips, clip_fraction=cfg.clip_fraction)
            if cfg.workers > 0:  # compiled here once, loaded by every worker from the cache
                from spikesim.families import is_compiled
                from spikesim.precompile import precompile

                precompile([f for f in ("noise-free", "paper") if not is_compiled(f)])
            yield from self._loader(ds, batch_size=None)
            return
        while True:
            self.train_ds.set_epoch(st.epoch)
            sampler = EpochSampler(len(self.train_ds), cfg.seed, st.epoch, self.rank,
                                   self.world, skip=st.in_epoch * cfg.batch_size)
            yield from self._loader(self.train_ds, batch_size=cfg.batch_size, sampler=sampler,
                                    drop_last=True)
            st.epoch += 1
            st.in_epoch = 0

    # --- the three operations ----------------------------------------------------
    def step(self, batch: dict) -> float:
        """One optimisation step on ``batch``; returns the loss."""
        cfg = self.cfg
        nb = self.device.type == "cuda"
        spikes = batch["spikes"].to(self.device, non_blocking=nb)
        mask = batch["mask"].to(self.device, non_blocking=nb)
        gt = batch["gt"].to(self.device, non_blocking=nb)
        if cfg.channels_last:
            spikes = spikes.contiguous(memory_format=torch.channels_last)
        with self.autocast:
            rgb, nmap = self.net(spikes, mask)
        loss = F.mse_loss(rgb.float(), gt)
        if cfg.noise_weight > 0:
            loss = loss + cfg.noise_weight * F.mse_loss(
                nmap.float(), noise_map_target(batch["meta"], gt))
        self.optimizer.zero_grad(set_to_none=True)
        self.scaler.scale(loss).backward()
        self.scaler.step(self.optimizer)
        self.scaler.update()
        self.scheduler.step()
        self.state.step += 1
        self.state.in_epoch += 1
        return float(loss.detach())

    def validation_frames(self) -> list:
        if self._val_frames is None:
            from spikejdd.train.validation import validation_frames

            c = self.cfg
            # device simulation: the sweep too is simulated with torch (no numba kernels)
            sim = {"backend": "torch", "device": self.device} if c.device_sim else {}
            self._val_frames = validation_frames(c.val_size, c.val_speeds, c.val_levels,
                                                 context=self.mcfg.n_readouts + 2, **sim)
        return self._val_frames

    def validate(self) -> dict:
        """Validation PSNR (dB, linear) on the sweep or the evaluation files."""
        if self.cfg.validation_kind() == "files":
            return evaluate_psnr(self.model, self.eval_ds, self.device, self.cfg.eval_frames)
        from spikejdd.train.validation import validate_model

        res = validate_model(self.model, self.validation_frames(), self.device)
        res.pop("rows")
        return res

    def bench(self, sjdd: dict | None = None) -> dict | None:
        """The chunk's benchmark row (sweep validation only): sjdd minus best classical, dB."""
        if self.cfg.validation_kind() != "sweep" or not self.cfg.bench_methods:
            return None
        from spikejdd.train.validation import (
            bench_row,
            classical_scores,
            validate_model,
            validation_pictures,
        )

        cache = self.out / "val_classical.json"
        key = json.dumps({"size": list(self.cfg.val_size), "speeds": list(self.cfg.val_speeds),
                          "levels": self.cfg.val_levels, "methods": self.cfg.bench_methods,
                          "window": self.mcfg.n_readouts, "pictures": validation_pictures()})
        classical = None
        if cache.exists():
            blob = json.loads(cache.read_text())
            classical = blob["scores"] if blob.get("key") == key else None
        if classical is None:
            classical = classical_scores(self.validation_frames(), self.cfg.bench_methods)
            for v in classical.values():
                v.pop("rows")
            cache.write_text(json.dumps({"key": key, "scores": classical}))
        sjdd = sjdd or validate_model(self.model, self.validation_frames(), self.device)
        return bench_row(self.state.step, sjdd, classical)

    def save(self, name: str, eval_result: dict | None = None, resumable: bool = True) -> Path:
        """Write ``<out>/<name>``: weights, state, data, seed and — when ``resumable`` — the
        optimizer and scheduler (``best.pt`` is written without them: a third of the size)."""
        st = self.state
        tr = dict(st.to_dict(), train_config=json.dumps(asdict(self.cfg), default=str))
        if resumable:
            tr.update(optimizer=self.optimizer.state_dict(),
                      scheduler=self.scheduler.state_dict())
        return save_checkpoint(self.out / name, self.model, data=self.data_desc,
                               seed=self.cfg.seed,
                               eval=eval_result or (st.history[-1] if st.history else {}),
                               train=tr)

    def resume(self, path: str | os.PathLike) -> None:
        """Restore weights, optimizer, scheduler and state from checkpoint ``path``."""
        blob = load_checkpoint(path)
        if blob["config"] != self.mcfg.to_dict():
            raise bad_value("resume", str(path), "a checkpoint of the same model configuration "
                            f"({config_difference(blob['config'], self.mcfg.to_dict())}: give "
                            "the --model and --set it was trained with)")
        tr = blob.get("train") or {}
        changed = self.cfg.resume_differences(json.loads(tr.get("train_config") or "{}"))
        if changed:  # the optimizer and data order would silently keep the run's own
            raise bad_value("resume", str(path), "the run's own settings, and these differ: "
                            + ", ".join(changed) + " (its run.json lists them; a new --out "
                            "starts a new run)")
        self.model.load_state_dict(blob["state_dict"])
        if "optimizer" in tr:
            self.optimizer.load_state_dict(tr["optimizer"])
            self.scheduler.load_state_dict(tr["scheduler"])
        self.state = TrainState.from_checkpoint(tr)

    def initialise(self, weights: str) -> None:
        """Start from the weights of ``weights`` (a shipped name or a checkpoint path) with
        a fresh optimizer, schedule and state: fine-tuning, not resuming."""
        path = resolve_weights(weights)
        blob = load_checkpoint(path)
        if blob["config"] != self.mcfg.to_dict():
            raise bad_value("init", str(weights), "weights of the same model configuration "
                            f"as --model {self.cfg.model} and its --set overrides "
                            f"({config_difference(blob['config'], self.mcfg.to_dict())})")
        self.model.load_state_dict(blob["state_dict"])

    def resume_path(self) -> str | None:
        r = self.cfg.resume
        if r == "auto":
            return str(self.out / "last.pt") if (self.out / "last.pt").exists() else None
        return r

    def close(self) -> None:
        if self.distributed:
            dist.barrier()
            dist.destroy_process_group()

    def over_time(self, t_start: float) -> bool:
        """Whether ``time_limit_min`` minutes have passed since ``t_start`` (``time.time()``,
        seconds; the start of the call); under DDP every rank gets the same answer."""
        lim = self.cfg.time_limit_min
        over = lim is not None and time.time() - t_start > 60 * lim
        if self.distributed and lim is not None:  # every rank stops together
            flag = torch.tensor([float(over)], device=self.device)
            dist.all_reduce(flag, op=dist.ReduceOp.MAX)
            over = bool(flag.item())
        return over

