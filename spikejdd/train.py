"""Training SJDD-Net: ``spikejdd train --data DIR`` (or ``--config run.json``).

* Data: :class:`spikejdd.data.SpikeWindowDataset` over spikesim HDF5 files —
  random crops (``crop``, 64 by default) at any offset with the crop's true
  Bayer phase, random flips, windows of ``n_readouts`` around each GT readout.
* Loss: L2 on linear RGB plus ``noise_weight`` × L2 of the noise map against
  its target ``sqrt(σ_g² + σ_p²·y)/255`` (y = the GT's mean over colours in
  8-bit DN; the published ``σ/255`` for Gaussian noise).
* Adam (``lr`` 5e-4) with step decay (``gamma`` every ``lr_step`` steps), batch 8.
* Determinism: one ``seed`` fixes the initial weights, the sample order
  (a permutation per epoch from ``(seed, epoch)``) and every crop/flip
  (``SpikeWindowDataset`` draws from ``(seed, epoch, index)``); it is written
  to ``run.json`` and into every checkpoint.  Resuming restores the model,
  optimizer, scheduler and position in the epoch, so an interrupted run ends
  with the same weights as an uninterrupted one (tested).
* Periodic evaluation (PSNR, linear light) on ``eval_data`` (or the training
  files' centred full frames), checkpoints ``last.pt`` / ``best.pt``, a
  ``log.jsonl``, and a tqdm bar with loss and throughput.
* CPU or CUDA; several GPUs through ``torchrun --nproc_per_node N -m
  spikejdd.cli train ...`` (torch DistributedDataParallel, one process per
  GPU, gloo on CPU); bfloat16/float16 autocast on CUDA (``amp``), with the
  deformable convolution and the HQS update kept in float32.

:func:`synthesize` writes a small procedural training set with
``spikesim.simulate`` + ``spikesim.io.write_h5`` (pictures and motions kept
apart from the evaluation sweep's scenes; noise: GN σ ~ U(0, 15) or GPN
σ_g, σ_p ~ U(0, 5) DN per sequence).
"""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import numpy as np
import torch
import torch.distributed as dist
import torch.nn.functional as F
from tqdm import tqdm

from spikejdd.models.checkpoints import load_checkpoint, save_checkpoint
from spikejdd.models.sjdd import DEFAULT, LITE, PUBLISHED, SJDDConfig, SJDDNet, count_parameters
from spikesim.errors import SpikeSimTypeError, bad_value

__all__ = ["TrainConfig", "train", "synthesize", "MODEL_PRESETS", "noise_map_target",
           "EpochSampler", "evaluate_psnr"]

MODEL_PRESETS = {"default": DEFAULT, "lite": LITE, "published": PUBLISHED}


