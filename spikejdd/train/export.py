"""Turning a run checkpoint into shippable weights (:func:`export_weights`)."""

from __future__ import annotations

from pathlib import Path

from spikejdd.models.checkpoints import load_checkpoint, save_checkpoint

__all__ = ["export_weights"]


def export_weights(checkpoint, dest, eval_result: dict | None = None,
                   precision: str = "float32") -> Path:
    """Write a run checkpoint as a shippable one: weights, configuration, data
    description, seed, training summary and ``eval_result`` — no optimizer state.
    ``precision`` (``"float32"``, ``"float16"`` or ``"int8"``) is how the weights
    are stored (see :func:`~spikejdd.models.save_checkpoint`; always read back as
    float32). Also writes ``<dest stem>.ref.json``, the reference output of
    :func:`spikejdd.models.reference_input` used by the tests, computed from the
    weights as stored."""
    from spikejdd.models import load_model, write_reference

    blob = load_checkpoint(checkpoint)
    model = load_model(blob)
    tr = blob.get("train") or {}
    summary = {k: tr.get(k) for k in ("step", "epoch", "best_psnr", "history", "train_config")}
    dest = Path(dest)
    save_checkpoint(dest, model, data=blob.get("data"), seed=blob.get("seed"),
                    eval=dict(blob.get("eval") or {}, **(eval_result or {})), train=summary,
                    precision=precision)
    write_reference(load_model(dest), dest.with_suffix(".ref.json"))
    return dest
