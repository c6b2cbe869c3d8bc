"""Training SJDD-Net: ``spikejdd train`` (``--online`` or ``--data DIR``) or :func:`train`.

Split after BasicSR: :mod:`~spikejdd.train.run` (the thin :func:`train`
entry), :mod:`~spikejdd.train.trainer` (:class:`Trainer`: ``step``,
``validate``, ``save``, ``resume``), :mod:`~spikejdd.train.state`
(:class:`TrainState`), :mod:`~spikejdd.train.config` (:class:`TrainConfig` and
the authors' schedule), :mod:`~spikejdd.train.online` (simulation inside the
data loader), :mod:`~spikejdd.train.scenes`,
:mod:`~spikejdd.train.pictures` and :mod:`~spikejdd.train.content` (what the
model trains on: pictures, dead leaves, textures, exposure),
:mod:`~spikejdd.train.validation` (the Table-1-shaped validation sweep and
each chunk's benchmark row), :mod:`~spikejdd.train.synthesis` (a fixed set
on disk), :mod:`~spikejdd.train.workers` (loader workers that die with the
training process) and :mod:`~spikejdd.train.export` (shippable weights).
"""

from spikejdd.train.config import MODEL_PRESETS, TrainConfig
from spikejdd.train.export import export_weights
from spikejdd.train.pictures import TEST_PICTURES, TRAIN_PICTURES, VALIDATION_PICTURES
from spikejdd.train.run import train
from spikejdd.train.state import TrainState
from spikejdd.train.synthesis import synthesize
from spikejdd.train.trainer import EpochSampler, Trainer, evaluate_psnr, noise_map_target

__all__ = ["TrainConfig", "train", "synthesize", "MODEL_PRESETS", "noise_map_target",
           "EpochSampler", "evaluate_psnr", "export_weights", "Trainer", "TrainState",
           "TRAIN_PICTURES", "TEST_PICTURES", "VALIDATION_PICTURES"]
