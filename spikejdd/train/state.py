"""Where a run stands (:class:`TrainState`): everything besides weights and optimizer that
exact resume needs, stored under ``train`` in every checkpoint."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

__all__ = ["TrainState"]


@dataclass
class TrainState:
    """Steps done, the epoch and steps into it (file data), the best validation PSNR (dB),
    the validation history (one dict per validation), the training time so far
    (minutes, over every call of a run in chunks), the set-up time so far (minutes
    before each call's first batch: workers, kernel compilation; see
    :func:`spikejdd.train.train`) and the running training loss (the moving average
    the log reports), so a resumed run logs what an uninterrupted one would."""

    step: int = 0
    epoch: int = 0
    in_epoch: int = 0
    best_psnr: float = -math.inf
    history: list = field(default_factory=list)
    minutes: float = 0.0
    setup_minutes: float = 0.0
    running_loss: float | None = None

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_checkpoint(cls, train: dict | None) -> TrainState:
        """From a checkpoint's ``train`` entry (missing keys: a fresh run's values)."""
        tr = train or {}
        return cls(step=int(tr.get("step", 0)), epoch=int(tr.get("epoch", 0)),
                   in_epoch=int(tr.get("in_epoch", 0)),
                   best_psnr=float(tr.get("best_psnr", -math.inf)),
                   history=list(tr.get("history", [])), minutes=float(tr.get("minutes", 0.0)),
                   setup_minutes=float(tr.get("setup_minutes", 0.0)),
                   running_loss=tr.get("running_loss"))
