"""Training batches simulated on the training device (``spikejdd train --online --device-sim``).

Each batch is rendered and simulated where the model trains, in one process:
no loader processes, no numba kernels (``spikesim.torch_backend``).  Sample
``i`` of the stream ``seed`` is a scene of
:func:`spikejdd.train.device_scenes.draw_device_scene` (drawn on the host from
``numpy.random.default_rng([seed, i])``, as are its Bayer phase, noise level —
:func:`spikejdd.train.online.draw_noise`: GN σ_g ~ U(0, 15) or GPN with the
evaluation's ranges — and simulation seed), rendered on the device at the
``window + 1`` readout boundaries and at the middle of the centre readout
``window // 2`` (its exact ground truth), and simulated with
:func:`spikesim.torch_backend.simulate_batch` (20 kHz, full_scale_rate 0.6,
modulo reset: the evaluation's sensor).  The batch of step ``s`` on rank ``r``
of ``world`` holds samples ``(s·world + r)·B … + B − 1``, as
:class:`spikejdd.train.online.OnlineSpikeDataset`'s, so the stream is a
function of ``(seed, index)`` and a resumed run continues it exactly.
"""

from __future__ import annotations

import numpy as np
import torch

from spikesim.cfa import mask_planes
from spikesim.errors import bad_value

__all__ = ["device_sample_params", "device_batch", "DeviceBatches", "CLOCK_HZ", "RATE"]

#: The training sensor: readout clock (Hz) and spikes per readout at full scale.
CLOCK_HZ, RATE = 20_000.0, 0.6


def device_sample_params(seed: int, index: int, crop: int) -> dict:
    """Everything about sample ``index`` of stream ``seed`` (host numbers): its scene,
    ``cfa``, ``noise`` (``"GN"``/``"GPN"``), ``sigma_g``, ``sigma_p`` (8-bit DN) and
    ``sim_seed``."""
    from spikejdd.train.device_scenes import draw_device_scene
    from spikejdd.train.online import BAYER_PATTERNS, draw_noise

    rng = np.random.default_rng([int(seed), int(index)])
    scene = draw_device_scene(rng, (crop, crop))
    cfa = BAYER_PATTERNS[int(rng.integers(4))]
    mode, sg, sp = draw_noise(rng)
    return {"scene": scene, "cfa": cfa, "noise": mode, "sigma_g": sg, "sigma_p": sp,
            "sim_seed": int(rng.integers(2**31)), "index": int(index)}


def _content_name(scene: dict) -> str:
    names = [scene["background"]["content"]]
    if scene["kind"] == "disk":
        names.append(scene["look"]["content"])
    elif scene["kind"] == "sprites":
        names += [s["look"]["content"] for s in scene["sprites"]]
    return "+".join(names)


def device_batch(seed: int, indices, crop: int, window: int, device) -> dict:
    """Samples ``indices`` of stream ``seed`` on ``device``: ``spikes`` (B, window,
    crop, crop) float32 0/1, ``mask`` (B, 4, crop, crop), ``gt`` (B, 3, crop, crop)
    linear RGB at the middle of readout ``window // 2``, and ``meta`` (numbers as
    float64 tensors, names as lists: :func:`spikejdd.train.online.collate`'s form)."""
    from spikejdd.train.device_scenes import render
    from spikesim.torch_backend import simulate_batch

    device = torch.device(device)
    params = [device_sample_params(seed, i, crop) for i in indices]
    # key frames at the readout boundaries 0 … window; the ground truth at its own instant
    keys = np.arange(window + 1, dtype=np.float64)
    size = (crop, crop)
    frames = torch.stack([render(p["scene"], keys / CLOCK_HZ, size, device) for p in params])
    gt = torch.cat([render(p["scene"], [(window // 2 + 0.5) / CLOCK_HZ], size, device)
                    for p in params])
    spikes = simulate_batch(frames, keys, window,
                            [p["sim_seed"] for p in params], [p["cfa"] for p in params],
                            [p["sigma_g"] for p in params], [p["sigma_p"] for p in params],
                            full_scale_rate=RATE)
    masks = torch.from_numpy(np.stack([mask_planes(p["cfa"], crop, crop) for p in params]))
    meta = {"index": [p["index"] for p in params], "sigma_g": [p["sigma_g"] for p in params],
            "sigma_p": [p["sigma_p"] for p in params],
            "speed_px_s": [p["scene"]["speed_px_s"] for p in params]}
    meta = {k: torch.tensor(v, dtype=torch.float64) for k, v in meta.items()}
    meta.update(cfa=[p["cfa"] for p in params], noise=[p["noise"] for p in params],
                kind=[p["scene"]["kind"] for p in params],
                motion=[p["scene"]["motion"] for p in params],
                speed_bin=[p["scene"]["speed_bin"] for p in params],
                content=[_content_name(p["scene"]) for p in params])
    return {"spikes": spikes.to(torch.float32), "mask": masks.to(device),
            "gt": gt, "meta": meta}


class DeviceBatches:
    """Batches of steps ``start_step, start_step + 1, …`` simulated on ``device``.

    Parameters
    ----------
    batch_size, crop, window : int
        Samples per batch, crop side (pixels, ≥ 2), readouts per sample.
    seed : int
        The run's seed.
    device : torch device
        Where to render, simulate and deliver.
    start_step, stop_step : int
        First step, and one past the last (None: endless).
    rank, world : int
        This process's share under DistributedDataParallel.
    """

    def __init__(self, batch_size: int, crop: int, window: int = 39, seed: int = 0,
                 device="cpu", start_step: int = 0, stop_step: int | None = None,
                 rank: int = 0, world: int = 1):
        for name, v, lo in (("batch_size", batch_size, 1), ("crop", crop, 2),
                            ("window", window, 1), ("start_step", start_step, 0)):
            if isinstance(v, bool) or not isinstance(v, int) or v < lo:
                raise bad_value(name, v, f"an integer >= {lo}")
        if stop_step is not None and stop_step < start_step:
            raise bad_value("stop_step", stop_step, f"None or >= start_step ({start_step})")
        self.batch_size, self.crop, self.window = batch_size, crop, window
        self.seed, self.device = int(seed), torch.device(device)
        self.start_step, self.stop_step = start_step, stop_step
        self.rank, self.world = int(rank), int(world)

    def batch(self, step: int) -> dict:
        """The batch of ``step`` on this rank."""
        first = (int(step) * self.world + self.rank) * self.batch_size
        return device_batch(self.seed, range(first, first + self.batch_size), self.crop,
                            self.window, self.device)

    def __iter__(self):
        step = self.start_step
        while self.stop_step is None or step < self.stop_step:
            yield self.batch(step)
            step += 1
