"""Simulation inside the data loader: every training step sees fresh scenes, noise and motion.

:func:`simulate_sample` draws one scene (:func:`spikejdd.train.scenes.draw_scene`),
a Bayer phase, a noise level and simulates ``window`` readouts with
``spikesim.simulate`` (RGGB-family CFA, 20 kHz, full_scale_rate 0.6, modulo
reset — the evaluation sweep's sensor), recording the exact radiance at the
centre readout as ground truth.  Noise, half the samples each:

* GN: σ_g ~ U(0, 15) DN (the paper's range for Gaussian noise);
* GPN: σ_g, σ_p drawn from ``spikejdd.evaluate.GPN_RANGE`` (the evaluation's
  random-GPN ranges: σ_g ~ U(0, 15), σ_p ~ U(0, 1)).

Everything about sample ``i`` comes from ``numpy.random.default_rng([seed, i])``
(and the simulation seed derived from it), so a sample depends on ``(seed, i)``
only.  :class:`OnlineSpikeDataset` yields whole batches: the batch of step
``s`` on rank ``r`` of ``world`` holds samples ``(s·world + r)·B … + B − 1``.
With ``W`` loader workers, worker ``k`` makes steps ``start + k, start + k + W,
…`` and torch's loader returns them round-robin, i.e. in step order — the
stream is the same for any number of workers and resumes at any step.  Run
the loader with ``multiprocessing_context="spawn"`` (numba's threading layer
does not survive ``fork``).
"""

from __future__ import annotations

import numpy as np
import torch
from torch.utils.data import IterableDataset

from spikesim.cfa import mask_planes
from spikesim.errors import bad_value

__all__ = ["simulate_sample", "collate", "OnlineSpikeDataset", "BAYER_PATTERNS", "draw_noise"]

BAYER_PATTERNS = ("RGGB", "GRBG", "GBRG", "BGGR")


def draw_noise(rng: np.random.Generator) -> tuple[str, float, float]:
    """(mode, σ_g, σ_p) in 8-bit DN: GN σ ~ U(0, 15) or GPN with the evaluation's ranges."""
    from spikejdd.evaluate import GPN_RANGE

    if rng.random() < 0.5:
        return "GN", float(rng.uniform(0.0, 15.0)), 0.0
    return ("GPN", float(rng.uniform(*GPN_RANGE["sigma_g"])),
            float(rng.uniform(*GPN_RANGE["sigma_p"])))


def simulate_sample(seed: int, index: int, crop: int, window: int = 39, clips=(),
                    clip_fraction: float = 0.0) -> dict:
    """Sample ``index`` of the stream ``seed``: ``spikes`` (window, crop, crop) float32 0/1,
    ``mask`` (4, crop, crop), ``gt`` (3, crop, crop) linear RGB and ``meta``.  With
    ``clips`` (video files or frame folders), a ``clip_fraction`` of the samples come
    from them (:mod:`spikejdd.train.clips`)."""
    import spikesim as ss
    from spikejdd.train.clips import draw_clip
    from spikejdd.train.scenes import draw_scene

    rng = np.random.default_rng([int(seed), int(index)])
    if clips and rng.random() < clip_fraction:
        scene, desc = draw_clip(rng, list(clips), (crop, crop))
    else:
        scene, desc = draw_scene(rng, (crop, crop))
    cfa = BAYER_PATTERNS[int(rng.integers(4))]
    mode, sg, sp = draw_noise(rng)
    noise = ss.noise.PaperNoise(sigma_g=sg, sigma_p=sp) if (sg or sp) else None
    sensor = ss.Sensor(height=crop, width=crop, cfa=cfa, clock_hz=20_000.0,
                       full_scale_rate=0.6, noise=noise)
    half = window // 2
    stream = ss.simulate(scene, sensor, n_readouts=window, seed=int(rng.integers(2**31)),
                         gt_readouts=[half])
    spikes = torch.from_numpy(np.ascontiguousarray(stream.unpack(), dtype=np.float32))
    gt = torch.from_numpy(np.ascontiguousarray(np.asarray(stream.gt[0]).transpose(2, 0, 1),
                                               dtype=np.float32))
    meta = dict(desc, content="+".join(desc["content"]), cfa=cfa, noise=mode, sigma_g=sg,
                sigma_p=sp, index=int(index))
    return {"spikes": spikes, "mask": torch.from_numpy(mask_planes(cfa, crop, crop)), "gt": gt,
            "meta": meta}


