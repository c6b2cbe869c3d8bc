"""Torch models as reconstruction methods: the inputs SJDD-Net gets, for any ``nn.Module``.

:func:`model_inputs` cuts the window of readouts around the centre and builds
the Bayer mask planes exactly as ``method="sjdd"`` does; :class:`TorchMethod`
wraps any ``nn.Module`` with the forward ``module(spikes, mask)``:

* ``spikes``: (1, window, H, W) float32 0/1, readouts ``start .. start+window-1``
  placed as :func:`spikesim.estimate.window_bounds` (centred on ``center``,
  shifted inside near the ends of the stream);
* ``mask``: (1, 4, H, W) float32 planes ``[R, G1, G2, B]`` of the pattern
  (:func:`spikesim.cfa.mask_planes`);
* returns (1, 3, H, W) linear RGB, or a tuple whose first item is that (as
  SJDD-Net's ``(rgb, noise_map)``).

Example::

    import spikejdd as sj
    from spikejdd.models import TorchMethod

    class Mean(torch.nn.Module):              # TFP as a "network"
        def forward(self, spikes, mask):
            return spikes.mean(1, keepdim=True).expand(-1, 3, -1, -1) / 0.6

    sj.register_method("mean-net", TorchMethod(Mean(), window=39))
"""

from __future__ import annotations

import numpy as np
import torch

from spikejdd.models.pretrained import DEFAULT_WEIGHTS, cached_model
from spikejdd.runtime import check_device
from spikesim.cfa import mask_planes, normalize_cfa
from spikesim.errors import SpikeSimValueError, bad_value
from spikesim.estimate import window_bounds

__all__ = ["model_inputs", "TorchMethod", "sjdd_method"]


def model_inputs(spikes, cfa, center, window: int) -> tuple[torch.Tensor, torch.Tensor]:
    """``(spikes, mask)`` tensors for a window of ``window`` readouts around ``center``.

    Raises if the stream holds fewer than ``window`` readouts (a learned model's
    window is fixed) or the pattern is monochrome.
    """
    pattern = normalize_cfa(cfa)
    if pattern is None:
        raise bad_value("cfa", "mono" if cfa is None else cfa,
                        "a Bayer pattern: this learned method reconstructs colour from a Bayer "
                        "stream and cannot run on a monochrome one")
    arr = np.asarray(spikes)
    if arr.shape[0] < window:
        raise bad_value("spikes", f"{arr.shape[0]} readouts",
                        f"at least {window} readouts (the model's window)")
    start, stop = window_bounds(arr.shape[0], center, window)
    h, w = arr.shape[1:]
    x = torch.from_numpy(np.ascontiguousarray(arr[start:stop], dtype=np.float32))[None]
    m = torch.from_numpy(mask_planes(pattern, h, w))[None]
    return x, m


def _run(module: torch.nn.Module, x: torch.Tensor, m: torch.Tensor, device: str,
         label: str) -> np.ndarray:
    device = check_device(device)
    with torch.inference_mode():
        out = module(x.to(device), m.to(device))
    if isinstance(out, (tuple, list)):
        out = out[0]
    if not isinstance(out, torch.Tensor) or tuple(out.shape) != (1, 3) + tuple(x.shape[2:]):
        shape = tuple(out.shape) if isinstance(out, torch.Tensor) else type(out).__name__
        raise SpikeSimValueError(f"{label} returned {shape}, expected a tensor (1, 3, "
                                 f"{x.shape[2]}, {x.shape[3]}) of linear RGB")
    return out[0].clamp(0, 1).permute(1, 2, 0).float().cpu().numpy()


class TorchMethod:
    """A method (protocol of :mod:`spikejdd.registry`) from an ``nn.Module``.

    Parameters
    ----------
    module : torch.nn.Module
        ``module(spikes, mask)`` as in the module doc; put in eval mode.
    window : int
        Readouts the module takes (SJDD-Net: 39).
    device : str
        Default device; a ``device`` option at call time overrides it.
    """

    def __init__(self, module: torch.nn.Module, window: int = 39, device: str = "cpu"):
        if not isinstance(module, torch.nn.Module):
            raise bad_value("module", type(module).__name__, "a torch.nn.Module")
        if isinstance(window, bool) or not isinstance(window, int) or window < 1:
            raise bad_value("window", window, "an integer >= 1 readouts")
        self.module = module.eval()
        self.window = window
        self.device = device
        self.__doc__ = f"torch module {type(module).__name__}, {window}-readout window"

    def window_for(self, n_readouts: int) -> int:
        return self.window

    def __call__(self, spikes, cfa, center, rate: float = 0.6,
                 device: str | None = None) -> np.ndarray:
        dev = device or self.device
        x, m = model_inputs(spikes, cfa, center, self.window)
        if next(iter(self.module.parameters()), torch.empty(0)).device != torch.device(dev):
            self.module.to(dev)
        return _run(self.module, x, m, dev, type(self.module).__name__)


def sjdd_method(spikes, cfa, center, rate: float = 0.6, weights: str = DEFAULT_WEIGHTS,
                device: str = "cpu") -> np.ndarray:
    """SJDD-Net on the window of ``n_readouts`` (39) readouts centred on ``center``.

    ``weights`` is a shipped name or a checkpoint path (its model configuration
    is read from the checkpoint).  The window is placed as
    :func:`spikesim.estimate.window_bounds` does (shifted inside near the
    ends).  The shipped models were trained at ``full_scale_rate`` 0.6; another
    ``rate`` is accepted but out of their training range.  Threads are a
    per-process setting (:func:`spikejdd.runtime.set_threads`).  Returns
    (H, W, 3) linear RGB clipped to [0, 1].
    """
    model = cached_model(weights, str(device))
    x, m = model_inputs(spikes, cfa, center, model.config.n_readouts)
    return _run(model, x, m, str(device), f"SJDD-Net ({weights})")


def _sjdd_window(n_readouts: int, weights: str = DEFAULT_WEIGHTS) -> int:
    return cached_model(weights, "cpu").config.n_readouts


sjdd_method.window_for = _sjdd_window
