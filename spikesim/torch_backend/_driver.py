"""``simulate(..., backend="torch")``: the chunk driver of :mod:`spikesim.simulate` on tensors.

:class:`TorchRun` is a :class:`spikesim.simulate.SimulationRun` (same checks,
metadata, key times, chunks and ground truth) whose chunks are simulated by
:mod:`spikesim.torch_backend._core` on a torch device instead of the numba
kernel: per chunk the scene's key frames are sampled through the colour filter
into a (K, H, W) float32 tensor, and the chunk's readouts are taken in tiles of
``T`` readouts (all pixels of a tile at once; ``T·H·W`` bounded, see
:data:`TILE_ELEMENTS`).  The accumulator stays on the device from chunk to
chunk; each tile's packed bits are copied to the host.
"""

from __future__ import annotations

import numpy as np
import torch

from spikesim import rng as _keys
from spikesim.bits import packed_width
from spikesim.cfa import LUMA_WEIGHTS, channel_index
from spikesim.errors import SpikeSimValueError, bad_value
from spikesim.noise import PaperNoise, PhysicalNoise
from spikesim.scenes.static import validate_grey, validate_radiance
from spikesim.schedule import build_schedule
from spikesim.simulate import CHUNK_KEYFRAME_BYTES, SimulationRun
from spikesim.stream import SpikeChunk
from spikesim.torch_backend import _core, _rng

__all__ = ["TorchRun", "resolve_device", "mosaic", "TILE_ELEMENTS",
           "physical_noise_error"]

#: Pixel-readouts per tile (``T·H·W``) by device type: a float64 tensor of a tile
#: is 16 MiB on the CPU, 256 MiB on a GPU (about ten are alive at once).
TILE_ELEMENTS = {"cpu": 1 << 21, "cuda": 1 << 25}


def resolve_device(device) -> torch.device:
    """``device`` as a ``torch.device``: None picks CUDA when available, else the CPU."""
    if device is None:
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    try:
        dev = torch.device(device)
    except (RuntimeError, TypeError):
        raise bad_value("device", device, "None, 'cpu', 'cuda' or 'cuda:N' (a torch device)") \
            from None
    if dev.type == "cuda" and not torch.cuda.is_available():
        raise bad_value("device", device, "'cpu' or None (no CUDA device here)")
    if dev.type not in TILE_ELEMENTS:
        raise bad_value("device", device, "a 'cpu' or 'cuda' torch device")
    return dev


def physical_noise_error() -> SpikeSimValueError:
    """The one-line error of physical noise on the torch backend (docs/torch.md)."""
    return SpikeSimValueError(
        "sensor.noise=PhysicalNoise(...) is not supported by backend='torch': it simulates "
        "no noise and paper noise (PaperNoise, GN/GPN); use backend='numba' for physical noise")


def mosaic(rgb: torch.Tensor, chan: torch.Tensor) -> torch.Tensor:
    """Radiance (..., 3, H, W) through the colour filter: (..., H, W) float32.

    ``chan`` (broadcasting to (..., H, W), int64) is the channel each pixel
    samples (0 R, 1 G, 2 B), or −1 for a monochrome pixel, which sees
    Rec. 709 luma summed in float64 (``spikesim._mosaic.mosaic_into``: the
    same operations, so the same float32 values)."""
    mono = chan < 0
    shape = torch.broadcast_shapes(rgb.shape[:-3] + rgb.shape[-2:], chan.shape)
    out = None
    if bool(mono.any()):
        x = rgb.to(torch.float64)
        l0, l1, l2 = (float(v) for v in LUMA_WEIGHTS)
        out = ((l0 * x[..., 0, :, :] + l1 * x[..., 1, :, :]) + l2 * x[..., 2, :, :]).to(
            torch.float32).expand(shape)
        if bool(mono.all()):
            return out.contiguous()
    idx = chan.clamp_min(0).expand(shape).unsqueeze(-3)
    picked = torch.gather(rgb.expand(*shape[:-2], 3, *shape[-2:]), -3, idx).squeeze(-3).to(
        torch.float32)
    return picked if out is None else torch.where(mono.expand(shape), out, picked)


def _channel_map(cfa: str | None, h: int, w: int, device) -> torch.Tensor:
    idx = channel_index(cfa, h, w)
    if idx is None:
        return torch.full((h, w), -1, dtype=torch.int64, device=device)
    return torch.from_numpy(idx.astype(np.int64)).to(device)


