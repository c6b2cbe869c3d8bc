"""Named classical pipelines: estimator → demosaic → optional spatial denoiser.

Grammar of a pipeline name (all lower case)::

    <estimator>[<window>] + <demosaic> [+ <denoiser>]

* estimator: ``tfp`` (window default 41 readouts, or the whole stream when it
  is shorter) or ``tfi`` (search range default: the whole stream); an
  optional window in readouts follows the name directly, e.g. ``tfp21`` —
  this is the temporal-denoising choice; an explicit window longer than the
  stream is an error;
* demosaic: ``bilinear``, ``malvar2004``, ``menon2007``, ``opencv_ea``
  (:mod:`spikejdd.demosaic`);
* denoiser: ``nlm`` or ``bilateral`` (:mod:`spikejdd.denoise`).

Examples: ``tfp+bilinear``, ``tfi+malvar2004``, ``tfp+menon2007+nlm``,
``tfp21+opencv_ea+bilateral``.  The estimate is demosaiced in linear scene
units and the result is clipped to [0, 1] (the range of the ground truth).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from spikejdd.baselines import ESTIMATORS, estimate_mosaic, estimator_window
from spikejdd.demosaic import DEMOSAIC_METHODS, demosaic
from spikejdd.denoise import DENOISE_METHODS, denoise

__all__ = ["Pipeline", "parse_pipeline", "standard_pipelines", "PIPELINE_GRAMMAR"]

PIPELINE_GRAMMAR = "<tfp|tfi>[window]+<" + "|".join(DEMOSAIC_METHODS) + ">[+<" + "|".join(
    DENOISE_METHODS
) + ">]"

_NAME = re.compile(
    r"^(?P<est>" + "|".join(ESTIMATORS) + r")(?P<win>[1-9][0-9]*)?"
    r"\+(?P<dem>" + "|".join(DEMOSAIC_METHODS) + r")"
    r"(?:\+(?P<den>" + "|".join(DENOISE_METHODS) + r"))?$"
)


@dataclass(frozen=True)
class Pipeline:
    """A parsed pipeline; call it like any registered method."""

    name: str
    estimator: str
    window: int | None
    demosaic: str
    denoiser: str | None

    def __call__(
        self,
        spikes: np.ndarray,
        cfa: str | None,
        center: int | None,
        rate: float = 0.6,
        no_spike: str = "bound",
    ) -> np.ndarray:
        raw = estimate_mosaic(spikes, center, self.estimator, self.window, rate, no_spike)
        rgb = demosaic(raw, cfa, self.demosaic)
        np.clip(rgb, 0.0, 1.0, out=rgb)
        if self.denoiser is not None:
            rgb = denoise(rgb, self.denoiser)
            np.clip(rgb, 0.0, 1.0, out=rgb)
        return rgb

    def window_for(self, n_readouts: int, **_options) -> int:
        """Readouts this pipeline uses on a stream of ``n_readouts`` (reported with results)."""
        return estimator_window(self.estimator, self.window, n_readouts)

    @property
    def description(self) -> str:
        win = f"{self.window} readouts" if self.window else "default window"
        den = f", then {self.denoiser}" if self.denoiser else ""
        return f"{self.estimator.upper()} ({win}), {self.demosaic} demosaic{den}"


def parse_pipeline(name: str) -> Pipeline | None:
    """Return the :class:`Pipeline` for a name matching the grammar, else ``None``."""
    if not isinstance(name, str):
        return None
    m = _NAME.match(name.strip().lower())
    if m is None:
        return None
    win = int(m["win"]) if m["win"] else None
    return Pipeline(name.strip().lower(), m["est"], win, m["dem"], m["den"])


def standard_pipelines() -> list[str]:
    """The pipelines the baseline sweep scores (every estimator × demosaic, and denoisers)."""
    names = [f"{e}+{d}" for e in ESTIMATORS for d in DEMOSAIC_METHODS]
    names += [f"tfp+menon2007+{n}" for n in DENOISE_METHODS]
    names += ["tfp21+menon2007", "tfi+menon2007+nlm"]
    return names


PipelineFn = Callable[..., np.ndarray]