def collate(samples: list[dict]) -> dict:
    """Stack samples into a batch; numeric ``meta`` fields become tensors, others lists.

    Samples of different kinds carry different fields (a clip sample has its playback
    ``rate``, a procedural one does not): every field of any sample is kept, with None
    where a sample lacks it (then a list)."""
    out = {k: torch.stack([s[k] for s in samples]) for k in ("spikes", "mask", "gt")}
    meta = {}
    for key in dict.fromkeys(k for s in samples for k in s["meta"]):
        vals = [s["meta"].get(key) for s in samples]
        meta[key] = (torch.tensor(vals, dtype=torch.float64)
                     if all(isinstance(v, int | float) for v in vals) else vals)
    out["meta"] = meta
    return out


def _one_thread() -> None:
    """Simulate on one thread in a loader worker: one worker per core already fills the
    machine, and numba's and OpenCV's own pools of one thread per core in each of, say,
    14 workers would oversubscribe a 16-core machine 14 times (the bits do not depend on
    the thread count)."""
    import cv2
    import numba

    numba.set_num_threads(1)
    cv2.setNumThreads(1)


class OnlineSpikeDataset(IterableDataset):
    """Batches simulated on the fly for steps ``start_step, start_step + 1, …`` (see module doc).

    Parameters
    ----------
    batch_size, crop, window : int
        Samples per batch, crop side (pixels, ≥ 2; odd sizes too, as with file data),
        readouts per sample.
    seed : int
        The run's seed.
    start_step : int
        First step to make (resume).
    stop_step : int, optional
        One past the last step (default: endless).
    rank, world : int
        This process's share under DistributedDataParallel.
    """

    def __init__(self, batch_size: int, crop: int, window: int = 39, seed: int = 0,
                 start_step: int = 0, stop_step: int | None = None, rank: int = 0,
                 world: int = 1, clips=(), clip_fraction: float = 0.0):
        for name, v, lo in (("batch_size", batch_size, 1), ("crop", crop, 2),
                            ("window", window, 1), ("start_step", start_step, 0)):
            if isinstance(v, bool) or not isinstance(v, int) or v < lo:
                raise bad_value(name, v, f"an integer >= {lo}")
        if stop_step is not None and stop_step < start_step:
            raise bad_value("stop_step", stop_step, f"None or >= start_step ({start_step})")
        self.batch_size, self.crop, self.window = batch_size, crop, window
        self.seed, self.start_step, self.stop_step = int(seed), start_step, stop_step
        self.rank, self.world = int(rank), int(world)
        if not 0.0 <= clip_fraction <= 1.0:
            raise bad_value("clip_fraction", clip_fraction, "a fraction in [0, 1]")
        self.clips, self.clip_fraction = tuple(str(c) for c in clips), float(clip_fraction)

    def batch(self, step: int) -> dict:
        """The batch of ``step`` on this rank."""
        first = (int(step) * self.world + self.rank) * self.batch_size
        return collate([simulate_sample(self.seed, first + j, self.crop, self.window,
                                        self.clips, self.clip_fraction)
                        for j in range(self.batch_size)])

    def __iter__(self):
        info = torch.utils.data.get_worker_info()
        k, n = (0, 1) if info is None else (info.id, info.num_workers)
        if info is not None:
            _one_thread()
        step = self.start_step + k
        while self.stop_step is None or step < self.stop_step:
            yield self.batch(step)
            step += n
