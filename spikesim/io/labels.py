"""The noise and motion labels of a sequence, read from its metadata.

One function, :func:`sequence_labels`, so that ``spikesim info`` shows the
labels ``spikejdd evaluate`` groups its results by (spikejdd imports it from
here).
"""

from __future__ import annotations

__all__ = ["sequence_labels"]


def sequence_labels(meta: dict) -> dict:
    """``{"noise": ..., "motion": ...}`` of a sequence, read from its metadata.

    Noise: the dataset builder's label when there is one, else ``none``,
    ``GN<σ_g>``, ``GPN`` or ``physical`` from the sensor's noise model, and
    ``unknown`` for a capture (no sensor recorded: a converted ``.dat``).
    Motion: the scene's motion (``pan``, ``zoom``, ...), ``object`` for
    procedural scenes with built-in object motion, ``static``, or ``video``.
    """
    dataset = meta.get("dataset") or {}
    noise = (meta.get("sensor") or {}).get("noise") or None
    label = dataset.get("noise_label")
    if not label:
        if "sensor" not in meta:  # a capture (converted), not a simulation: noise unknown
            label = "unknown"
        elif not noise:
            label = "none"
        elif noise.get("type") == "paper":
            sg, sp = float(noise.get("sigma_g", 0.0)), float(noise.get("sigma_p", 0.0))
            label = "GPN" if sp > 0 else f"GN{sg:g}"
        else:
            label = str(noise.get("type", "other"))
    scene = meta.get("scene") or {}
    spec = dataset.get("scene_spec") or {}
    motion = scene.get("motion") or spec.get("motion")
    if not motion:
        kind = scene.get("type") or spec.get("kind")
        motion = {"procedural": "object", "static": "static", "video": "video"}.get(kind,
                                                                                  "unknown")
    return {"noise": str(label), "motion": str(motion)}
