"""Shipped weights, their reference outputs, and the model cache of ``method="sjdd"``.

* :func:`load_pretrained` — a shipped checkpoint (``spikejdd/weights/<name>.pt``,
  model card ``<name>.md``) by name;
* :func:`reference_input`, :func:`write_reference`, :func:`reference_check` —
  the fixed input and stored output (``<name>.ref.json``) that pin each shipped
  model's numbers;
* :func:`resolve_weights`, :func:`cached_model` — a shipped name or a
  checkpoint path (the model configuration is read from the checkpoint) to a
  model in eval mode, kept in a small LRU cache per (weights, device).
"""

from __future__ import annotations

import functools
import json
from pathlib import Path

import numpy as np
import torch

from spikejdd.models.checkpoints import load_model
from spikejdd.models.sjdd import SJDDNet
from spikesim.cfa import mask_planes
from spikesim.errors import bad_value

__all__ = ["WEIGHTS_DIR", "DEFAULT_WEIGHTS", "list_pretrained", "pretrained_path",
           "load_pretrained", "resolve_weights", "cached_model", "reference_input",
           "write_reference", "reference_check"]

WEIGHTS_DIR = Path(__file__).resolve().parent.parent / "weights"
#: Weights used by ``method="sjdd"`` when none are named.
DEFAULT_WEIGHTS = "sjdd-full"


def list_pretrained() -> list[str]:
    """Names of the shipped checkpoints (``spikejdd/weights/<name>.pt``)."""
    return sorted(p.stem for p in WEIGHTS_DIR.glob("*.pt"))


def pretrained_path(name: str) -> Path:
    """The file of shipped checkpoint ``name``; raises listing the shipped names."""
    if not isinstance(name, str) or not (WEIGHTS_DIR / f"{name}.pt").is_file():
        raise bad_value("name", name, f"a shipped checkpoint {list_pretrained()}")
    return WEIGHTS_DIR / f"{name}.pt"


def load_pretrained(name: str = DEFAULT_WEIGHTS, device="cpu") -> SJDDNet:
    """A shipped model by name (see ``spikejdd/weights/<name>.md``), in eval mode."""
    return load_model(pretrained_path(name), device=device)


def resolve_weights(weights: str | Path) -> Path:
    """A shipped name or a checkpoint path → the checkpoint file.

    Names without a path separator or ``.pt`` suffix are looked up among the
    shipped checkpoints first; anything else must be an existing file.
    """
    text = str(weights)
    if text in list_pretrained():
        return pretrained_path(text)
    path = Path(text).expanduser()
    if path.is_file():
        return path
    raise bad_value("weights", text, f"a shipped name {list_pretrained()} or an existing "
                    "checkpoint file (e.g. runs/sjdd/best.pt)")


@functools.lru_cache(maxsize=4)
def _cached(path: str, mtime_ns: int, device: str) -> SJDDNet:
    return load_model(path, device=device)


def cached_model(weights: str | Path = DEFAULT_WEIGHTS, device: str = "cpu") -> SJDDNet:
    """:func:`resolve_weights` + :func:`~spikejdd.models.load_model`, cached (4 models).

    The cache key includes the file's modification time, so a checkpoint
    rewritten by a running training is read again.
    """
    path = resolve_weights(weights).resolve()
    return _cached(str(path), path.stat().st_mtime_ns, str(device))


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
    """Largest absolute difference between shipped model ``name`` and its stored reference output;
    raises if it exceeds the stored tolerance."""
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
