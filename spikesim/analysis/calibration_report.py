"""A calibration's report: the parameters, what identified each, and the goodness of fit.

:func:`build_report` assembles the :class:`CalibrationResult` of
:func:`spikesim.analysis.calibrate.calibrate`:

* **data** (JSON): the capture, the regions (or pools), the parameters, their
  ``status`` (:func:`parameter_status`), the diagnostics (per colour plane
  too), the fitted sensor, the goodness of fit and the notes;
* **tables** (Markdown): parameters with their status, the per-plane fit of a
  colour capture, diagnostics, and the goodness of fit side by side
  (:mod:`spikesim.analysis.gof_report`);
* **plot** (PNG): the three goodness-of-fit panels of
  :func:`spikesim.analysis.gof_report.plot_comparison`.

A parameter's status is ``fitted``, ``assumed ...`` (a split the capture
cannot make: the stated assumption decides it), ``relative ...`` (a scale
set by a convention) or ``not identified: <why>`` — then it keeps the package
default and the report says so instead of giving a number the data cannot
support.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import spikesim as ss
from spikesim.analysis.gof_report import (
    comparison_rows,
    cv_rows,
    plot_comparison,
    spread_rows,
    verdict,
)
from spikesim.analysis.report import AnalysisResult

__all__ = ["CalibrationResult", "build_report", "parameter_status"]


@dataclass
class CalibrationResult(AnalysisResult):
    """An :class:`AnalysisResult` with the fitted ``sensor`` and the region masks used."""

    sensor: ss.Sensor | None = None
    dark_mask: np.ndarray | None = None
    flat_masks: list | None = None
    flat_levels: list | None = None


#: How the regions were found (``Regions.detected``, or "none" without a flat region).
_REGIONS_FROM = {True: "detected automatically", False: "from masks",
                 "flat regions": "dark region from dark_mask, flat regions detected",
                 "none": "no flat region"}


def parameter_status(params: dict, identified: dict, cfg, scale_known: bool,
                     natural: bool) -> dict:
    """Each parameter's status (module notes); ``identified`` maps a parameter
    the capture could not identify to the reason."""
    out = {}
    for k in params:
        if k in identified and identified[k] is not True:
            out[k] = str(identified[k]) + " (package default kept)"
        else:
            out[k] = "fitted"
    for k in ("threshold_mismatch", "prnu"):
        if out[k] == "fitted":
            out[k] = f"fitted, split assumed (mismatch_split = {cfg.mismatch_split:.3g})"
    if cfg.electrons_per_threshold is not None:
        out["electrons_per_threshold"] = "given (electrons_per_threshold)"
    elif out["temporal_threshold_noise"] == "fitted":
        out["temporal_threshold_noise"] = ("assumed (temporal_threshold_noise = "
                                           f"{cfg.temporal_threshold_noise:g}); E fitted")
    if not scale_known and out["full_scale_rate"] == "fitted":
        out["full_scale_rate"] = ("relative: radiance 1 is the " +
                                  ("99th percentile of the pooled rates" if natural else
                                   "brightest flat region"))
    elif cfg.full_scale_rate is not None:
        out["full_scale_rate"] = "given (full_scale_rate)"
    return out


def build_report(cap, n, cfg, sensor, params, diag, notes, dark, flats, lv, detected, fit,
                 identified: dict, scale_known: bool, natural: bool) -> CalibrationResult:
    """Assemble the :class:`CalibrationResult` (module notes)."""
    status = parameter_status(params, identified, cfg, scale_known, natural)
    ties = _ties(status)
    gof = None
    if fit is not None:
        headers, rows = comparison_rows(fit["fits"], ties)
        strip = ("plot", "curves")
        gof = {**{k: v for k, v in fit["fits"]["calibrated"].items() if k not in strip},
               "defaults": {k: v for k, v in fit["fits"]["defaults"].items() if k not in strip},
               "comparison": [dict(zip(fit["headers"], r, strict=True)) for r in fit["rows"]],
               "side_by_side": [dict(zip(headers, r, strict=True)) for r in rows],
               "method": "pools (no flat region)" if natural else "regions"}
    result = CalibrationResult("calibration", "Calibration of the noise model", {},
                               sensor=sensor, dark_mask=dark, flat_masks=flats,
                               flat_levels=list(map(float, lv)))
    regions = {"detected": detected, "dark_pixels": diag["dark_pixels"],
               "flat_pixels": diag.get("flat_pixels", []), "flat_levels": lv}
    if natural:
        regions.update(steady_pixels=diag["steady_pixels"], pool_pixels=diag["pool_pixels"])
    result.data = {"capture": {"name": cap.name, "shape": [n, cap.height, cap.width],
                               "cfa": cap.cfa, "clock_hz": cap.clock_hz},
                   "regions": regions, "parameters": params, "status": status,
                   "identified": {k: k not in identified for k in params},
                   "diagnostics": diag, "sensor": sensor.to_dict(), "goodness_of_fit": gof,
                   "notes": notes}
    result.tables = [("Fitted parameters", ["parameter", "value", "status"],
                      [(k, v, status[k]) for k, v in params.items()])]
    if cap.cfa is not None:
        result.tables.append(_plane_table(diag["planes"], natural))
    result.tables.append(("Diagnostics", ["quantity", "value"],
                          [(k, v) for k, v in diag.items()
                           if not isinstance(v, (list, dict, np.ndarray))]))
    if fit is not None:
        cal = fit["fits"]["calibrated"]
        result.tables += [
            ("Goodness of fit: distance of each re-simulation from the capture (0 = "
             "identical; smaller is closer)", *comparison_rows(fit["fits"], ties)),
            ("Interval CV per rate bin: capture and both re-simulations"
             + (" (local CV, successive intervals)" if natural else ""), *cv_rows(fit["fits"])),
            ("Spatial spread (relative s.d. of the rates"
             + (" over their local scene" if natural else "") + ")",
             *spread_rows(fit["fits"], [f"flat region {i}" for i in range(len(flats))]))]
        if not natural:
            result.tables.append(("Goodness of fit per region: capture against re-simulation "
                                  "of the fitted sensor", cal["headers"], cal["rows"]))
        result.plot = plot_comparison(fit["fits"])
    result.notes = [_summary_line(cap, n, diag, lv, detected, natural),
                    _identifiability(cfg, diag), *notes]
    missing = [k for k in params if status[k].startswith("not identified")]
    if missing:
        result.notes.append("Not identified by this capture (package defaults kept): "
                            + ", ".join(missing) + ".")
    if fit is not None:
        result.notes.append(verdict(fit["fits"], ties))
        if not scale_known:
            result.notes.append("The defaults' re-simulation keeps the fitted dark_current_rel "
                                "and hot_pixel_dark_rel: with radiances unknown, full scale is "
                                "a convention and fractions of it are not comparable.")
    return result


def _ties(status: dict) -> dict:
    """The distances whose part of the model the capture did not identify (both
    re-simulations then use the package defaults' for it)."""
    ties = {}
    if status["electrons_per_threshold"].startswith("not identified"):
        ties["interval_cv_error"] = ("the temporal noise was not identified, both use the "
                                     "package defaults'")
    if status["prnu"].startswith("not identified"):
        ties["spatial_spread_error"] = ("the fixed pattern was not identified, both use the "
                                        "package defaults'")
    return ties


def _summary_line(cap, n, diag, lv, detected, natural) -> str:
    head = f"Capture {cap.name}: {n} readouts × {cap.height} × {cap.width}"
    if cap.cfa is not None:
        head += f", colour filter {cap.cfa} (fitted plane by plane: R, G1, G2, B)"
    if natural:
        return (head + f"; no flat region: calibrated from {diag['steady_pixels']} steady "
                f"pixels (temporal noise) and {diag['pool_pixels']} pixels in locally flat "
                f"neighbourhoods (fixed pattern), {diag['dark_pixels']} dark pixels.")
    return (head + f"; regions {_REGIONS_FROM[detected]}: {diag['dark_pixels']} dark pixels, "
            f"flat regions of {diag['flat_pixels']} pixels at radiances "
            f"{[round(float(v), 4) for v in lv]}.")


def _identifiability(cfg, diag) -> str:
    temporal = ("with E given." if cfg.electrons_per_threshold is not None else
                f"with σ_t held at {cfg.temporal_threshold_noise}.")
    return ("Identifiability: threshold mismatch and PRNU are split with mismatch_split = "
            f"{cfg.mismatch_split:.3g} (combined response spread fitted: "
            f"{diag['combined_gain_spread']:.4g}); comparator jitter and shot noise share the "
            f"fitted cycle CV² κ² = {diag['kappa2']:.4g} " + temporal + " The charge loss at "
            "reset (reset_charge_loss) is not fitted and is held at 0: a loss f would appear "
            "as a slightly lower rate (q/(1 + f·q)) folded into the response.")


def _plane_table(planes, natural):
    headers = ["plane", "pixels", "combined response spread", "threshold mismatch (split)",
               "PRNU (split)"]
    with_r = any("response_R" in p for p in planes)
    if with_r:
        headers.append("response R (spikes/readout at radiance 1)")
    rows = []
    for p in planes:
        row = [p["plane"], p["pixels"], p["combined_gain_spread"], p["threshold_mismatch"],
               p["prnu"]]
        if with_r:
            row.append(p.get("response_R", float("nan")))
        rows.append(tuple(row))
    where = "pools of locally flat pixels" if natural else "flat regions"
    return (f"Per colour plane (from its {where}; the sensor takes the pixel-weighted mean)",
            headers, rows)
