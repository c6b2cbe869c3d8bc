"""Calibration: fit the physical noise model and ``full_scale_rate`` to a capture.

:func:`calibrate` runs three steps, each in its own module:

0. **colour** — the capture's colour filter, from its metadata (HDF5, a
   simulated stream) or ``cfa=`` (a ``.dat``, an array); a capture of unknown
   filter that looks like colour is refused
   (:func:`spikesim.analysis.planes.refuse_colour_as_mono`);
1. **regions** — the user's dark/flat masks or automatic detection, plane by
   plane (:mod:`spikesim.analysis.calibration_regions`); a capture with no
   dark region is calibrated with the dark current held at the package
   defaults (stated in the notes);
2. **fit** — with flat regions :func:`spikesim.analysis.calibrate_fit.fit_parameters`
   (model, formulas and identifiability in its module notes), with the
   temporal noise (κ² and, when the interval CV² grows with the interval
   length, the charge noise ``charge_noise_electrons``) from
   :func:`spikesim.analysis.temporal_fit.fit_temporal`; without one,
   :func:`spikesim.analysis.natural_fit.fit_natural` (steady pixels' interval
   statistics, spatial residuals over locally flat neighbourhoods);
3. **report** — the fitted :class:`spikesim.Sensor`, each parameter's status
   (fitted, assumed, or *not identified* with the package default kept) and,
   unless ``check=False``, a goodness-of-fit check
   (:func:`spikesim.analysis.fitcheck.compare_resimulations`) that
   re-simulates the capture with the fitted sensor *and* with the package
   defaults, and compares both with the capture: per-pixel rate KS, interval
   CV per rate bin and spatial spread, as tables and a plot
   (:mod:`spikesim.analysis.calibration_report`).

Identifiability (stated, not hidden): rates depend on ``g/t`` and ``d/t``
only and intervals on κ² and σ_q² only, so two splits cannot be measured:
threshold mismatch vs PRNU (split with ``mismatch_split``) and comparator
jitter vs shot noise (give ``electrons_per_threshold`` to fit σ_t, otherwise
σ_t is held at ``temporal_threshold_noise`` and E is fitted).  Options are
the fields of :class:`spikesim.analysis.calibration_config.CalibrationConfig`.
"""

from __future__ import annotations

import numpy as np

import spikesim as ss
from spikesim.analysis.calibrate_fit import MIN_FLAT_SPIKES, SATURATED_RATE, fit_parameters
from spikesim.analysis.calibration_config import (
    DEFAULT_MISMATCH_SPLIT,
    MIN_READOUTS,
    CalibrationConfig,
    config_with,
)
from spikesim.analysis.calibration_regions import gather_regions, reason_counts
from spikesim.analysis.calibration_report import CalibrationResult, build_report
from spikesim.analysis.capture import as_capture, pixel_counts, pixel_intervals
from spikesim.analysis.natural_fit import fit_natural, window_counts
from spikesim.analysis.planes import planes_of, refuse_colour_as_mono
from spikesim.analysis.regions import describe_region
from spikesim.errors import bad_value

__all__ = ["calibrate", "CalibrationResult", "CalibrationConfig", "fit_parameters",
           "MIN_READOUTS", "DEFAULT_MISMATCH_SPLIT", "SATURATED_RATE"]

_LIMITS = {"dark_current_spread": 10.0, "threshold_mismatch": 0.3, "prnu": 0.3,
           "temporal_threshold_noise": 0.1, "hot_pixel_fraction": 1.0}


#: Reset modes the fit's rate and interval model describes (:mod:`calibrate_fit`).
CALIBRATED_RESETS = ("modulo", "subtract")


def _reset_mode(cap, reset, notes, given: str = "reset") -> str:
    """The capture's reset mode: the one its metadata records (a spikesim
    simulation; a ``reset`` given that differs is an error), else ``reset``,
    else modulo (stated in the notes).  Zero reset is refused: it discards each
    cycle's residual charge, so its rate is not linear in the charge and its
    intervals follow another law.  Errors call the parameter ``given``."""
    sensor = cap.meta.get("sensor")
    recorded = sensor.get("reset") if isinstance(sensor, dict) else None
    name = given
    if reset is None:
        reset, name = recorded, "the capture's reset mode (its metadata)"
    elif recorded is not None and reset != recorded:
        raise bad_value(given, reset, f"the capture's own reset mode {recorded!r}, which its "
                        f"metadata records (or leave {given} out)")
    if reset is None:
        notes.append("reset mode unknown: modulo assumed (modulo and subtract reset fire "
                     "alike below one threshold per readout); pass reset= (--reset) if it "
                     "is known")
        return "modulo"
    if reset not in CALIBRATED_RESETS:
        raise bad_value(name, reset,
                        "'modulo' or 'subtract': the calibration's rate and interval model has "
                        "no zero-reset form (a zero reset discards each cycle's residual "
                        "charge)" if reset == "zero" else "'modulo' or 'subtract'")
    return reset


