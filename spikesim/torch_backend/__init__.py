"""The simulator in PyTorch tensor code: the same model and the same bits as the numba kernel.

``spikesim.simulate(..., backend="torch", device=None)`` and
``spikesim.simulate_chunks(..., backend="torch")`` run the sensor model of
:mod:`spikesim._kernels` with tensors on a torch device (docs/torch.md):

* :mod:`~spikesim.torch_backend._rng` — the counter-based hash and table
  normals of :mod:`spikesim.rng`, on 64-bit integer tensors;
* :mod:`~spikesim.torch_backend._fixed` — the exact fixed-point accumulator
  (2⁻⁶⁴ θ fraction, 64-bit whole part), every reset mode;
* :mod:`~spikesim.torch_backend._core` — mean radiance over each readout,
  paper noise, charge and packed bits for a tile of readouts;
* :mod:`~spikesim.torch_backend._driver` — the chunk driver
  (:class:`TorchRun`);
* :mod:`~spikesim.torch_backend.batch` — many small sensors at once
  (:func:`simulate_batch`, training batches simulated on the device).

Supported: no noise and paper noise (GN, GPN), the clean twin, ground truth,
every reset mode and CFA, mono.  Physical noise raises a one-line error.
PyTorch is an optional dependency (``pip install 'spikesim[torch]'``): without
it, ``backend="torch"`` raises a one-line error and nothing else changes.
Importing this package does not import torch; its functions do.
"""

from __future__ import annotations

from spikesim.errors import SpikeSimValueError

__all__ = ["require_torch", "TorchRun", "simulate_batch", "BACKENDS"]

#: The simulator's backends: the numba kernel and this package.
BACKENDS = ("numba", "torch")


def require_torch():
    """Import and return torch, or raise the one-line error of a missing optional dependency."""
    try:
        import torch
    except ImportError:
        raise SpikeSimValueError(
            "backend='torch' needs PyTorch, which is not installed: "
            "pip install 'spikesim[torch]' (or use backend='numba')") from None
    return torch


def __getattr__(name: str):
    """``TorchRun`` and ``simulate_batch``, imported with torch on first use (PEP 562),
    or the one-line error of :func:`require_torch` when torch is missing."""
    if name == "TorchRun":
        require_torch()
        from spikesim.torch_backend._driver import TorchRun

        return TorchRun
    if name == "simulate_batch":
        require_torch()
        from spikesim.torch_backend.batch import simulate_batch

        return simulate_batch
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
