"""spikejdd: reconstruction from Bayer spike streams (classical baselines, metrics, data).

Public names::

    import spikejdd as sj
    sj.reconstruct(spikes, cfa="RGGB", method="tfi+malvar2004", center=None)
    sj.register_method("mine", fn)          # fn(spikes, cfa, center) -> (H, W, 3)
    sj.METHODS.register / get / names       # the one Registry object
    sj.list_methods()
    sj.baselines.tfp / tfi, sj.metrics.psnr / ssim, sj.demosaic.demosaic
    sj.data.SpikeWindowDataset              # imports torch on first use

Modules that need torch (``data``, ``capture``, ``models``) and the
evaluation harness are imported lazily, so the classical tools load fast.
"""

from __future__ import annotations

import importlib

from spikejdd import baselines, demosaic, denoise, metrics, pipelines
from spikejdd.registry import (
    METHODS,
    Registry,
    get_method,
    list_methods,
    reconstruct,
    register_method,
    unregister_method,
)

__all__ = [
    "reconstruct",
    "METHODS",
    "Registry",
    "register_method",
    "unregister_method",
    "get_method",
    "list_methods",
    "baselines",
    "demosaic",
    "denoise",
    "metrics",
    "pipelines",
    "data",
    "capture",
    "evaluate",
    "models",
    "runtime",
]

_LAZY = ("data", "capture", "evaluate", "models", "runtime")


def __getattr__(name: str):
    if name in _LAZY:
        module = importlib.import_module(f"spikejdd.{name}")
        globals()[name] = module
        return module
    raise AttributeError(f"module 'spikejdd' has no attribute {name!r}")