def _planes(cap, rate, option: str):
    """The capture's colour planes; a capture whose colour filter is unknown
    (a ``.dat`` or an array, no ``cfa`` given) is refused when it looks like
    colour (:func:`spikesim.analysis.planes.refuse_colour_as_mono`)."""
    if cap.cfa is None and not cap.cfa_known:
        refuse_colour_as_mono(rate, option)
    return planes_of(cap.cfa, cap.height, cap.width)


#: A detected flat region is left out when its response spread's CV² exceeds the most
#: precise region's by more than this factor and :data:`ODD_Z` standard errors.
ODD_FACTOR = 1.44
ODD_Z = 3.0


def _fit_flat(rate, mom, n, reg, flat_levels, cfg, names, notes):
    """The fit with flat regions (:func:`fit_parameters`), detected regions whose
    spread is out of line left out (:func:`_inconsistent`, with a note; ``reg``
    is updated); returns ``(params, diag, levels, hot, identified, scale_known)``."""
    levels = reg.levels(flat_levels, names["flat_levels"])
    if levels is not None and cfg.full_scale_rate is not None:
        raise bad_value(names.get("full_scale_rate", "full_scale_rate"), cfg.full_scale_rate,
                        f"None when {names['flat_levels']} are given (the radiances already "
                        "set the scale)")
    scale_known = levels is not None or cfg.full_scale_rate is not None
    params, diag, lv, hot = fit_parameters(rate, mom, n, reg.dark, reg.flats, levels, cfg,
                                           reg.names, reg.planes)
    odd = _inconsistent(diag["region_spreads"]) if reg.detected is not False else []
    if odd and len(odd) < len(reg.flats):  # moving or textured content: fit without it
        notes.append(
            "left out as moving or textured content: " + ", ".join(
                f"{reg.names[i]} {describe_region(reg.flats[i], rate)}, response spread "
                f"{np.sqrt(max(diag['region_spreads'][i][0], 0)):.3g}" for i in odd)
            + f" (its spread exceeds the best-measured region's by more than {ODD_FACTOR:g}x "
            f"in variance and {ODD_Z:g} standard errors; the chip's pattern is the same "
            "everywhere, moving or textured content adds to it)")
        keep = [i for i in range(len(reg.flats)) if i not in odd]
        reg.flats, reg.planes = [reg.flats[i] for i in keep], [reg.planes[i] for i in keep]
        reg.names, reg.source = [reg.names[i] for i in keep], [reg.source[i] for i in keep]
        levels = None if levels is None else np.asarray(levels)[keep]
        params, diag, lv, hot = fit_parameters(rate, mom, n, reg.dark, reg.flats, levels, cfg,
                                               reg.names, reg.planes)
    diag["region_spreads"] = [list(v) for v in diag["region_spreads"]]
    return params, diag, lv, hot, diag.pop("identified"), scale_known


def _inconsistent(spreads) -> list:
    """Indices of the flat regions whose response spread ``(CV², s.e.)`` is too high
    against the most precisely measured one's (:data:`ODD_FACTOR`, :data:`ODD_Z`):
    the chip's pattern is the same everywhere, and moving or textured content
    only adds to a region's spread."""
    known = [cs for cs in spreads if np.isfinite(cs[1])]
    if len(known) < 2:
        return []
    ref, ref_se = min(known, key=lambda cs: cs[1])
    return [i for i, (cv2, se) in enumerate(spreads) if np.isfinite(se)
            and cv2 > ODD_FACTOR * max(ref, 0.0) and cv2 - ref > ODD_Z * np.hypot(se, ref_se)]


def _left_out(dropped) -> str:
    """For the no-flat-region errors: what detection left out, or nothing."""
    return f"; left out: {reason_counts(dropped)}" if dropped else ""


def _sensor(cap, params, notes, reset):
    for k, hi in _LIMITS.items():
        if params[k] > hi:
            notes.append(f"{k} = {params[k]:.4g} clipped to the model's limit {hi}")
            params[k] = hi
    noise = ss.noise.PhysicalNoise(**{k: v for k, v in params.items() if k != "full_scale_rate"})
    if not cap.clock_hz:
        notes.append("clock unknown: the sensor's clock_hz is set to 20 kHz (rates per "
                     "readout are what was fitted)")
    return ss.Sensor(height=cap.height, width=cap.width, cfa=cap.cfa,
                     clock_hz=cap.clock_hz or 20_000.0, reset=reset,
                     full_scale_rate=params["full_scale_rate"], noise=noise)


