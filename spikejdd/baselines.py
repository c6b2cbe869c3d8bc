"""Classical baselines: per-pixel intensity estimators (TFP, TFI) in scene units.

These are :mod:`spikesim.estimate` re-exported for the reconstruction side,
plus :func:`estimate_mosaic`, which picks an estimator by name.  Composition
with demosaicing and denoising into named pipelines is in
:mod:`spikejdd.pipelines`.
"""

from __future__ import annotations

import numpy as np

from spikesim.errors import bad_value
from spikesim.estimate import (
    NO_SPIKE_RULES,
    TFP_DEFAULT_WINDOW,
    default_tfp_window,
    tfi,
    tfp,
    tfp_std,
    window_bounds,
)

__all__ = ["tfp", "tfi", "tfp_std", "window_bounds", "NO_SPIKE_RULES", "ESTIMATORS",
           "estimate_mosaic", "estimator_window", "TFP_DEFAULT_WINDOW", "default_tfp_window"]

ESTIMATORS: tuple[str, ...] = ("tfp", "tfi")


def estimate_mosaic(
    spikes: np.ndarray,
    center: int | None,
    estimator: str = "tfp",
    window: int | None = None,
    rate: float = 0.6,
    no_spike: str = "bound",
) -> np.ndarray:
    """(H, W) float64 intensity from the named estimator.

    ``window`` defaults to 41 readouts for TFP (the whole stream when it is
    shorter) and to the whole stream for TFI; an explicit window longer than
    the stream raises.  ``no_spike`` is TFI's rule for pixels without a spike
    (see :func:`tfi`).
    """
    if estimator == "tfp":
        return tfp(spikes, center, window, rate)
    if estimator == "tfi":
        return tfi(spikes, center, rate, window=window, no_spike=no_spike)
    raise bad_value("estimator", estimator, f"one of {ESTIMATORS}")


def estimator_window(estimator: str, window: int | None, n_readouts: int) -> int:
    """Readouts the named estimator uses on a stream of ``n_readouts`` (what to report)."""
    if window is not None:
        return int(window)
    if estimator == "tfp":
        return default_tfp_window(n_readouts)
    return int(n_readouts)
