"""Options of :func:`spikesim.analysis.calibrate.calibrate`, validated in one place.

:class:`CalibrationConfig` holds what the fit assumes (the splits a capture
cannot identify, whether to fit the accumulating charge noise), how regions
are found, and how the goodness-of-fit re-simulation runs.  ``calibrate``
takes one (``config=``) or the same names as keyword arguments.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from spikesim._validate import is_int, is_real
from spikesim.errors import bad_value

__all__ = ["CalibrationConfig", "MIN_READOUTS", "DEFAULT_MISMATCH_SPLIT", "config_with"]

#: Shortest capture accepted (readouts): the length of public real samples.  At
#: 200 readouts a region needs a rate of 0.02 spikes/readout for the fit's 4 spikes
#: per pixel and intervals up to 40 readouts give at least 4 per pixel.
MIN_READOUTS = 200
#: Threshold-mismatch share of the combined response spread (package defaults, SCSim).
DEFAULT_MISMATCH_SPLIT = 0.045**2 / (0.045**2 + 0.058**2)


@dataclass(frozen=True)
class CalibrationConfig:
    """What the calibration assumes and how it checks itself.

    Parameters
    ----------
    detect : bool
        Find dark and flat regions automatically when no mask is given.
    min_pixels : int
        Smallest detected region (pixels, after erosion; on a colour capture a
        quarter of it, at least 32, in each colour plane).  256 by default: at a
        few spikes per pixel, smaller patches of moving content pass the
        one-level and motion tests by chance.
    electrons_per_threshold : float or None
        Known electrons per threshold (e⁻; from the chip's conversion gain):
        then the comparator jitter σ_t is fitted.  ``None``: σ_t is held at
        ``temporal_threshold_noise`` and E is fitted.
    temporal_threshold_noise : float
        Assumed comparator jitter σ_t (relative s.d. per cycle) when E is fitted.
    mismatch_split : float
        Threshold-mismatch share ``s²/(s² + p²)`` of the fitted response spread.
    full_scale_rate : float or None
        Known firing rate at radiance 1 (spikes per readout, e.g. a chip's
        rate at full white), for captures whose flat radiances are unknown:
        each flat region's radiance is then its dark-subtracted rate over the
        mean response ``r·(1 + s²)``, so the radiances and the currents
        relative to full scale (``dark_current_rel``, ``hot_pixel_dark_rel``)
        are measured, not fractions of the brightest region.  ``None``: the
        brightest region is full scale.  Not with ``flat_levels`` (the
        radiances already set the scale).
    fit_charge_noise : bool
        Fit ``charge_noise_electrons`` (interval CV² growing with the interval
        length) when the data supports it; ``False`` keeps it at 0.
    max_readouts : int or None
        Use only the first readouts of the capture.
    check : bool
        Re-simulate the fitted and the default sensor and compare statistics.
    check_readouts : int or None
        Readouts of the re-simulation (``None``: the whole capture).
    check_seed : int
        Seed of the re-simulation.
    """

    detect: bool = True
    min_pixels: int = 256
    electrons_per_threshold: float | None = None
    temporal_threshold_noise: float = 0.006
    mismatch_split: float = DEFAULT_MISMATCH_SPLIT
    full_scale_rate: float | None = None
    fit_charge_noise: bool = True
    max_readouts: int | None = None
    check: bool = True
    check_readouts: int | None = 4000
    check_seed: int = 1

    def __post_init__(self):
        for name in ("detect", "fit_charge_noise", "check"):
            if not isinstance(getattr(self, name), bool):
                raise bad_value(name, getattr(self, name), "True or False")
        if not is_int(self.min_pixels) or self.min_pixels < 1:
            raise bad_value("min_pixels", self.min_pixels, "an integer >= 1 (pixels)")
        e = self.electrons_per_threshold
        if e is not None and not (is_real(e) and float(e) > 0):
            raise bad_value("electrons_per_threshold", e, "a number > 0 or None")
        st = self.temporal_threshold_noise
        if not (is_real(st) and 0 <= float(st) <= 0.1):
            raise bad_value("temporal_threshold_noise", st, "a relative s.d. in [0, 0.1]")
        if not (is_real(self.mismatch_split) and 0 <= float(self.mismatch_split) <= 1):
            raise bad_value("mismatch_split", self.mismatch_split, "a share in [0, 1]")
        r = self.full_scale_rate
        if r is not None and not (is_real(r) and 0 < float(r) <= 1):
            raise bad_value("full_scale_rate", r, "a rate in (0, 1] spikes per readout, or None")
        for name in ("max_readouts", "check_readouts"):
            v = getattr(self, name)
            if v is not None and not (is_int(v) and v >= 1):
                raise bad_value(name, v, "an integer >= 1 (readouts) or None")
        if not is_int(self.check_seed) or self.check_seed < 0:
            raise bad_value("check_seed", self.check_seed, "a non-negative integer")


def config_with(config: CalibrationConfig | None, options: dict) -> CalibrationConfig:
    """``config`` (default: ``CalibrationConfig()``) with ``options`` replacing its fields."""
    base = CalibrationConfig() if config is None else config
    if not isinstance(base, CalibrationConfig):
        raise bad_value("config", type(base).__name__, "a CalibrationConfig or None")
    known = {f.name for f in dataclasses.fields(CalibrationConfig)}
    unknown = sorted(set(options) - known)
    if unknown:
        raise bad_value("calibrate options", unknown, f"names among {sorted(known)}")
    return dataclasses.replace(base, **options)
