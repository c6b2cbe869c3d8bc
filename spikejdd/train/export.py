"""Turning a run checkpoint into shippable weights (:func:`export_weights`)."""

from __future__ import annotations

from pathlib import Path

from spikejdd.models.checkpoints import load_checkpoint, save_checkpoint

__all__ = ["export_weights"]


def export_weights(checkpoint, dest, eval_result: dict | None = None) -> Path:
    """Write a run checkpoint as a shippable one: weights, configuration, data
    description, seed, training summary and ``eval_result`` — no optimizer state.
    Also writes ``<dest stem>.ref.json``, the reference output of
    :func:`spikejdd.models.reference_input` used by the tests."""
    from spikejdd.models import load_model, write_reference

    blob = load_checkpoint(checkpoint)
    model = load_model(blob)
    tr = blob.get("train") or {}
    summary = {k: tr.get(k) for k in ("step", "epoch", "best_psnr", "history", "train_config")}
    dest = Path(dest)
    save_checkpoint(dest, model, data=blob.get("data"), seed=blob.get("seed"),
                    eval=dict(blob.get("eval") or {}, **(eval_result or {})), train=summary)
    write_reference(model, dest.with_suffix(".ref.json"))
    return dest
