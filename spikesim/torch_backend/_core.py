"""One tile of readouts in PyTorch: mean radiance, paper noise, charge, accumulator, bits.

The model of :mod:`spikesim._kernels` (docs/model.md), on tensors with any
leading batch dimensions (one sensor, or many small ones at once):

* the charge of readout ``n`` is ``gain · Ī_n + offset`` with ``Ī_n`` the exact
  mean of the piecewise-linear radiance over ``[n, n+1)``: inside a segment
  ``I_a + (I_b − I_a)·φ_n``, ``φ_n = (n + ½ − t_a)/(t_b − t_a)``; a period
  holding key times is the sum of its pieces ``len·(I_a + (I_b − I_a)·φ_mid)``
  (:func:`mean_radiance`, from the schedule of ``spikesim.schedule``);
* paper-mode noise (eq. 3 and 5 of the paper): ``Ĩ = max(Ī + σ(Ī)·z, 0)``,
  ``σ = √(σ_g² + σ_p²·255·Ī)/255``, ``z`` the counter-based normal of (seed,
  pixel, readout) (:mod:`spikesim.torch_backend._rng`);
* the exact fixed-point accumulator (:mod:`spikesim.torch_backend._fixed`).

Each float64 value is computed with the operations of the numba kernel in its
order, one IEEE operation per tensor operation, so the spikes are its bits.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from spikesim import rng as _keys
from spikesim._kernels import RUN_PIECES
from spikesim.torch_backend import _fixed, _rng

__all__ = ["AccumulatorModel", "mean_radiance", "charges", "initial_state", "pack_bits",
           "advance"]


@dataclass
class AccumulatorModel:
    """What one accumulator set needs besides the radiance: ``gain`` (thresholds
    per readout per unit radiance) and ``offset``, the reset mode, and paper
    noise — ``sg2``, ``sp2`` (σ_g², σ_p² in DN²; floats, or tensors that
    broadcast against (..., T, H, W) for per-sample levels) and the stream keys
    ``key_paper`` (int64 tensor of the batch shape).  ``noisy`` False: no draws."""

    gain: float
    offset: float
    reset: str
    noisy: bool = False
    sg2: float | torch.Tensor = 0.0
    sp2: float | torch.Tensor = 0.0
    key_paper: torch.Tensor | None = None


def stream_keys(seeds, stream: int, device) -> torch.Tensor:
    """int64 tensor of ``spikesim.rng.stream_key(seed, stream)`` for each seed."""
    return torch.tensor([_rng.as_signed(int(_keys.stream_key(int(s), stream))) for s in seeds],
                        dtype=torch.int64, device=device)


def initial_state(init_keys: torch.Tensor, pixel_keys: torch.Tensor, uniform: bool):
    """``(frac, whole)`` of a fresh accumulator, shape ``init_keys.shape + (H, W)``:
    the fraction ``pixel_bits(readout_key(key_init, 0), p)`` (uniform in [0, 1) θ),
    or 0; whole part 0 (``spikesim._kernels._init_block``)."""
    shape = (*init_keys.shape, *pixel_keys.shape)
    whole = torch.zeros(shape, dtype=torch.int64, device=pixel_keys.device)
    if not uniform:
        return torch.zeros_like(whole), whole
    zero = torch.zeros(1, dtype=torch.int64, device=pixel_keys.device)
    rk = _rng.readout_keys(init_keys, zero)[..., 0]
    return _rng.mix64(rk[..., None, None] ^ pixel_keys), whole


def _tile_runs(sched, t0: int, t1: int):
    """The schedule's runs over readouts ``[t0, t1)``: ``(row0, row1, a, b, φ)`` for
    the rows inside one segment (key frames ``a``, ``b``; ``φ`` float64 per row,
    the kernel's ``(n + ½ − t_a)·inv``, in its order), ``(row, p0, p1)`` for a row
    split into pieces ``[p0, p1)``."""
    segments, pieces = [], []
    starts, stops = sched.start, sched.stop
    first = int(np.searchsorted(stops, t0, side="right"))
    for r in range(first, len(starts)):
        n0, n1 = max(int(starts[r]), t0), min(int(stops[r]), t1)
        if n0 >= t1:
            break
        if sched.kind[r] == RUN_PIECES:
            pieces.append((n0 - t0, int(sched.p0[r]), int(sched.p1[r])))
            continue
        n = np.arange(n0, n1, dtype=np.int64).astype(np.float64)
        phi = (n + 0.5 - sched.ta[r]) * sched.inv[r]
        segments.append((n0 - t0, n1 - t0, int(sched.a[r]), int(sched.b[r]), phi))
    return segments, pieces


def mean_radiance(frames: torch.Tensor, sched, t0: int, t1: int) -> torch.Tensor:
    """Mean radiance (float64, (..., T, H, W)) of readouts ``[t0, t1)`` from the
    chunk's key frames ``frames`` (..., K, H, W) float32 and its schedule
    (``spikesim.schedule.build_schedule``, readouts ``t0, t1`` inside it):
    ``I_a + (I_b − I_a)·φ`` inside a segment (``spikesim._kernels._segment_radiance``),
    the pieces' ``len·(I_a + (I_b − I_a)·φ)`` summed in order from 0 for a readout
    that holds key times (``_pieces_radiance``)."""
    segments, pieces = _tile_runs(sched, t0, t1)
    dev = frames.device
    lead, hw = frames.shape[:-3], frames.shape[-2:]
    level = torch.empty((*lead, t1 - t0, *hw), dtype=torch.float64, device=dev)
    for row0, row1, a, b, phi in segments:
        ia = frames[..., a, :, :].to(torch.float64).unsqueeze(-3)
        di = frames[..., b, :, :].to(torch.float64).unsqueeze(-3) - ia
        ph = torch.from_numpy(phi).to(dev).view(-1, 1, 1)
        torch.add(ia, di * ph, out=level[..., row0:row1, :, :])
    for row, p0, p1 in pieces:
        acc = torch.zeros((*lead, *hw), dtype=torch.float64, device=dev)
        for p in range(p0, p1):
            va = frames[..., int(sched.piece_a[p]), :, :].to(torch.float64)
            vb = frames[..., int(sched.piece_b[p]), :, :].to(torch.float64)
            acc = acc + float(sched.piece_len[p]) * (va + (vb - va) * float(sched.piece_phi[p]))
        level[..., row, :, :] = acc
    return level


def charges(level: torch.Tensor, model: AccumulatorModel, readouts: torch.Tensor,
            pixel_keys: torch.Tensor) -> torch.Tensor:
    """Charges (float64 thresholds, (..., T, H, W)) of readouts ``readouts`` (T,)
    int64 at mean radiance ``level``, with ``model``'s paper noise
    (``spikesim._kernels._general_step``; its fast path computes the same)."""
    x = level
    if model.noisy:
        rk = _rng.readout_keys(model.key_paper, readouts)  # (..., T)
        z = _rng.normal(_rng.mix64(rk[..., None, None] ^ pixel_keys))
        sg2, sp2 = model.sg2, model.sp2
        if isinstance(sp2, torch.Tensor) or sp2 > 0.0:
            sd = _rng.sqrt_rn(sg2 + (sp2 * 255.0) * level) * (1.0 / 255.0)
        else:
            sd = float(np.sqrt(sg2)) * (1.0 / 255.0)
        x = torch.clamp_min(level + sd * z, 0.0)
    return model.gain * x + model.offset


def advance(state: tuple[torch.Tensor, torch.Tensor], level: torch.Tensor,
            model: AccumulatorModel, readouts: torch.Tensor, pixel_keys: torch.Tensor):
    """Readouts ``readouts`` of one accumulator set: the new state and the spikes
    (..., T, H, W) bool."""
    qw, qf = _fixed.to_fixed(charges(level, model, readouts, pixel_keys))
    frac, whole, spikes = _fixed.accumulate(state[0], state[1], qw, qf, model.reset)
    return (frac, whole), spikes


_BIT_WEIGHTS: dict = {}


def pack_bits(spikes: torch.Tensor) -> torch.Tensor:
    """(..., W) bool spikes → (..., ⌈W/8⌉) uint8, little bit order (pixel x → bit x % 8
    of byte x // 8), as ``np.packbits(..., bitorder="little")``."""
    w = spikes.shape[-1]
    nb = (w + 7) // 8
    x = spikes.to(torch.uint8)
    if nb * 8 != w:
        x = torch.nn.functional.pad(x, (0, nb * 8 - w))
    key = str(spikes.device)
    if key not in _BIT_WEIGHTS:
        _BIT_WEIGHTS[key] = torch.tensor([1 << i for i in range(8)], dtype=torch.uint8,
                                         device=spikes.device)
    return (x.view(*x.shape[:-1], nb, 8) * _BIT_WEIGHTS[key]).sum(-1, dtype=torch.uint8)
