"""Checkpoints: our self-describing format and a strict converter from the published layout.

Our format (``torch.save`` of a plain dict, loadable with ``weights_only=True``)::

    {"format": "spikejdd-sjdd", "format_version": 1,
     "config": SJDDConfig.to_dict(), "state_dict": {...},
     "data": {...},        # training data description (paths, noise model and range, ...)
     "seed": int,          # the run's seed
     "eval": {...},        # evaluation results (PSNR, ...), may be empty
     "train": {...},       # step, epoch, optimizer/scheduler/RNG state (run checkpoints only)
     "versions": {...},
     "int8_state": {...},  # format_version 2 only (save_checkpoint's precision="int8"):
     "int8_scales": {...}} # the quantized weights, kept out of state_dict

Published checkpoints (``{"model_state": state_dict, ...}`` saved from a
``DataParallel`` model, or a bare state dict) are converted by
:func:`convert_published_state_dict`: the ``module.`` prefix is dropped and
the three top-level names are renamed (``repre`` → ``csr``, ``estimator`` →
``sne``, ``prior`` → ``ccp``; ``mus.k`` unchanged); every other name already
matches our module tree.  The match is strict: unexpected keys, missing keys
and shape mismatches are all reported together in one error.  The published
code builds the noise estimator's residual blocks from a helper module that is
not in its repository; we assume its two convolutions are ``body.0`` and
``body.2`` (EDSR layout) and the converter would report otherwise.
"""

from __future__ import annotations

import os
from pathlib import Path

import torch

from spikejdd.models.sjdd import PUBLISHED, SJDDConfig, SJDDNet
from spikesim.errors import SpikeSimFormatError, SpikeSimTypeError, SpikeSimValueError

__all__ = ["save_checkpoint", "load_checkpoint", "load_model", "convert_published_state_dict",
           "to_published_state_dict", "check_state_dict", "CheckpointError", "FORMAT",
           "FORMAT_VERSION", "PRECISIONS"]

FORMAT = "spikejdd-sjdd"
FORMAT_VERSION = 1
#: The version written for weights stored as 8-bit integers (older readers refuse it).
INT8_FORMAT_VERSION = 2
PRECISIONS = ("float32", "float16", "int8")
_RENAME = {"repre.": "csr.", "estimator.": "sne.", "prior.": "ccp."}


class CheckpointError(SpikeSimFormatError):
    """A checkpoint that does not match the model (lists every mismatch)."""


def _versions() -> dict:
    import spikesim

    return {"torch": str(torch.__version__), "spikesim": str(getattr(spikesim, "__version__", "?"))}


def check_state_dict(model: torch.nn.Module, state: dict, source: str = "checkpoint") -> None:
    """Raise :class:`CheckpointError` unless ``state`` has exactly the model's keys and shapes."""
    own = model.state_dict()
    missing = sorted(set(own) - set(state))
    unexpected = sorted(set(state) - set(own))
    shapes = sorted(f"{k}: checkpoint {tuple(state[k].shape)} vs model {tuple(own[k].shape)}"
                    for k in set(own) & set(state) if tuple(state[k].shape) != tuple(own[k].shape))
    if missing or unexpected or shapes:
        def show(items):
            return ", ".join(items[:8]) + (f", ... ({len(items)} in all)" if len(items) > 8 else "")
        parts = []
        if missing:
            parts.append(f"missing keys: {show(missing)}")
        if unexpected:
            parts.append(f"unexpected keys: {show(unexpected)}")
        if shapes:
            parts.append(f"shape mismatches: {show(shapes)}")
        raise CheckpointError(f"{source} does not match the model — " + "; ".join(parts))


def save_checkpoint(path, model: SJDDNet, *, data: dict | None = None, seed: int | None = None,
                    eval: dict | None = None, train: dict | None = None,
                    precision: str = "float32") -> Path:
    """Write ``model`` with its configuration and provenance (atomically); returns the path.

    ``precision`` is how the floating-point weights are stored; they are always
    read back as float32.  ``"float16"`` halves the file.  ``"int8"`` quarters it:
    each weight tensor of two or more dimensions is stored as integers
    ``round(w / s)`` in [−127, 127] with one float32 scale ``s = max|w| / 127``
    per output channel (the first dimension; symmetric per-channel quantization,
    Krishnamoorthi, arXiv:1806.08342, sec. 2), every other float tensor as
    float16.  The integers and scales are kept in ``int8_state`` and
    ``int8_scales``, out of ``state_dict``, so that loading the raw
    ``state_dict`` into a model with plain ``torch.load`` fails on the missing
    keys instead of reading integers as weights; :func:`load_checkpoint` puts
    them back.  For SJDD-Net either changes the validation PSNR by about 0.001
    dB (``spikejdd/weights/sjdd-full.md``)."""
    if precision not in PRECISIONS:
        raise SpikeSimValueError(f"precision={precision!r} is invalid: expected one of "
                                 f"{PRECISIONS}")
    if not isinstance(model, SJDDNet):
        model = getattr(model, "module", model)  # DDP / DataParallel wrapper
    if not isinstance(model, SJDDNet):
        raise SpikeSimTypeError(f"model must be an SJDDNet, got {type(model).__name__}")
    state = {k: v.detach().cpu() for k, v in model.state_dict().items()}
    scales, quantized = {}, {}
    if precision == "int8":
        for k, v in list(state.items()):
            if v.is_floating_point() and v.ndim >= 2:
                w = state.pop(k).float()
                scales[k] = (w.abs().amax(dim=tuple(range(1, w.ndim)), keepdim=True)
                             .clamp_min(torch.finfo(torch.float32).tiny) / 127.0)
                quantized[k] = torch.round(w / scales[k]).clamp(-127, 127).to(torch.int8)
    if precision != "float32":
        state = {k: v.half() if v.is_floating_point() else v for k, v in state.items()}
    version = INT8_FORMAT_VERSION if scales else FORMAT_VERSION
    blob = {"format": FORMAT, "format_version": version,
            "config": model.config.to_dict(), "state_dict": state, "data": data or {},
            "seed": seed, "eval": eval or {}, "train": train or {}, "versions": _versions()}
    if scales:
        blob["int8_state"], blob["int8_scales"] = quantized, scales
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + f".tmp{os.getpid()}")
    torch.save(blob, tmp)
    os.replace(tmp, path)
    return path