def calibrate(capture, *, dark_mask=None, flat_masks=None, flat_levels=None,
              config: CalibrationConfig | None = None, cfa: str | None = None,
              clock_hz: float | None = None, height: int | None = None,
              width: int | None = None, flip: bool = True, reset: str | None = None,
              progress: bool = False, option_names: dict | None = None,
              **options) -> CalibrationResult:
    """Fit a :class:`spikesim.Sensor` with :class:`~spikesim.noise.PhysicalNoise` to a capture.

    Parameters
    ----------
    capture : path, (T, H, W) array, SpikeStream, DatFile or Sequence
        The spike capture, at least :data:`MIN_READOUTS` (200) readouts (a
        ``.dat`` needs ``height``/``width``; ``flip`` as in
        :func:`spikesim.io.read_dat`; ``cfa``/``clock_hz`` override the source).
    cfa : str, optional
        The colour filter (``"RGGB"``, ``"BGGR"``, ``"GRBG"``, ``"GBRG"``, or
        ``"mono"``) of a capture that does not record it (a ``.dat``, an
        array); a colour capture is fitted plane by plane.  A capture of
        unknown filter that looks like colour is refused with an error saying
        to pass it.
    reset : {"modulo", "subtract"}, optional
        The capture's reset mode, kept in the fitted sensor; by default the
        one a spikesim capture records (a different one given is an error),
        else modulo (stated in the notes).  Zero-reset captures are refused:
        the fit's model does not describe them.
    dark_mask : (H, W) bool, optional
        Pixels that saw no light.
    flat_masks : list of (H, W) bool, or (H, W) int labels (0 = none), optional
        Regions of uniform radiance (on a colour capture each is split into
        its colour planes).  When neither mask is given and ``detect`` is
        true, both are found by :mod:`spikesim.analysis.calibration_regions`;
        when no flat region is found, the capture is calibrated without one
        (:mod:`spikesim.analysis.natural_fit`).
    flat_levels : sequence of float, optional
        Radiance of each flat region in scene units (1 = full scale); without
        them the brightest region is full scale, unless ``full_scale_rate``
        (a :class:`CalibrationConfig` field) gives the rate at radiance 1.
    config : CalibrationConfig, optional
        Fit assumptions and check settings; ``**options`` (its field names:
        ``detect``, ``electrons_per_threshold``, ``temporal_threshold_noise``,
        ``mismatch_split``, ``full_scale_rate``, ``fit_charge_noise``, ``max_readouts``, ``check``,
        ``check_readouts``, ``check_seed``, ``min_pixels``) replace its fields.
    option_names : dict, optional
        How errors name ``flat_levels``, ``reset``, ``full_scale_rate`` and
        ``cfa`` (the CLI passes its flags, ``{"flat_levels": "--levels", "reset":
        "--reset", "full_scale_rate": "--full-scale-rate", "cfa": "--cfa"}``);
        default: the keyword names.
    """
    cfg = config_with(config, options)
    cap = as_capture(capture, height=height, width=width, flip=flip, cfa=cfa, clock_hz=clock_hz)
    n = cap.n_readouts if cfg.max_readouts is None else min(cfg.max_readouts, cap.n_readouts)
    if n < MIN_READOUTS:
        raise bad_value("capture length", f"{n} readouts",
                        f"at least {MIN_READOUTS} readouts for calibration")
    names = {"flat_levels": "flat_levels", "reset": "reset", **(option_names or {})}
    region_notes: list[str] = []
    reset = _reset_mode(cap, reset, region_notes, names["reset"])
    rate = pixel_counts(cap, 0, n, progress=progress) / n
    planes = _planes(cap, rate, names.get("cfa", "cfa"))
    reg = gather_regions(cap, rate, n, dark_mask, flat_masks, cfg, planes, progress,
                         region_notes)
    dark, flats, detected = reg.dark, reg.flats, reg.detected
    mom = pixel_intervals(cap, 0, n, progress=progress)
    natural = None
    if not flats:  # no flat region: per-pixel temporal statistics and spatial residuals
        if flat_levels is not None:
            raise bad_value(names["flat_levels"], flat_levels, "no radiances: no flat region was "
                            "found, and the capture is calibrated without one")
        region_notes.append("no flat region found (a uniform, static region of >= "
                            f"{cfg.min_pixels} pixels and >= {MIN_FLAT_SPIKES} spikes per pixel "
                            f"below saturation{_left_out(reg.left_out)}): calibrated from "
                            "per-pixel temporal statistics and spatial residuals instead")
        counts = window_counts(cap, n)
        params, diag, hot, pools, steady, identified = fit_natural(rate, mom, counts, n, dark,
                                                                   planes, cfg)
        natural, lv, scale_known = (pools, steady, planes), np.zeros(0), \
            cfg.full_scale_rate is not None
    else:
        params, diag, lv, hot, identified, scale_known = _fit_flat(
            rate, mom, n, reg, flat_levels, cfg, names, region_notes)
        flats = reg.flats
    notes = region_notes + list(diag.pop("notes"))
    sensor = _sensor(cap, params, notes, reset)
    fit = None
    if cfg.check:
        from spikesim.analysis.fitcheck import compare_resimulations, default_sensor_like

        fit = compare_resimulations(
            cap, {"calibrated": sensor,
                  "defaults": default_sensor_like(sensor, scale_known=scale_known)},
            rate, dark, flats, lv, hot, n_readouts=min(n, cfg.check_readouts or n),
            seed=cfg.check_seed, progress=progress, natural=natural)
    return build_report(cap, n, cfg, sensor, params, diag, notes, dark, flats, lv,
                        "none" if natural else detected, fit, identified, scale_known,
                        natural is not None)
