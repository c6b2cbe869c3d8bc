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

Both take an ``ensemble`` option, the geometric self-ensemble of
:func:`run_ensemble`: the mean of the module's outputs on the input, its
transpose and their 180° rotations, each mapped back (Timofte, Rothe & Van
Gool, "Seven ways to improve example-based single image super resolution",
CVPR 2016, sec. 3.6; EDSR's "+" models).  It costs one forward pass per view.
"""

from __future__ import annotations

import numpy as np
import torch

from spikejdd.models.pretrained import DEFAULT_WEIGHTS, cached_model, resolve_weights
from spikejdd.runtime import ENSEMBLES, check_device, check_ensemble
from spikesim.cfa import channel_index, mask_planes, normalize_cfa
from spikesim.errors import SpikeSimValueError, bad_value
from spikesim.estimate import window_bounds

__all__ = ["model_inputs", "run_ensemble", "ENSEMBLES", "TorchMethod", "sjdd_method"]

#: The ``sjdd`` method's default: the input and its transpose.  On the
#: benchmark at GN σ = 10 it moves the shipped model from below to above the
#: best classical pipeline on static and slow scenes, for twice the time
#: (docs/sjdd.md, "Self-ensemble").
SJDD_ENSEMBLE = 2


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


def _view(t: torch.Tensor, v: int) -> torch.Tensor:
    """View ``v`` of the last two axes: bit 0 transposes, bit 1 rotates by 180°
    (the two commute, and each view is its own inverse)."""
    if v & 1:
        t = t.transpose(-1, -2)
    if v & 2:
        t = t.flip(-1, -2)
    return t


def _forward(module, x, m, label):
    out = module(x, m)
    if isinstance(out, (tuple, list)):
        out = out[0]
    if not isinstance(out, torch.Tensor) or tuple(out.shape) != (1, 3) + tuple(x.shape[2:]):
        shape = tuple(out.shape) if isinstance(out, torch.Tensor) else type(out).__name__
        raise SpikeSimValueError(f"{label} returned {shape}, expected a tensor (1, 3, "
                                 f"{x.shape[2]}, {x.shape[3]}) of linear RGB")
    return out[0]


def run_ensemble(module, x: torch.Tensor, cfa: str, ensemble: int, label: str = "the model",
                 ) -> torch.Tensor:
    """(3, H, W) mean of ``module(spikes, mask)`` over ``ensemble`` geometric
    views of ``x`` (1, T, H, W) (:data:`ENSEMBLES`, :func:`_view`), each output
    mapped back to the input's pixels.

    A view keeps the Bayer pattern the module was given: where transposing or
    rotating changes the pattern's phase, the view drops its first and last
    rows, or columns, or both (a view left empty is skipped).  Every output
    pixel is the mean of the views that contain it (the identity view contains
    all).  With ``ensemble`` = 1 this is the module's output itself, bit for bit.
    """
    ensemble = check_ensemble(ensemble, default=1)
    pattern = normalize_cfa(cfa)
    h, w = x.shape[-2:]
    mask = torch.from_numpy(mask_planes(pattern, h, w))[None].to(x.device)
    first = _forward(module, x, mask, label)
    if ensemble == 1:
        return first
    colours = torch.from_numpy(channel_index(pattern, h, w))
    index = torch.arange(h * w, device=x.device).reshape(h, w)
    total = first.reshape(3, -1).clone()
    count = torch.ones(h * w, device=x.device, dtype=total.dtype)
    for v in range(1, ensemble):
        c = _view(colours, v)
        for dy, dx in ((0, 0), (0, 1), (1, 0), (1, 1)):
            hh, ww = c.shape[0] - 2 * dy, c.shape[1] - 2 * dx
            if hh >= 1 and ww >= 1 and torch.equal(
                    c[dy:dy + hh, dx:dx + ww], torch.from_numpy(channel_index(pattern, hh, ww))):
                break
        else:
            continue  # no crop of this view has the pattern (tiny images): skipped
        xv = _view(x, v)[..., dy:dy + hh, dx:dx + ww].contiguous()
        mv = torch.from_numpy(mask_planes(pattern, hh, ww))[None].to(x.device)
        iv = _view(index, v)[dy:dy + hh, dx:dx + ww].reshape(-1)
        total.index_add_(1, iv, _forward(module, xv, mv, label).reshape(3, -1))
        count.index_add_(0, iv, torch.ones_like(iv, dtype=total.dtype))
    return (total / count).reshape(3, h, w)


def _run(module: torch.nn.Module, x: torch.Tensor, cfa: str, device: str, label: str,
         ensemble: int = 1) -> np.ndarray:
    device = check_device(device)
    with torch.inference_mode():
        out = run_ensemble(module, x.to(device), cfa, ensemble, label)
    return out.clamp(0, 1).permute(1, 2, 0).float().cpu().numpy()


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
    ensemble : int
        Default self-ensemble (:func:`run_ensemble`: 1, 2 or 4 forward passes;
        None: 1); an ``ensemble`` option at call time overrides it (None: this
        default).
    """

    def __init__(self, module: torch.nn.Module, window: int = 39, device: str = "cpu",
                 ensemble: int = 1):
        if not isinstance(module, torch.nn.Module):
            raise bad_value("module", type(module).__name__, "a torch.nn.Module")
        if isinstance(window, bool) or not isinstance(window, int) or window < 1:
            raise bad_value("window", window, "an integer >= 1 readouts")
        self.module = module.eval()
        self.window = window
        self.device = device
        self.ensemble = check_ensemble(ensemble, default=1)
        self.__doc__ = f"torch module {type(module).__name__}, {window}-readout window"

    def window_for(self, n_readouts: int) -> int:
        return self.window

    def __call__(self, spikes, cfa, center, rate: float = 0.6,
                 device: str | None = None, ensemble: int | None = None) -> np.ndarray:
        dev = device or self.device
        k = check_ensemble(ensemble, default=self.ensemble)
        x, _ = model_inputs(spikes, cfa, center, self.window)
        if next(iter(self.module.parameters()), torch.empty(0)).device != torch.device(dev):
            self.module.to(dev)
        return _run(self.module, x, cfa, dev, type(self.module).__name__, k)


def sjdd_method(spikes, cfa, center, rate: float = 0.6, weights: str = DEFAULT_WEIGHTS,
                device: str = "cpu", ensemble: int = SJDD_ENSEMBLE) -> np.ndarray:
    """SJDD-Net on the window of ``n_readouts`` (39) readouts centred on ``center``.

    ``weights`` is a shipped name or a checkpoint path (its model configuration
    is read from the checkpoint).  The window is placed as
    :func:`spikesim.estimate.window_bounds` does (shifted inside near the
    ends).  The shipped models were trained at ``full_scale_rate`` 0.6; another
    ``rate`` is accepted but out of their training range.  Threads are a
    per-process setting (:func:`spikejdd.runtime.set_threads`).  ``ensemble``:
    the self-ensemble of :func:`run_ensemble` (default, or None,
    :data:`SJDD_ENSEMBLE`: two forward passes; 1 is the plain model, twice
    as fast).  Returns
    (H, W, 3) linear RGB clipped to [0, 1].
    """
    k = check_ensemble(ensemble, default=SJDD_ENSEMBLE)
    model = cached_model(weights, str(device))
    x, _ = model_inputs(spikes, cfa, center, model.config.n_readouts)
    return _run(model, x, cfa, str(device), f"SJDD-Net ({weights})", k)


def _sjdd_window(n_readouts: int, weights: str = DEFAULT_WEIGHTS, **_options) -> int:
    return cached_model(weights, "cpu").config.n_readouts


sjdd_method.window_for = _sjdd_window
sjdd_method.check_weights = resolve_weights  # the registry checks sjdd@WEIGHTS when named
