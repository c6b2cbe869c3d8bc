"""Classical baselines: per-pixel intensity estimators (TFP, TFI) in scene units.

These are :mod:`spikesim.estimate` re-exported for the reconstruction side,
plus :func:`estimate_mosaic`, which picks an estimator by name.  Composition
with demosaicing and denoising into named pipelines is in
:mod:`spikejdd.pipelines`.
"""

from __future__ import annotations

import numpy as np

from spikesim.errors import bad_value
from spikesim.estimate import NO_SPIKE_RULES, tfi, tfp, tfp_std, window_bounds

__all__ = ["tfp", "tfi", "tfp_std", "window_bounds", "NO_SPIKE_RULES", "ESTIMATORS",
           "estimate_mosaic"]

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

    ``window`` defaults to 41 readouts for TFP and to the whole stream for TFI;
    ``no_spike`` is TFI's rule for pixels without a spike (see :func:`tfi`).
    """
    if estimator == "tfp":
        return tfp(spikes, center, 41 if window is None else window, rate)
    if estimator == "tfi":
        return tfi(spikes, center, rate, window=window, no_spike=no_spike)
    raise bad_value("estimator", estimator, f"one of {ESTIMATORS}")
