"""The exact fixed-point accumulator of :mod:`spikesim._kernels` in PyTorch tensor code.

The accumulator of a pixel, in units of its threshold θ, is a 64-bit fraction
(units of 2⁻⁶⁴ θ, an unsigned word held in an ``int64`` tensor) and a signed
64-bit whole part.  A readout's charge ``q`` (float64, thresholds) is split once
into whole and fraction (:func:`to_fixed`, truncation to 2⁻⁶⁴ θ, saturating at
:data:`Q_WHOLE_MAX`) and added exactly; the pixel fires when the whole part
reaches 1, at most once per readout; reset ``modulo`` keeps the fraction,
``subtract`` removes one θ (the backlog saturates at :data:`WHOLE_MAX`),
``zero`` clears both (docs/model.md; Dong et al., AAAI 2024, eq. 1).

:func:`accumulate` takes the charges of ``T`` readouts at once.  Modulo and
subtract reset never change the fraction at a firing, so the fraction after
readout ``n`` is ``frac₀ + Σₖ≤ₙ qfₖ`` (mod 2⁶⁴, a cumulative sum of words) and
its carries are the unsigned decreases of that sum; modulo reset then fires
where ``qw + carry ≥ 1``, and subtract reset's backlog follows Lindley's
recursion ``Bₙ = max(Bₙ₋₁ + aₙ − 1, 0)`` (``aₙ = qwₙ + carryₙ``), solved by a
cumulative minimum.  Where a premise of these forms fails (a negative whole
part, or a backlog that could reach the saturation) and for zero reset, the
readouts are taken one by one, the numba kernel's general step.
"""

from __future__ import annotations

import torch

from spikesim.torch_backend._rng import ult

__all__ = ["Q_WHOLE_MAX", "WHOLE_MAX", "to_fixed", "accumulate", "RESETS"]

#: Largest whole part of one readout's charge (thresholds), as ``spikesim._kernels``.
Q_WHOLE_MAX = 2.0**53
#: Largest backlog of subtract reset (thresholds), as ``spikesim._kernels``.
WHOLE_MAX = 2**62
_TWO64 = 2.0**64
_TWO63 = 2.0**63
_FRAC_MAX = _TWO64 - 2048.0  # the largest float64 below 2⁶⁴
_MIN64 = -(1 << 63)
RESETS = ("modulo", "subtract", "zero")


def _u64_of_float(f: torch.Tensor) -> torch.Tensor:
    """The uint64 word (in int64) of an integer-truncated float64 ``0 ≤ f < 2⁶⁴``:
    values from 2⁶³ on are shifted down by 2⁶³ (exact) before the conversion."""
    big = f >= _TWO63
    v = torch.where(big, f - _TWO63, f).to(torch.int64)
    return torch.where(big, v + _MIN64, v)


def to_fixed(q: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Split charges (float64, thresholds) into ``(whole int64, fraction uint64 word)``;
    charges from :data:`Q_WHOLE_MAX` on (infinity included) saturate there
    (``spikesim._kernels._to_fixed``)."""
    qc = torch.clamp(q, max=Q_WHOLE_MAX)
    w = torch.floor(qc)
    return w.to(torch.int64), _u64_of_float(torch.clamp((qc - w) * _TWO64, max=_FRAC_MAX))


def _step(frac, whole, qw, qf, reset: str):
    """One readout of the general step: the new ``(frac, whole)`` and the spikes."""
    s = frac + qf
    w = torch.clamp(whole + qw + ult(s, frac).to(torch.int64), max=WHOLE_MAX)
    fire = w >= 1
    if reset == "subtract":
        w = w - fire.to(torch.int64)
    else:
        w = torch.where(fire, 0, w)
        if reset == "zero":
            s = torch.where(fire, 0, s)
    return s, w, fire


def accumulate(frac: torch.Tensor, whole: torch.Tensor, qw: torch.Tensor, qf: torch.Tensor,
               reset: str) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Add the charges of ``T`` readouts to the accumulator.

    ``frac``, ``whole``: (..., H, W) state; ``qw``, ``qf``: (..., T, H, W)
    charges from :func:`to_fixed`.  Returns the new ``(frac, whole)`` and the
    spikes, (..., T, H, W) bool.
    """
    t = qw.shape[-3]
    if reset != "zero" and t > 1 and bool((qw.min() >= 0) & (whole.min() >= 0)):
        s = torch.cumsum(qf, dim=-3) + frac.unsqueeze(-3)  # wrapping sums of words
        prev = torch.cat([frac.unsqueeze(-3), s[..., :-1, :, :]], dim=-3)
        a = qw + ult(s, prev).to(torch.int64)  # whole thresholds gained per readout
        if reset == "modulo" and bool(whole.max() == 0):
            return s[..., -1, :, :], torch.zeros_like(whole), a >= 1
        if reset == "subtract" and int(whole.max()) + t * int(a.max()) < WHOLE_MAX:
            b0 = whole.unsqueeze(-3)
            c = torch.cumsum(a - 1, dim=-3)
            backlog = c - torch.minimum(torch.cummin(c, dim=-3).values, -b0)
            before = torch.cat([b0, backlog[..., :-1, :, :]], dim=-3)
            return s[..., -1, :, :], backlog[..., -1, :, :], (before + a) >= 1
    spikes = torch.empty(qw.shape, dtype=torch.bool, device=qw.device)
    for i in range(t):
        frac, whole, spikes[..., i, :, :] = _step(frac, whole, qw[..., i, :, :],
                                                  qf[..., i, :, :], reset)
    return frac, whole, spikes