@dataclass
class TrainConfig:
    """Every setting of a run (written to ``run.json``; a JSON file of these keys is a
    valid ``--config``)."""

    data: str = ""
    out: str = "runs/sjdd"
    eval_data: str | None = None
    model: str = "default"  # a preset of MODEL_PRESETS
    model_overrides: dict = field(default_factory=dict)  # SJDDConfig fields to change
    steps: int = 10_000
    batch_size: int = 8
    crop: int = 64
    flips: bool = True
    lr: float = 5e-4
    lr_step: int = 2_000
    gamma: float = 0.8
    noise_weight: float = 0.0
    eval_every: int = 500
    eval_frames: int = 12
    checkpoint_every: int = 500
    log_every: int = 10
    seed: int = 0
    workers: int = 0
    device: str = "auto"
    threads: int | None = None  # torch intra-op CPU threads (1 is fastest on a busy 2-core box)
    amp: bool = True
    time_limit_min: float | None = None
    resume: str | None = None  # a checkpoint path, or "auto" = <out>/last.pt when present
    progress: bool = True

    def model_config(self) -> SJDDConfig:
        if self.model not in MODEL_PRESETS:
            raise bad_value("model", self.model, f"one of {sorted(MODEL_PRESETS)}")
        return MODEL_PRESETS[self.model].replace(**dict(self.model_overrides))

    @classmethod
    def from_dict(cls, d: dict) -> TrainConfig:
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise bad_value("train config keys", unknown, f"names among {sorted(known)}")
        return cls(**d)

    def validate(self) -> None:
        if not self.data:
            raise bad_value("data", self.data, "a spikesim HDF5 file or folder")
        for name in ("steps", "batch_size", "crop", "lr_step", "eval_every", "checkpoint_every",
                     "log_every", "eval_frames"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise bad_value(name, v, "an integer >= 1")
        if self.threads is not None and (isinstance(self.threads, bool) or
                                         not isinstance(self.threads, int) or self.threads < 1):
            raise bad_value("threads", self.threads, "an integer >= 1 (or unset: torch's choice)")
        if isinstance(self.workers, bool) or not isinstance(self.workers, int) or self.workers < 0:
            raise bad_value("workers", self.workers, "an integer >= 0 (data-loader processes)")
        if self.time_limit_min is not None and not (self.time_limit_min > 0):
            raise bad_value("time_limit_min", self.time_limit_min, "minutes > 0 (or unset)")
        if not (self.lr > 0 and 0 < self.gamma <= 1 and self.noise_weight >= 0):
            raise bad_value("lr/gamma/noise_weight", (self.lr, self.gamma, self.noise_weight),
                            "lr > 0, 0 < gamma <= 1, noise_weight >= 0")


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


def _device(name: str, local_rank: int) -> torch.device:
    if name == "auto":
        return torch.device(f"cuda:{local_rank}" if torch.cuda.is_available() else "cpu")
    dev = torch.device(name)
    if dev.type == "cuda" and not torch.cuda.is_available():
        raise bad_value("device", name, "'cpu' or 'auto' (no CUDA device here)")
    return dev


def _to(batch: dict, device) -> dict:
    return {k: (v.to(device, non_blocking=True) if isinstance(v, torch.Tensor) else v)
            for k, v in batch.items()}


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


def _autocast(device: torch.device, enabled: bool):
    if device.type == "cuda" and enabled:  # pragma: no cover - CUDA only
        dtype = torch.bfloat16 if torch.cuda.is_bf16_supported() else torch.float16
        return torch.autocast("cuda", dtype=dtype), dtype
    return torch.autocast("cpu", enabled=False), None


def train(cfg: TrainConfig | dict) -> dict:
    """Run (or resume) a training run; returns the final summary (also in ``run.json``)."""
    from spikejdd.data import SpikeWindowDataset

    if isinstance(cfg, dict):
        cfg = TrainConfig.from_dict(cfg)
    if not isinstance(cfg, TrainConfig):
        raise SpikeSimTypeError(f"cfg must be a TrainConfig or dict, got {type(cfg).__name__}")
    cfg.validate()
    world = int(os.environ.get("WORLD_SIZE", "1"))
    rank = int(os.environ.get("RANK", "0"))
    local_rank = int(os.environ.get("LOCAL_RANK", "0"))
    device = _device(cfg.device, local_rank)
    if cfg.threads:
        torch.set_num_threads(int(cfg.threads))
    distributed = world > 1
    if distributed:
        if device.type == "cuda":  # pragma: no cover - multi-GPU only
            torch.cuda.set_device(device)
        dist.init_process_group("nccl" if device.type == "cuda" else "gloo")
    main_proc = rank == 0
    out = Path(cfg.out)
    if main_proc:
        out.mkdir(parents=True, exist_ok=True)

    mcfg = cfg.model_config()
    torch.manual_seed(cfg.seed)
    model = SJDDNet(mcfg).to(device)
    optimizer = torch.optim.Adam(model.parameters(), lr=cfg.lr)
    scheduler = torch.optim.lr_scheduler.StepLR(optimizer, step_size=cfg.lr_step, gamma=cfg.gamma)
    step, epoch, in_epoch, best, history = 0, 0, 0, -math.inf, []

    resume = cfg.resume
    if resume == "auto":
        resume = str(out / "last.pt") if (out / "last.pt").exists() else None
    if resume:
        blob = load_checkpoint(resume)
        if blob["config"] != mcfg.to_dict():
            raise bad_value("resume", resume, "a checkpoint of the same model configuration")
        model.load_state_dict(blob["state_dict"])
        tr = blob.get("train") or {}
        if "optimizer" in tr:
            optimizer.load_state_dict(tr["optimizer"])
            scheduler.load_state_dict(tr["scheduler"])
        step, epoch, in_epoch = int(tr.get("step", 0)), int(tr.get("epoch", 0)), \
            int(tr.get("in_epoch", 0))
        best = float(tr.get("best_psnr", -math.inf))
        history = list(tr.get("history", []))

    train_ds = SpikeWindowDataset(cfg.data, window=mcfg.n_readouts, crop=cfg.crop, train=True,
                                  flips=cfg.flips, seed=cfg.seed)
    eval_ds = SpikeWindowDataset(cfg.eval_data or cfg.data, window=mcfg.n_readouts, crop=None,
                                 train=False) if main_proc else None
    data_desc = {"train": str(cfg.data), "eval": str(cfg.eval_data or cfg.data),
                 "train_samples": len(train_ds), "sequences": len(train_ds._infos),
                 "noise": sorted({f"{i.noise[0]}" for i in train_ds._infos.values()}),
                 "sigma_g_range": _range([i.noise[1] for i in train_ds._infos.values()]),
                 "sigma_p_range": _range([i.noise[2] for i in train_ds._infos.values()]),
                 "crop": cfg.crop, "flips": cfg.flips}
    info_path = Path(cfg.data) / "synth.json" if Path(cfg.data).is_dir() else None
    if info_path is not None and info_path.exists():
        data_desc["synthesis"] = json.loads(info_path.read_text())

    net = model
    if distributed:
        from torch.nn.parallel import DistributedDataParallel as DDP

        net = DDP(model, device_ids=[device.index] if device.type == "cuda" else None)
    scaler_needed = False
    ctx, amp_dtype = _autocast(device, cfg.amp)
    if amp_dtype == torch.float16:  # pragma: no cover - CUDA only
        scaler_needed = True
    scaler = torch.amp.GradScaler("cuda", enabled=scaler_needed)

    run_info = {"config": asdict(cfg), "model_config": mcfg.to_dict(),
                "parameters": count_parameters(model), "seed": cfg.seed, "world_size": world,
                "device": str(device), "amp": str(amp_dtype), "data": data_desc,
                "torch": str(torch.__version__)}
    if main_proc:
        (out / "run.json").write_text(json.dumps(run_info, indent=1, default=str))

    def save(name: str, eval_result: dict | None = None):
        tr = {"step": step, "epoch": epoch, "in_epoch": in_epoch, "best_psnr": best,
              "optimizer": optimizer.state_dict(), "scheduler": scheduler.state_dict(),
              "history": history, "train_config": json.dumps(asdict(cfg), default=str)}
        save_checkpoint(out / name, model, data=data_desc, seed=cfg.seed,
                        eval=eval_result or (history[-1] if history else {}), train=tr)

    t_start = time.time()
    per_rank = len(train_ds) // world
    if per_rank < cfg.batch_size:
        raise bad_value("batch_size", cfg.batch_size,
                        f"at most the samples per process ({per_rank})")
    bar = tqdm(total=cfg.steps, initial=step, desc="train", disable=not (main_proc and
                                                                        cfg.progress))
    model.train()
    running, seen, t_last = None, 0, time.time()
    stop = False
    while step < cfg.steps and not stop:
        train_ds.set_epoch(epoch)
        sampler = EpochSampler(len(train_ds), cfg.seed, epoch, rank, world,
                               skip=in_epoch * cfg.batch_size)
        loader = torch.utils.data.DataLoader(
            train_ds, batch_size=cfg.batch_size, sampler=sampler, drop_last=True,
            num_workers=cfg.workers, pin_memory=device.type == "cuda",
            multiprocessing_context="spawn" if cfg.workers > 0 else None)
        for batch in loader:
            batch = _to(batch, device)
            spikes, mask, gt = batch["spikes"], batch["mask"], batch["gt"]
            with ctx:
                rgb, nmap = net(spikes, mask)
            loss = F.mse_loss(rgb.float(), gt)
            if cfg.noise_weight > 0:
                loss = loss + cfg.noise_weight * F.mse_loss(
                    nmap.float(), noise_map_target(batch["meta"], gt))
            optimizer.zero_grad(set_to_none=True)
            scaler.scale(loss).backward()
            scaler.step(optimizer)
            scaler.update()
            scheduler.step()
            step += 1
            in_epoch += 1
            seen += spikes.shape[0] * world
            lv = float(loss.detach())
            running = lv if running is None else 0.9 * running + 0.1 * lv
            if main_proc and step % cfg.log_every == 0:
                now = time.time()
                bar.set_postfix(loss=f"{running:.2e}", psnr=f"{-10 * math.log10(running):.2f}",
                                samples_s=f"{seen / max(now - t_last, 1e-9):.1f}",
                                lr=f"{scheduler.get_last_lr()[0]:.1e}")
                seen, t_last = 0, now
            bar.update(1)
            over_time = (cfg.time_limit_min is not None
                         and time.time() - t_start > 60 * cfg.time_limit_min)
            if distributed and cfg.time_limit_min is not None:  # every rank stops together
                flag = torch.tensor([float(over_time)], device=device)
                dist.all_reduce(flag, op=dist.ReduceOp.MAX)
                over_time = bool(flag.item())
            last = step >= cfg.steps or over_time
            if main_proc and (step % cfg.eval_every == 0 or last):
                res = evaluate_psnr(model, eval_ds, device, cfg.eval_frames)
                res.update(step=step, train_loss=running, minutes=(time.time() - t_start) / 60,
                           lr=scheduler.get_last_lr()[0])
                history.append(res)
                with open(out / "log.jsonl", "a") as fh:
                    fh.write(json.dumps(res) + "\n")
                bar.write(f"step {step}: eval PSNR {res['psnr_linear']:.2f} dB "
                          f"(train loss {running:.3e})")
                if res["psnr_linear"] > best:
                    best = res["psnr_linear"]
                    save("best.pt", res)
            if main_proc and (step % cfg.checkpoint_every == 0 or last):
                save("last.pt")
            if last:
                stop = over_time or step >= cfg.steps
                break
        else:
            epoch += 1
            in_epoch = 0
            continue
        if stop or step >= cfg.steps:
            break
    bar.close()
    summary = dict(run_info, steps_done=step, best_psnr=best, history=history,
                   minutes=(time.time() - t_start) / 60)
    if main_proc:
        (out / "run.json").write_text(json.dumps(summary, indent=1, default=str))
    if distributed:
        dist.barrier()
        dist.destroy_process_group()
    return summary


def _range(values) -> list[float]:
    return [float(min(values)), float(max(values))] if values else []


# --- procedural training data ----------------------------------------------
#: Pictures for training (none of the evaluation sweep's: astronaut, coffee, chelsea).
TRAIN_PICTURES = ("rocket", "hubble_deep_field", "immunohistochemistry", "colorwheel", "retina",
                  "grass", "gravel", "brick", "moon", "coins", "clock", "camera")
TRAIN_MOTIONS = ("pan", "rotation", "zoom", "shake", "homography")


def _picture(name: str, rng: np.random.Generator) -> np.ndarray:
    """A training picture as linear float RGB with a random colour mix (grey ones get colour)."""
    import skimage.data

    img = np.asarray(getattr(skimage.data, name)(), dtype=np.float64)
    if img.max() > 1.0:
        img = img / 255.0
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    img = img[..., :3]
    lin = np.where(img <= 0.04045, img / 12.92, ((img + 0.055) / 1.055) ** 2.4)
    mix = np.eye(3) * rng.uniform(0.5, 1.0, 3) + rng.uniform(0.0, 0.35, (3, 3))
    lin = lin @ mix.T
    lin = lin / max(np.percentile(lin, 99.5), 1e-6) * rng.uniform(0.6, 1.0)
    return np.clip(lin, 0.0, 1.0).astype(np.float32)


def _scene(rng: np.random.Generator, size: tuple[int, int]):
    from spikesim.scenes.analytic import ProceduralScene, SplineTexture
    from spikesim.scenes.paths import make_path, peak_speed_per_phase
    from spikesim.scenes.picture import MovingPicture
    from spikesim.scenes.sources import cover_resize

    name = str(rng.choice(TRAIN_PICTURES))
    motion = str(rng.choice(TRAIN_MOTIONS))
    speed = float(rng.uniform(100.0, 1500.0))
    direction = float(rng.uniform(0.0, 360.0))
    picture = _picture(name, rng)

    class _Picture(MovingPicture):
        """A MovingPicture over an in-memory picture (training only)."""

        def __init__(self):
            ProceduralScene.__init__(self, size, exposure=1.0, max_px=1.0)
            self.name, self.motion, self.direction_deg = name, motion, direction
            self._path, period = make_path(motion, self.height, self.width, direction)
            self._picture = cover_resize(picture, (self.height, self.width))
            self._texture = SplineTexture(self._picture)
            self.rate = speed / peak_speed_per_phase(self._path, period, self.height, self.width)
            self._set_speed(speed)
            rows, cols = np.mgrid[0:self.height, 0:self.width].astype(np.float64)
            self._grid = np.stack([cols.ravel(), rows.ravel(), np.ones(rows.size)])

    return _Picture(), {"picture": name, "motion": motion, "speed_px_s": speed,
                        "direction_deg": direction}


def synthesize(out_dir, n_sequences: int = 96, sizes=((64, 96), (96, 128)),
               n_readouts: int = 99, gt_every: int = 6, window: int = 39, seed: int = 1234,
               progress: bool = True) -> dict:
    """Write ``n_sequences`` procedural HDF5 sequences to ``out_dir`` (see the module doc).

    Each sequence: RGGB, 20 kHz, full_scale_rate 0.6, modulo reset; GT every
    ``gt_every`` readouts wherever a ``window``-readout window fits.  Half the
    sequences get Gaussian noise σ ~ U(0, 15) DN, half Gaussian–Poisson σ_g,
    σ_p ~ U(0, 5) DN (the paper's ranges).  Returns the description (also
    written to ``synth.json``).
    """
    import spikesim as ss

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    half = window // 2
    gts = list(range(half, n_readouts - (window - half) + 1, gt_every))
    if not gts:
        raise bad_value("n_readouts", n_readouts, f"at least window = {window}")
    seqs = []
    for i in tqdm(range(n_sequences), desc="synthesize", disable=not progress):
        size = tuple(int(v) for v in sizes[int(rng.integers(len(sizes)))])
        scene, desc = _scene(rng, size)
        if i % 2 == 0:
            sg, sp = float(rng.uniform(0, 15)), 0.0
        else:
            sg, sp = float(rng.uniform(0, 5)), float(rng.uniform(0, 5))
        noise = ss.noise.PaperNoise(sigma_g=sg, sigma_p=sp) if (sg or sp) else None
        sensor = ss.Sensor(height=size[0], width=size[1], cfa="RGGB", clock_hz=20_000.0,
                           full_scale_rate=0.6, noise=noise)
        stream = ss.simulate(scene, sensor, n_readouts=n_readouts, seed=seed + i,
                             gt_readouts=gts)
        ss.io.write_h5(out / f"seq{i:04d}.h5", stream)
        seqs.append(dict(desc, file=f"seq{i:04d}.h5", size=list(size), sigma_g=sg, sigma_p=sp))
    info = {"generator": "spikejdd.train.synthesize", "seed": seed, "n_sequences": n_sequences,
            "n_readouts": n_readouts, "gt_readouts": gts, "window": window,
            "sensor": "RGGB, 20 kHz, full_scale_rate 0.6, modulo reset, paper noise",
            "noise": "GN sigma~U(0,15) (even sequences) / GPN sigma_g,sigma_p~U(0,5) (odd)",
            "pictures": list(TRAIN_PICTURES), "motions": list(TRAIN_MOTIONS),
            "speed_px_s": [100.0, 1500.0], "sequences": seqs}
    (out / "synth.json").write_text(json.dumps(info, indent=1))
    return info


def export_weights(checkpoint, dest, eval_result: dict | None = None) -> Path:
    """Write a run checkpoint as a shippable one: weights, configuration, data
    description, seed, training summary and ``eval_result`` — no optimizer state.
    Also writes ``<dest stem>.ref.json``, the reference output of
    :func:`spikejdd.models.reference_input` used by the tests."""
    from spikejdd.models import load_model, write_reference

    blob = load_checkpoint(checkpoint)
    model = load_model(blob)
    tr = blob.get("train") or {}
    summary = {k: tr.get(k) for k in ("step", "epoch", "best_psnr", "history", "train_config")}
    dest = Path(dest)
    save_checkpoint(dest, model, data=blob.get("data"), seed=blob.get("seed"),
                    eval=dict(blob.get("eval") or {}, **(eval_result or {})), train=summary)
    write_reference(model, dest.with_suffix(".ref.json"))
    return dest
