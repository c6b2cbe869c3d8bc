"""The settings of a training run (:class:`TrainConfig`) and the authors' schedule.

**Schedule (default).** The authors' ``train.py`` (github.com/csycdong/SJDD-Net):
Adam, learning rate ``5e-4``, ``StepLR(step_size=50, gamma=0.8)`` stepped once
per *epoch*, batch 8, 64×64 patches.  We step the scheduler per optimisation
step, so the decay interval is ``lr_step_epochs`` (50) × the steps in an epoch:
``len(files dataset) // (batch · processes)`` for a file dataset, and
``epoch_steps`` (240, the authors' epoch as measured from their log: ×0.8
about every 12,000 steps) for data simulated in the loader, which has no
epochs.  ``lr_step`` set explicitly overrides both.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, fields
from pathlib import Path

from spikejdd.models.sjdd import DEFAULT, LITE, PUBLISHED, SJDDConfig
from spikesim.errors import bad_value

__all__ = ["TrainConfig", "MODEL_PRESETS", "CLASSICAL", "AUTHORS_LR", "AUTHORS_GAMMA",
           "AUTHORS_LR_STEP_EPOCHS", "AUTHORS_EPOCH_STEPS"]

MODEL_PRESETS = {"default": DEFAULT, "lite": LITE, "published": PUBLISHED}
#: The authors' schedule (see the module doc).
AUTHORS_LR, AUTHORS_GAMMA, AUTHORS_LR_STEP_EPOCHS, AUTHORS_EPOCH_STEPS = 5e-4, 0.8, 50, 240
#: Classical pipelines each chunk's benchmark row compares against.
CLASSICAL = ["tfp+malvar2004", "tfp+menon2007", "tfp+menon2007+bilateral", "tfp+menon2007+nlm"]


#: Settings a resumed run may change: how long, where and how fast it runs, not what it
#: learns from or how (the model's own fields are checked with its configuration).
RESUME_MAY_CHANGE = frozenset({
    "steps", "time_limit_min", "resume", "init", "out", "device", "workers", "threads",
    "progress", "amp", "channels_last", "eval_every", "checkpoint_every", "log_every",
    "model", "model_overrides"})
#: Settings that are paths: compared as resolved paths.
_PATH_FIELDS = ("data", "eval_data")


def _comparable(name: str, value):
    """``value`` of setting ``name`` as it compares across calls (paths resolved, JSON types)."""
    if name in _PATH_FIELDS and value:
        return str(Path(value).resolve())
    if name == "clips":
        return [str(Path(c).resolve()) for c in value]
    return json.loads(json.dumps(value, default=str))


@dataclass
class TrainConfig:
    """Every setting of a run (written to ``run.json``; a JSON file of these keys is a
    valid ``--config``)."""

    data: str = ""  # HDF5 file/folder; unused with online=True
    online: bool = False  # simulate every sample in the data loader (spikejdd.train.online)
    device_sim: bool = False  # online samples rendered and simulated on the training device
    clips: list = field(default_factory=list)  # video files/frame folders for online samples
    clip_fraction: float = 0.25  # share of online samples cut from clips (when clips given)
    out: str = "runs/sjdd"
    eval_data: str | None = None
    validation: str = "auto"  # "files" (eval_data or data), "sweep", "auto": sweep when online
    val_size: list = field(default_factory=lambda: [48, 64])  # validation frame (H, W)
    val_speeds: list = field(default_factory=lambda: [0.0, 150.0, 1500.0, 3000.0])  # px/s
    val_levels: list | None = None  # noise labels of the sweep (None: GN0/5/10/15, GPN-rand)
    bench_methods: list = field(default_factory=lambda: list(CLASSICAL))
    model: str = "default"  # a preset of MODEL_PRESETS
    model_overrides: dict = field(default_factory=dict)  # SJDDConfig fields to change
    steps: int = 10_000
    batch_size: int = 8
    crop: int = 64
    flips: bool = True
    lr: float = AUTHORS_LR
    lr_step: int | None = None  # None: lr_step_epochs × steps per epoch
    lr_step_epochs: int = AUTHORS_LR_STEP_EPOCHS
    epoch_steps: int = AUTHORS_EPOCH_STEPS  # a nominal epoch of online data, steps
    gamma: float = AUTHORS_GAMMA
    noise_weight: float = 0.0
    eval_every: int = 500
    eval_frames: int = 12
    checkpoint_every: int = 500
    log_every: int = 10
    seed: int = 0
    workers: int = 0
    device: str = "auto"
    threads: int | None = None  # torch intra-op CPU threads (1 is fastest on a busy 2-core box)
    channels_last: bool = False
    amp: bool = True
    time_limit_min: float | None = None
    resume: str | None = None  # a checkpoint path, or "auto" = <out>/last.pt when present
    init: str | None = None  # weights to start from (shipped name or checkpoint); not on resume
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

    def resume_differences(self, saved: dict) -> list[str]:
        """The settings that differ from ``saved`` (the ``train_config`` a checkpoint
        holds) among those a resumed run may not change (not in
        :data:`RESUME_MAY_CHANGE`): ``["crop=48 (the run has 64)", …]``.  A setting
        that has no effect in either run (:meth:`unused_settings`) may differ, and
        ``validation`` is compared as the kind it resolves to ("auto" is "sweep" online)."""
        known = {f.name for f in fields(self)}
        theirs = TrainConfig(**{k: v for k, v in saved.items() if k in known})
        unused = self.unused_settings() & theirs.unused_settings()
        out = []
        for f in fields(self):
            if f.name in RESUME_MAY_CHANGE or f.name in unused or f.name not in saved:
                continue
            if f.name == "validation" and self.validation_kind() == theirs.validation_kind():
                continue
            mine = _comparable(f.name, getattr(self, f.name))
            if mine != _comparable(f.name, saved[f.name]):
                out.append(f"{f.name}={getattr(self, f.name)!r} (the run has {saved[f.name]!r})")
        return out

    def unused_settings(self) -> set[str]:
        """The settings that have no effect given the others: the epoch the step decay
        counts in (``lr_step_epochs``, ``epoch_steps``) under an explicit ``lr_step``;
        ``epoch_steps`` and the clips with file data; ``clip_fraction`` without clips;
        ``flips`` online (every sample is drawn afresh); the sweep's settings under
        validation on files, and the files' under the sweep."""
        out = set()
        if self.lr_step is not None:
            out |= {"lr_step_epochs", "epoch_steps"}
        if self.online:
            out.add("flips")
        else:
            out |= {"epoch_steps", "clips", "clip_fraction"}
        if self.device_sim:  # no loader processes, no clips
            out |= {"workers", "clips", "clip_fraction"}
        if not self.clips:
            out.add("clip_fraction")
        if self.validation_kind() == "files":
            out |= {"val_size", "val_speeds", "val_levels", "bench_methods"}
        else:
            out |= {"eval_data", "eval_frames"}
        return out

    def validation_kind(self) -> str:
        """``"files"`` or ``"sweep"`` (``"auto"`` resolved)."""
        if self.validation == "auto":
            return "sweep" if self.online else "files"
        return self.validation

    def lr_step_for(self, steps_per_epoch: int) -> int:
        """The decay interval in steps (see the module doc)."""
        if self.lr_step is not None:
            return self.lr_step
        return max(1, self.lr_step_epochs * max(1, int(steps_per_epoch)))

    def validate(self) -> None:
        if not self.data and not self.online:
            raise bad_value("data", self.data, "a spikesim HDF5 file or folder (or online=True)")
        if Path(self.out).exists() and not Path(self.out).is_dir():
            raise bad_value("out", str(self.out), "a run folder, not an existing file")
        for name in ("steps", "batch_size", "crop", "eval_every", "checkpoint_every",
                     "log_every", "eval_frames", "lr_step_epochs", "epoch_steps"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise bad_value(name, v, "an integer >= 1")
        if self.lr_step is not None and (isinstance(self.lr_step, bool) or
                                         not isinstance(self.lr_step, int) or self.lr_step < 1):
            raise bad_value("lr_step", self.lr_step, "an integer >= 1 (or unset: 50 epochs)")
        if not 0.0 <= self.clip_fraction <= 1.0:
            raise bad_value("clip_fraction", self.clip_fraction, "a fraction in [0, 1]")
        if self.online and self.data and not (self.validation == "files"
                                              and self.eval_data is None):
            raise bad_value("data", self.data, "None with online (online training simulates "
                            "every sample; --eval-data DIR with --validation files validates "
                            "on files)")
        if self.device_sim and not self.online:
            raise bad_value("device_sim", self.device_sim, "False without online (the device "
                            "simulates online samples: --online --device-sim)")
        if self.device_sim and self.clips:
            raise bad_value("clips", self.clips, "none with device_sim (clips are decoded and "
                            "simulated in loader processes: leave out --device-sim)")
        for c in self.clips:
            if not Path(c).exists():
                raise bad_value("clips", c, "existing video files or frame folders")
        if self.validation not in ("auto", "files", "sweep"):
            raise bad_value("validation", self.validation, "'auto', 'files' or 'sweep'")
        if self.validation_kind() == "files" and not (self.eval_data or self.data):
            raise bad_value("validation", self.validation, "'sweep' when there is no --data")
        try:
            h, w = (int(v) for v in self.val_size)
        except (TypeError, ValueError):
            raise bad_value("val_size", self.val_size, "[height, width] in pixels") from None
        if h < 12 or w < 12 or h % 2 or w % 2:  # SSIM-gauss11 needs 11 pixels
            raise bad_value("val_size", self.val_size, "even sizes >= 12 pixels")
        if not self.val_speeds or any(not (float(s) >= 0) for s in self.val_speeds):
            raise bad_value("val_speeds", self.val_speeds, "one or more speeds >= 0 px/s")
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
