"""Learned reconstruction: SJDD-Net (see :mod:`spikejdd.models.sjdd`).

Public names::

    from spikejdd.models import SJDDNet, SJDDConfig, DEFAULT, LITE, PUBLISHED, load_pretrained
    model = SJDDNet(LITE)                         # or SJDDNet() = published widths
    rgb, noise_map = model(spikes, mask)          # (N, 39, H, W), (N, 4, H, W)
    model = load_pretrained("sjdd-lite")          # a shipped checkpoint (spikejdd/weights)
    sj.reconstruct(spikes, cfa="RGGB", method="sjdd", center=19)

Importing this module registers the reconstruction method ``"sjdd"``
(:func:`sjdd_method`) with :mod:`spikejdd.registry`.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import torch

from spikejdd.models.checkpoints import (
    CheckpointError,
    check_state_dict,
    convert_published_state_dict,
    load_checkpoint,
    load_model,
    save_checkpoint,
    to_published_state_dict,
)
from spikejdd.models.deform import DeformConv2d, deform_conv2d, torchvision_available
from spikejdd.models.sjdd import (
    DEFAULT,
    LITE,
    PUBLISHED,
    PUBLISHED_PARAMETERS,
    SJDDConfig,
    SJDDNet,
    count_parameters,
)
from spikejdd.registry import _METHODS, register_method
from spikesim.cfa import mask_planes, normalize_cfa
from spikesim.errors import bad_value
from spikesim.estimate import window_bounds

__all__ = ["SJDDNet", "SJDDConfig", "DEFAULT", "LITE", "PUBLISHED", "PUBLISHED_PARAMETERS",
           "load_pretrained", "list_pretrained", "pretrained_path", "DEFAULT_WEIGHTS",
           "sjdd_method", "save_checkpoint", "load_checkpoint", "load_model",
           "convert_published_state_dict", "to_published_state_dict", "check_state_dict",
           "CheckpointError", "DeformConv2d", "deform_conv2d", "torchvision_available",
           "count_parameters", "reference_input", "reference_check", "write_reference"]

WEIGHTS_DIR = Path(__file__).resolve().parent.parent / "weights"
#: Weights used by ``method="sjdd"`` when none are named.
DEFAULT_WEIGHTS = "sjdd-lite"


def list_pretrained() -> list[str]:
    """Names of the shipped checkpoints (``spikejdd/weights/<name>.pt``)."""
    return sorted(p.stem for p in WEIGHTS_DIR.glob("*.pt"))


def pretrained_path(name: str) -> Path:
    path = WEIGHTS_DIR / f"{name}.pt"
    if not isinstance(name, str) or not path.is_file():
        raise bad_value("name", name, f"a shipped checkpoint {list_pretrained()}")
    return path


def load_pretrained(name: str = DEFAULT_WEIGHTS, device="cpu") -> SJDDNet:
    """A shipped model by name (see ``spikejdd/weights/<name>.md``), in eval mode."""
    return load_model(pretrained_path(name), device=device)


def reference_input(n_readouts: int = 39, height: int = 20, width: int = 28, seed: int = 2024,
                    cfa: str = "RGGB") -> tuple[torch.Tensor, torch.Tensor]:
    """The fixed input of the shipped models' reference outputs: ``(spikes, mask)``.

    Spikes are Bernoulli draws (NumPy PCG64, ``seed``) of a smooth colourful
    firing-probability field, so the reference exercises every stage.
    """
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float64)
    p = 0.35 + 0.25 * np.sin(xx / 3.0) * np.cos(yy / 4.0)
    p = p * (mask_planes(cfa, height, width) * np.array([1.0, 0.8, 0.8, 0.6])[:, None, None]
             ).sum(axis=0)
    spikes = (rng.random((n_readouts, height, width)) < p).astype(np.float32)
    mask = mask_planes(cfa, height, width)
    return torch.from_numpy(spikes)[None], torch.from_numpy(mask)[None]


def write_reference(model: SJDDNet, path) -> dict:
    """Store ``model``'s output on :func:`reference_input` as JSON (for the shipped weights)."""
    import json

    x, m = reference_input(model.config.n_readouts)
    with torch.no_grad():
        out, nmap = model.eval()(x, m)
    ref = {"input": {"function": "spikejdd.models.reference_input", "n_readouts":
                     model.config.n_readouts, "height": 20, "width": 28, "seed": 2024,
                     "cfa": "RGGB"},
           "rgb": np.round(out[0].numpy().astype(np.float64), 7).tolist(),
           "noise_map": np.round(nmap[0].numpy().astype(np.float64), 7).tolist(),
           "tolerance": 1e-4}
    Path(path).write_text(json.dumps(ref))
    return ref


def reference_check(name: str) -> float:
    """Max |difference| between shipped model ``name`` and its stored reference output;
    raises if it exceeds the stored tolerance."""
    import json

    ref = json.loads((WEIGHTS_DIR / f"{name}.ref.json").read_text())
    model = load_pretrained(name)
    inp = ref["input"]
    x, m = reference_input(inp["n_readouts"], inp["height"], inp["width"], inp["seed"],
                           inp["cfa"])
    with torch.no_grad():
        out, nmap = model(x, m)
    diff = max(float((out[0] - torch.tensor(ref["rgb"])).abs().max()),
               float((nmap[0] - torch.tensor(ref["noise_map"])).abs().max()))
    if diff > ref["tolerance"]:
        raise AssertionError(f"{name}: output differs from its reference by {diff:.3g} "
                             f"(> {ref['tolerance']})")
    return diff


@functools.lru_cache(maxsize=4)
def _cached_model(weights: str, device: str) -> SJDDNet:
    path = Path(weights)
    if path.suffix == ".pt" or path.exists():
        return load_model(path, device=device)
    return load_pretrained(weights, device=device)


def sjdd_method(spikes, cfa, center, rate: float = 0.6, weights: str = DEFAULT_WEIGHTS,
                device: str = "cpu", threads: int | None = None) -> np.ndarray:
    """SJDD-Net on the window of ``n_readouts`` (39) readouts centred on ``center``.

    The window is placed as :func:`spikesim.estimate.window_bounds` does
    (shifted inside near the ends).  The shipped models were trained at
    ``full_scale_rate`` 0.6; another ``rate`` is accepted but out of their
    training range.  Returns (H, W, 3) linear RGB clipped to [0, 1].
    """
    pattern = normalize_cfa(cfa)
    if pattern is None:
        raise bad_value("cfa", cfa, "a Bayer pattern (SJDD-Net is a colour method)")
    model = _cached_model(str(weights), str(device))
    n = model.config.n_readouts
    arr = np.asarray(spikes)
    if arr.shape[0] < n:
        raise bad_value("spikes", f"{arr.shape[0]} readouts",
                        f"at least {n} readouts (the model's window)")
    start, stop = window_bounds(arr.shape[0], center, n)
    h, w = arr.shape[1:]
    x = torch.from_numpy(np.ascontiguousarray(arr[start:stop], dtype=np.float32))[None]
    m = torch.from_numpy(mask_planes(pattern, h, w))[None]
    if threads:
        torch.set_num_threads(int(threads))
    with torch.inference_mode():
        out, _ = model(x.to(device), m.to(device))
    return out[0].clamp(0, 1).permute(1, 2, 0).float().cpu().numpy()


if "sjdd" not in _METHODS:
    register_method("sjdd", sjdd_method,
                    "SJDD-Net (AAAI 2024) learned JDD; shipped weights, 39-readout window")
