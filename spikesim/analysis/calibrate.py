"""Calibration: fit the physical noise model and ``full_scale_rate`` to a capture.

:func:`calibrate` runs three steps, each in its own module:

1. **regions** — the user's dark/flat masks (:func:`spikesim.analysis.masks.check_regions`)
   or, without masks, automatic detection on the rate map
   (:func:`spikesim.analysis.regions.detect_regions`); a capture with no flat
   region is refused (the gain cannot be measured without one), a capture
   with no dark region is calibrated with the dark current held at the
   package defaults (stated in the notes);
2. **fit** — :func:`spikesim.analysis.calibrate_fit.fit_parameters` (model,
   formulas and identifiability in its module notes), with the temporal
   noise (κ² and, when the interval CV² grows with the interval length, the
   charge noise ``charge_noise_electrons``) from
   :func:`spikesim.analysis.temporal_fit.fit_temporal`;
3. **report** — the fitted :class:`spikesim.Sensor` and, unless
   ``check=False``, a goodness-of-fit check
   (:func:`spikesim.analysis.fitcheck.compare_resimulations`) that
   re-simulates the capture's regions with the fitted sensor *and* with the
   package defaults, and compares both with the capture: per-pixel rate KS,
   interval CV per rate bin and spatial spread.

Identifiability (stated, not hidden): rates depend on ``g/t`` and ``d/t``
only and intervals on κ² and σ_q² only, so two splits cannot be measured:
threshold mismatch vs PRNU (split with ``mismatch_split``) and comparator
jitter vs shot noise (give ``electrons_per_threshold`` to fit σ_t, otherwise
σ_t is held at ``temporal_threshold_noise`` and E is fitted).  Options are
the fields of :class:`spikesim.analysis.calibration_config.CalibrationConfig`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import spikesim as ss
from spikesim.analysis.calibrate_fit import MIN_FLAT_SPIKES, SATURATED_RATE, fit_parameters
from spikesim.analysis.calibration_config import (
    DEFAULT_MISMATCH_SPLIT,
    MIN_READOUTS,
    CalibrationConfig,
    config_with,
)
from spikesim.analysis.capture import as_capture, pixel_counts, pixel_intervals
from spikesim.analysis.masks import check_regions, flat_names
from spikesim.analysis.regions import describe_region, find_regions, motion_score
from spikesim.analysis.report import AnalysisResult
from spikesim.errors import SpikeSimValueError, bad_value

__all__ = ["calibrate", "CalibrationResult", "CalibrationConfig", "fit_parameters",
           "MIN_READOUTS", "DEFAULT_MISMATCH_SPLIT", "SATURATED_RATE"]

_LIMITS = {"dark_current_spread": 10.0, "threshold_mismatch": 0.3, "prnu": 0.3,
           "temporal_threshold_noise": 0.1, "hot_pixel_fraction": 1.0}


@dataclass
class CalibrationResult(AnalysisResult):
    """An :class:`AnalysisResult` with the fitted ``sensor`` and the region masks used."""

    sensor: ss.Sensor | None = None
    dark_mask: np.ndarray | None = None
    flat_masks: list | None = None
    flat_levels: list | None = None


def _regions(cap, rate, n, dark_mask, flat_masks, cfg, progress, notes):
    """(dark, flats, detected) from the masks or by detection.  Given flat masks
    that fail the motion test of :mod:`spikesim.analysis.regions` get a note,
    and so does each detected candidate region that is left out."""
    shape = (cap.height, cap.width)
    dark, flats = check_regions(dark_mask, flat_masks, shape)
    if (dark is None and not flats) and not cfg.detect:
        raise bad_value("dark_mask/flat_masks", None, "masks, or detect=True")
    first = pixel_counts(cap, 0, n // 2, progress=progress) / (n // 2)
    second = (rate * n - first * (n // 2)) / (n - n // 2)
    if dark is not None and not flats and cfg.detect:  # the dark region given, flats found
        found = _detect(rate, n, cfg, first, second, notes)
        flats = [f & ~dark for f in found.flats if (f & ~dark).sum() >= cfg.min_pixels]
        flats = _bright_enough(flats, rate, n, notes)
        if not flats:
            raise bad_value("flat_masks", None,
                            "flat masks: none was given and no flat region was found outside "
                            f"dark_mask (a uniform, static region of >= {cfg.min_pixels} pixels "
                            f"and >= {MIN_FLAT_SPIKES} spikes per pixel below saturation"
                            f"{_left_out(found)})")
        return dark, flats, "flat regions"
    if dark is not None or flats:
        change = (second - first) * (n / 2)
        for name, f in zip(flat_names(flat_masks, len(flats)), flats, strict=True):
            r, limit = motion_score(f, change)
            if r > limit:
                notes.append(f"{name} does not look static: its pixels' count changes "
                             f"between the capture's halves are correlated between neighbours "
                             f"(r = {r:.3g} > {limit:.3g}); its intervals inflate the fitted "
                             "temporal noise")
        return dark, flats, False
    found = _detect(rate, n, cfg, first, second, notes)
    flats = _bright_enough(found.flats, rate, n, notes)
    if not flats:
        raise SpikeSimValueError(
            "no flat region found in the capture: the gain cannot be fitted without a "
            f"uniform, static region of >= {cfg.min_pixels} pixels and >= {MIN_FLAT_SPIKES} "
            "spikes per pixel below saturation (a longer capture helps), or regions given as "
            f"flat_masks{_left_out(found)}")
    return found.dark, flats, True


#: Most left-out candidate regions the notes name one by one (the largest first).
MAX_DROPPED_NOTES = 10


def _detect(rate, n, cfg, first, second, notes):
    """:func:`spikesim.analysis.regions.find_regions` on the capture; a note per
    candidate region left out (up to :data:`MAX_DROPPED_NOTES`, then one for the rest)."""
    found = find_regions(rate, n, min_pixels=cfg.min_pixels, halves=np.stack([first, second]))
    dropped = sorted(found.dropped, key=lambda d: -d.pixels)
    notes.extend(d.describe() for d in dropped[:MAX_DROPPED_NOTES])
    rest = dropped[MAX_DROPPED_NOTES:]
    if rest:
        notes.append(f"{len(rest)} smaller detected candidate regions "
                     f"({sum(d.pixels for d in rest)} pixels) were left out too: "
                     f"{_reason_counts(rest)}")
    return found


def _reason_counts(dropped) -> str:
    """``2 not static, 1 not uniform``: how many of ``dropped`` were left out for each reason."""
    kinds: dict[str, int] = {}
    for d in dropped:
        key = d.reason.split(" (")[0]
        kinds[key] = kinds.get(key, 0) + 1
    return ", ".join(f"{v} {k}" for v, k in sorted(((v, k) for k, v in kinds.items()),
                                                    reverse=True))


def _left_out(found) -> str:
    """For the no-flat-region errors: what detection left out, or nothing."""
    return f"; left out: {_reason_counts(found.dropped)}" if found.dropped else ""


def _bright_enough(flats, rate, n, notes):
    """The detected flat regions with at least :data:`MIN_FLAT_SPIKES` spikes per
    pixel (the fit needs them); each one dropped gets a note."""
    kept = []
    for f in flats:
        spikes = min(float(np.mean(rate[f])), float(np.median(rate[f]))) * n
        if spikes >= MIN_FLAT_SPIKES:
            kept.append(f)
        else:
            notes.append(f"a detected flat region {describe_region(f, rate)} was left out: "
                         f"too dim, {spikes:.3g} spikes per pixel, fewer than the fit's "
                         f"{MIN_FLAT_SPIKES} (a longer capture would keep it)")
    return kept


def _levels(flat_levels, flats, name: str = "flat_levels"):
    """The radiances (scene units, 1 = full scale) of the flat regions, one per
    region, or None; errors call the parameter ``name``."""
    if flat_levels is None:
        return None
    lv = np.asarray(flat_levels, dtype=np.float64).ravel()
    if lv.size != len(flats) or np.any(~np.isfinite(lv)) or np.any(lv <= 0):
        raise bad_value(name, lv.tolist(),
                        f"{len(flats)} finite radiances > 0, one per flat region")
    return lv


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
    reset : {"modulo", "subtract"}, optional
        The capture's reset mode, kept in the fitted sensor; by default the
        one a spikesim capture records (a different one given is an error),
        else modulo (stated in the notes).  Zero-reset captures are refused:
        the fit's model does not describe them.
    dark_mask : (H, W) bool, optional
        Pixels that saw no light.
    flat_masks : list of (H, W) bool, or (H, W) int labels (0 = none), optional
        Regions of uniform radiance.  When neither mask is given and
        ``detect`` is true, both are found by
        :func:`spikesim.analysis.regions.detect_regions`.
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
        How errors name ``flat_levels``, ``reset`` and ``full_scale_rate`` (the
        CLI passes its flags, ``{"flat_levels": "--levels", "reset": "--reset",
        "full_scale_rate": "--full-scale-rate"}``); default: the keyword names.
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
    dark, flats, detected = _regions(cap, rate, n, dark_mask, flat_masks, cfg, progress,
                                     region_notes)
    levels = _levels(flat_levels, flats, names["flat_levels"])
    if levels is not None and cfg.full_scale_rate is not None:
        raise bad_value(names.get("full_scale_rate", "full_scale_rate"), cfg.full_scale_rate,
                        f"None when {names['flat_levels']} are given (the radiances already "
                        "set the scale)")
    scale_known = levels is not None or cfg.full_scale_rate is not None
    mom = pixel_intervals(cap, 0, n, progress=progress)
    params, diag, lv, hot = fit_parameters(
        rate, mom, n, dark, flats, levels, cfg,
        flat_names(flat_masks if detected is False else None, len(flats)))
    notes = region_notes + list(diag.pop("notes"))
    sensor = _sensor(cap, params, notes, reset)
    fit = None
    if cfg.check:
        from spikesim.analysis.fitcheck import compare_resimulations, default_sensor_like

        fit = compare_resimulations(
            cap, {"calibrated": sensor,
                  "defaults": default_sensor_like(sensor, scale_known=scale_known)},
            rate, dark,
            flats, lv, hot, n_readouts=min(n, cfg.check_readouts or n), seed=cfg.check_seed,
            progress=progress)
    return _report(cap, n, cfg, sensor, params, diag, notes, dark, flats, lv, detected, fit,
                   flat_levels_unknown=not scale_known)


#: How the regions were found, by ``_regions``' third result, for the report.
_REGIONS_FROM = {True: "detected automatically", False: "from masks",
                 "flat regions": "dark region from dark_mask, flat regions detected"}


def _report(cap, n, cfg, sensor, params, diag, notes, dark, flats, lv, detected, fit,
            flat_levels_unknown: bool):
    """Assemble the :class:`CalibrationResult` (data, tables, notes, plot)."""
    gof = None if fit is None else {
        **{k: v for k, v in fit["fits"]["calibrated"].items() if k != "plot"},
        "defaults": {k: v for k, v in fit["fits"]["defaults"].items() if k != "plot"},
        "comparison": [dict(zip(fit["headers"], r, strict=True)) for r in fit["rows"]]}
    result = CalibrationResult("calibration", "Calibration of the noise model", {},
                               sensor=sensor, dark_mask=dark, flat_masks=flats,
                               flat_levels=list(map(float, lv)))
    result.data = {"capture": {"name": cap.name, "shape": [n, cap.height, cap.width],
                               "cfa": cap.cfa, "clock_hz": cap.clock_hz},
                   "regions": {"detected": detected, "dark_pixels": diag["dark_pixels"],
                               "flat_pixels": diag["flat_pixels"], "flat_levels": lv},
                   "parameters": params, "diagnostics": diag, "sensor": sensor.to_dict(),
                   "goodness_of_fit": gof, "notes": notes}
    result.tables = [("Fitted parameters", ["parameter", "value"], list(params.items())),
                     ("Diagnostics", ["quantity", "value"],
                      [(k, v) for k, v in diag.items() if not isinstance(v, (list, np.ndarray))])]
    if fit is not None:
        cal = fit["fits"]["calibrated"]
        result.tables += [
            ("Goodness of fit: distances of each re-simulation from the capture (smaller is "
             "closer)", fit["headers"], fit["rows"]),
            ("Interval CV per rate bin (calibrated re-simulation)",
             ["mean interval (readouts)", "capture pixels", "capture CV", "re-sim CV"],
             [(f"{b['lo']:g}-{b['hi']:g}", b["capture_pixels"], b["capture_cv"], b["resim_cv"])
              for b in cal["summary"]["cv_bins"]]),
            ("Goodness of fit per region: capture against re-simulation of the fitted sensor",
             cal["headers"], cal["rows"])]
        result.plot = cal["plot"]
    temporal = ("with E given." if cfg.electrons_per_threshold is not None else
                f"with σ_t held at {cfg.temporal_threshold_noise}.")
    result.notes = [
        f"Capture {cap.name}: {n} readouts × {cap.height} × {cap.width}; regions "
        f"{_REGIONS_FROM[detected]}: "
        f"{diag['dark_pixels']} dark pixels, flat regions of {diag['flat_pixels']} pixels at "
        f"radiances {[round(float(v), 4) for v in lv]}.",
        "Identifiability: threshold mismatch and PRNU are split with mismatch_split = "
        f"{cfg.mismatch_split:.3g} (combined response spread fitted: "
        f"{diag['combined_gain_spread']:.4g}); comparator jitter and shot noise share the "
        f"fitted cycle CV² κ² = {diag['kappa2']:.4g} " + temporal + " The charge loss at "
        "reset (reset_charge_loss) is not fitted and is held at 0: a loss f would appear as "
        "a slightly lower rate (q/(1 + f·q)) folded into the response.",
        *notes,
    ]
    if fit is not None:
        result.notes.append(_verdict(fit["rows"]))
        if flat_levels_unknown:
            result.notes.append("The defaults' re-simulation keeps the fitted dark_current_rel "
                                "and hot_pixel_dark_rel: with radiances unknown, full scale is "
                                "the brightest region and fractions of it are not comparable.")
    return result


def _verdict(rows) -> str:
    """One sentence: which re-simulation is closer on each summary distance."""
    (_, *cal), (_, *dft) = rows
    names = ["rate KS", "interval CV", "spatial spread"]
    parts = []
    for name, c, d in zip(names, cal, dft, strict=True):
        if not (np.isfinite(c) and np.isfinite(d)):
            parts.append(f"{name}: not measured")
        else:
            parts.append(f"{name}: {'calibrated' if c <= d else 'defaults'} closer "
                         f"({c:.3g} vs {d:.3g})")
    return "Re-simulation against the capture, calibrated vs package defaults — " + \
        "; ".join(parts) + "."