class TorchRun(SimulationRun):
    """A :class:`~spikesim.simulate.SimulationRun` simulated with PyTorch on ``device``
    (None: CUDA when available, else the CPU); the same chunks and bits.

    Supports every reset mode, CFA and initial state, no noise and paper noise
    (with its clean twin); physical noise raises (:func:`physical_noise_error`).
    """

    def __init__(self, scene, sensor, n_readouts: int, seed: int = 0, clean_twin: bool = False,
                 gt_readouts=None, chunk_readouts: int | None = None, progress: bool = False, *,
                 shot_sampler: str = "event", device=None):
        super().__init__(scene, sensor, n_readouts, seed, clean_twin, gt_readouts,
                         chunk_readouts, progress, shot_sampler=shot_sampler)
        if isinstance(sensor.noise, PhysicalNoise):
            raise physical_noise_error()
        self.device = resolve_device(device)

    # -- key frames and ground truth, without the numba samplers ---------------
    def _key_frame(self, t: float, chan: torch.Tensor) -> torch.Tensor:
        """The sensor-channel radiance at ``t``: (H, W) float32 on the device."""
        h, w = self.sensor.shape
        grey = self._grey_at(t)
        if grey is not None:  # every filter sees the grey value (``mosaic_grey_into``)
            return torch.tensor(validate_grey(grey, f"scene.grey(t={t:.6g})"),
                                device=self.device)  # (a copy: scenes hand out read-only frames)
        rad = np.asarray(self.scene.radiance(t))
        name = f"scene.radiance(t={t:.6g})"
        if rad.shape != (h, w, 3) or rad.dtype.kind != "f":
            rad = validate_radiance(rad, name)
            if rad.shape[:2] != (h, w):
                raise bad_value(f"{name}.shape", rad.shape, f"({h}, {w}, 3)")
        else:
            validate_radiance(rad, name)  # raises on NaN, inf, negative; values used as given
        x = torch.tensor(rad, device=self.device)
        return mosaic(x.permute(2, 0, 1), chan)

    def _ground_truth(self, n0: int, n1: int) -> tuple[np.ndarray, np.ndarray]:
        clock = self.sensor.clock_hz
        sel = self.gt_readouts[(self.gt_readouts >= n0) & (self.gt_readouts < n1)]
        gt = np.empty((len(sel), self.sensor.height, self.sensor.width, 3), np.float32)
        for i, g in enumerate(sel.tolist()):
            t = (g + 0.5) / clock
            grey = self._grey_at(t)
            if grey is not None:
                gt[i] = validate_grey(grey, f"scene.grey(t={t:.6g})")[:, :, None]
            else:
                gt[i] = validate_radiance(self.scene.radiance(t), f"scene.radiance(t={t:.6g})")
        return gt, sel.copy()

    def _models(self) -> tuple[_core.AccumulatorModel, _core.AccumulatorModel]:
        sensor, dev = self.sensor, self.device
        gain = float(sensor.full_scale_rate)
        noise = sensor.noise
        noisy = _core.AccumulatorModel(gain=gain, offset=0.0, reset=sensor.reset)
        if isinstance(noise, PaperNoise) and noise.per_readout:
            params = noise.kernel_params()
            noisy.noisy = True
            noisy.sg2, noisy.sp2 = float(params["paper_sg2"]), float(params["paper_sp2"])
            noisy.key_paper = _core.stream_keys([self.seed], _keys.STREAM_PAPER, dev)[0]
        return noisy, _core.AccumulatorModel(gain=gain, offset=0.0, reset=sensor.reset)

    def _chunks(self, into=None):
        sensor, dev = self.sensor, self.device
        h, w = sensor.shape
        chan = _channel_map(sensor.cfa, h, w, dev)
        pkeys = _rng.pixel_keys(h, w, dev)
        noisy, clean = self._models()
        init_key = _core.stream_keys([self.seed], _keys.STREAM_INIT, dev)[0]
        state = _core.initial_state(init_key, pkeys, sensor.init == "uniform")
        twin = (state[0].clone(), state[1].clone()) if self.clean_twin else None
        tile = max(1, TILE_ELEMENTS[dev.type] // (h * w))
        max_keys = max(2, CHUNK_KEYFRAME_BYTES // (h * w * 4))
        nbytes = packed_width(w)
        bar = None
        if self.progress:
            from tqdm.auto import tqdm

            bar = tqdm(total=self.n_readouts, unit="readout", desc="simulate (torch)")
        cache: dict[float, torch.Tensor] = {}
        try:
            n0 = 0
            while n0 < self.n_readouts:
                n1, times, tau = self._chunk_keys(n0, max_keys)
                frames = torch.stack([cache[t] if t in cache else self._key_frame(t, chan)
                                      for t in times.tolist()])
                cache = {times[-1].item(): frames[-1]}
                sched = build_schedule(tau, n0, n1)
                if into is not None:
                    out = into[0][n0:n1]
                    c_out = into[1][n0:n1] if self.clean_twin else None
                else:
                    out = np.empty((n1 - n0, h, nbytes), np.uint8)
                    c_out = np.empty_like(out) if self.clean_twin else None
                for t0 in range(n0, n1, tile):
                    t1 = min(n1, t0 + tile)
                    level = _core.mean_radiance(frames, sched, t0, t1)
                    readouts = torch.arange(t0, t1, dtype=torch.int64, device=dev)
                    state, spikes = _core.advance(state, level, noisy, readouts, pkeys)
                    out[t0 - n0:t1 - n0] = _core.pack_bits(spikes).cpu().numpy()
                    if twin is not None:
                        twin, spikes = _core.advance(twin, level, clean, readouts, pkeys)
                        c_out[t0 - n0:t1 - n0] = _core.pack_bits(spikes).cpu().numpy()
                gt, sel = self._ground_truth(n0, n1)
                yield SpikeChunk(n0, out, c_out, gt, sel)
                if bar is not None:
                    bar.update(n1 - n0)
                n0 = n1
        finally:
            if bar is not None:
                bar.close()