def load_checkpoint(path) -> dict:
    """Read one of our checkpoints (or a published one, converted); returns the dict."""
    path = Path(path)
    if path.is_dir():
        raise SpikeSimFormatError(f"checkpoint {str(path)!r} is a folder: name a checkpoint "
                                  "file in it (a run's best.pt or last.pt)")
    if not path.is_file():
        raise SpikeSimFormatError(f"checkpoint {str(path)!r} does not exist")
    try:
        blob = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:
        raise CheckpointError(f"cannot read checkpoint {str(path)!r}: not a PyTorch checkpoint of "
                              f"tensors, or damaged ({type(exc).__name__})") from exc
    if isinstance(blob, dict) and blob.get("format") == FORMAT:
        if int(blob.get("format_version", -1)) not in (FORMAT_VERSION, INT8_FORMAT_VERSION):
            raise CheckpointError(f"{path}: format_version {blob.get('format_version')} is not "
                                  f"{FORMAT_VERSION} or {INT8_FORMAT_VERSION}; upgrade spikejdd")
        for key in ("config", "state_dict"):
            if key not in blob:
                raise CheckpointError(f"{path}: no {key!r} entry")
        return _dequantized(blob, path)
    if isinstance(blob, dict):  # published layout
        state = blob.get("model_state", blob)
        return {"format": FORMAT, "format_version": FORMAT_VERSION,
                "config": PUBLISHED.to_dict(),
                "state_dict": convert_published_state_dict(state),
                "data": {"source": f"converted from published checkpoint {path.name}"},
                "seed": None, "eval": {}, "train": {}, "versions": {}}
    raise CheckpointError(f"{path}: not a checkpoint dict (got {type(blob).__name__})")


def _dequantized(blob: dict, path) -> dict:
    """``blob`` with its int8 weights (if any) turned back into float32 ``q · s`` in
    ``state_dict``."""
    quantized, scales = blob.pop("int8_state", None) or {}, blob.pop("int8_scales", None) or {}
    if set(quantized) != set(scales):
        odd = sorted(set(quantized) ^ set(scales))
        raise CheckpointError(f"{path}: int8 weights and scales do not pair up: {odd[:5]}")
    state = dict(blob["state_dict"])
    for k, q in quantized.items():
        if q.dtype != torch.int8 or k in state:
            raise CheckpointError(f"{path}: int8 weight {k!r} is not int8 or is stored twice")
        state[k] = q.float() * scales[k].float()
    return dict(blob, state_dict=state)


def load_model(path_or_blob, device="cpu", strict: bool = True) -> SJDDNet:
    """Build the model a checkpoint describes and load its weights (strictly)."""
    blob = path_or_blob if isinstance(path_or_blob, dict) else load_checkpoint(path_or_blob)
    model = SJDDNet(SJDDConfig.from_dict(blob["config"]))
    state = {k: v.float() if v.is_floating_point() else v for k, v in blob["state_dict"].items()}
    if strict:
        check_state_dict(model, state, source=str(path_or_blob)[:200]
                         if not isinstance(path_or_blob, dict) else "checkpoint")
    model.load_state_dict(state, strict=strict)
    return model.to(device).eval()


def convert_published_state_dict(state: dict, config: SJDDConfig | None = None) -> dict:
    """Published key names (optionally ``module.``-prefixed) → ours, checked strictly
    against a model of ``config`` (default: the published configuration)."""
    if not isinstance(state, dict):
        raise SpikeSimTypeError(f"state must be a dict of tensors, got {type(state).__name__}")
    out, unknown = {}, []
    for key, value in state.items():
        k = key[len("module."):] if key.startswith("module.") else key
        for old, new in _RENAME.items():
            if k.startswith(old):
                k = new + k[len(old):]
                break
        else:
            if not k.startswith("mus."):
                unknown.append(key)
                continue
        out[k] = value
    if unknown:
        raise CheckpointError(f"published checkpoint has keys outside repre/estimator/prior/mus: "
                              f"{unknown[:8]}" + (f" ... ({len(unknown)} in all)"
                                                  if len(unknown) > 8 else ""))
    model = SJDDNet(config or PUBLISHED)
    check_state_dict(model, out, source="published checkpoint")
    return out


def to_published_state_dict(model: SJDDNet, prefix: str = "module.") -> dict:
    """Our state dict in the published layout (inverse of the converter)."""
    back = {v: k for k, v in _RENAME.items()}
    out = {}
    for k, v in model.state_dict().items():
        for new, old in back.items():
            if k.startswith(new):
                k = old + k[len(new):]
                break
        out[prefix + k] = v
    return out
