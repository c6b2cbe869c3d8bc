"""Calibration: fit the physical noise model and ``full_scale_rate`` to a capture.

Model (:mod:`spikesim.noise`, :func:`spikesim.noise.fixed_pattern`): pixel ``i``
collects ``q_i = r·(g_i·I + d_i)/t_i`` thresholds per readout, with gain
``g ~ 1 + prnu·z``, threshold ``t ~ 1 + threshold_mismatch·z``, dark current
``d`` log-normal (mean ``dark_current_rel``, CV ``dark_current_spread``) plus
``hot_pixel_dark_rel`` on a fraction ``hot_pixel_fraction`` of pixels; each
firing cycle has coefficient of variation ``κ² = σ_t² + 1/E`` (comparator
jitter σ_t, shot noise with E electrons per threshold).  Let ``s``, ``p`` be the
threshold and gain spreads.  The fit, in order (rates ``λ_i`` = counts/T):

1. **hot pixels** (dark region): ``λ_i > max(5·median, exp(m + 6·MADσ), 20/T)``
   with ``m`` and ``MADσ`` the median and robust s.d. of ``log λ``;
   ``hot_pixel_fraction`` = hot/dark pixels.
2. **temporal noise** from the interval statistics of every non-hot pixel of
   the dark and flat regions with a mean interval of at least 5 readouts:
   ``Var_i(ISI) = κ²·m_i² + F_i`` (:mod:`spikesim.analysis.theory`, ``F_i`` the
   clock's rounding term), solved for κ² by weighted least squares (weights
   ``(n_i − 1)/(2·Var_i²)``, three fixed-point iterations).
3. **dark current**: ``b̄`` = mean non-hot dark rate; CV² of the dark rates
   minus the counting variance ``Var(count_T)/T²``.
4. **gain**: in flat region k of radiance ``I_k``, ``mean λ = R·I_k + b̄`` with
   ``R = r·E[g/t]``; least squares over the regions (intercept fitted too
   when there is no dark region and at least two regions).  Without known
   radiances the brightest region is taken as ``I = 1`` (full scale) and the
   others in proportion to their dark-subtracted rates.  The spread of the
   per-pixel response: ``CV_a² = (var λ − var b − hot − counting)/(mean λ − b̄)²``.
   Hot pixels (fraction ``f``, excess rate ``Δ`` measured in the dark) are
   also present in flat regions: where ``Δ`` is at least 8 robust s.d. of the
   region's rates they are cut out (rates above median + Δ/2), otherwise
   their two-point mixture is removed from the moments: mean − ``f·Δ``,
   variance − ``f(1 − f)·Δ²``.  Without a dark region, gross outliers (6
   robust s.d. in log rate) are dropped.
5. **un-mixing** with second-order moments: ``1 + CV_a² = (1 + p²)(1 + s²)``,
   ``1 + CV_b² = (1 + cv_d²)(1 + s²)``, ``E[g/t] = E[1/t] = 1 + s²``.

Identifiability (stated, not hidden): rates depend on ``g/t`` and ``d/t``
only and intervals on κ² only, so from spatial regions (different pixels at
different radiances) two splits cannot be measured:

* threshold mismatch vs PRNU: the combined response spread is fitted; it is
  split with ``mismatch_split = s²/(s² + p²)`` (default: the SCSim ratio of
  the package defaults, 0.045²/(0.045² + 0.058²));
* comparator jitter vs shot noise: κ² is fitted; give ``electrons_per_threshold``
  (from the chip's conversion gain) to fit σ_t, otherwise σ_t is held at
  ``temporal_threshold_noise`` and E is fitted.

The result holds a :class:`spikesim.Sensor` (``result.sensor``;
``result.sensor.to_json()`` loads with ``spikesim.Sensor.from_json``) and a
goodness-of-fit check (:mod:`spikesim.analysis.fitcheck`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

import spikesim as ss
from spikesim.analysis import theory
from spikesim.analysis.capture import as_capture, pixel_counts, pixel_intervals
from spikesim.analysis.regions import check_regions, detect_regions
from spikesim.analysis.report import AnalysisResult
from spikesim.errors import bad_value

__all__ = ["calibrate", "CalibrationResult", "fit_parameters", "MIN_READOUTS",
           "DEFAULT_MISMATCH_SPLIT"]

#: Shortest capture accepted (readouts): enough for dark rates of ~1e-3/readout.
MIN_READOUTS = 1000
#: Threshold-mismatch share of the combined response spread (package defaults, SCSim).
DEFAULT_MISMATCH_SPLIT = 0.045**2 / (0.045**2 + 0.058**2)
#: Regions whose median rate is at least this are saturated (no gain information).
SATURATED_RATE = 0.95


@dataclass
class CalibrationResult(AnalysisResult):
    """An :class:`AnalysisResult` with the fitted ``sensor`` and the region masks used."""

    sensor: ss.Sensor | None = None
    dark_mask: np.ndarray | None = None
    flat_masks: list | None = None
    flat_levels: list | None = None


def _robust_log(x):
    lx = np.log(np.maximum(x, 1e-12))
    m = float(np.median(lx))
    s = 1.4826 * float(np.median(np.abs(lx - m)))
    return lx, m, s


def _fit_kappa2(mom, mask, min_mean: float = 5.0, min_n: int = 5) -> tuple[float, int]:
    sel = mask & (mom.n >= min_n)
    mean = mom.mean()[sel]
    var = mom.var()[sel]
    n = mom.n[sel].astype(np.float64)
    keep = mean >= min_mean
    mean, var, n = mean[keep], var[keep], n[keep]
    if mean.size == 0:
        raise bad_value("capture length", f"no pixel with >= {min_n} intervals of >= "
                        f"{min_mean} readouts", "a longer capture (or a dark region) to measure "
                        "temporal noise from interval statistics")
    k2 = 0.0
    for _ in range(3):
        f = theory.frac_variance(mean, np.sqrt(k2) * mean)
        v_model = k2 * mean**2 + f
        w = (n - 1) / (2 * np.maximum(v_model, 1e-3) ** 2)
        k2 = float(np.sum(w * (var - f) * mean**2) / np.sum(w * mean**4))
        k2 = max(k2, 0.0)
    return k2, int(n.sum())


def fit_parameters(rate, mom, n_readouts, dark, flats, levels, electrons_per_threshold=None,
                   temporal_threshold_noise=0.006, mismatch_split=DEFAULT_MISMATCH_SPLIT):
    """Fit the model to per-pixel rates and interval moments (see module notes).

    Returns ``(params, diagnostics, used_levels, hot_mask)``; ``params`` are
    keyword arguments of :class:`spikesim.noise.PhysicalNoise` plus
    ``full_scale_rate``.
    """
    t = n_readouts
    notes = []
    hot = np.zeros(rate.shape, bool)
    if dark is not None:
        lx, m, s = _robust_log(rate[dark])
        med = float(np.median(rate[dark]))
        thr = max(5 * med, math.exp(m + 6 * s) if s > 0 else 0.0, 20.0 / t)
        hot[dark] = rate[dark] > thr
    good_dark = dark & ~hot if dark is not None else None
    # 2. temporal noise
    pool = np.zeros(rate.shape, bool)
    if good_dark is not None:
        pool |= good_dark
    for f in flats:
        pool |= f
    kappa2, n_iv = _fit_kappa2(mom, pool)
    # 3. dark current
    if good_dark is not None and good_dark.any():
        b = rate[good_dark]
        b_mean = float(b.mean())
        samp = float(np.mean(theory.count_variance(np.minimum(b, 1), t, b * kappa2))) / t**2
        cv_b2 = max((float(b.var()) - samp) / b_mean**2, 0.0) if b_mean > 0 else 0.0
    else:
        b_mean, cv_b2 = 0.0, 0.0
        if levels is not None and len(flats) >= 2:
            notes.append("no dark region: dark rate from the intercept of the flat-field fit; "
                         "its spread and the hot pixels not measured (set to 0)")
        else:
            notes.append("no dark region: dark current and hot pixels not measured (set to 0)")
    # 4. gain
    if not flats:
        raise bad_value("flat_masks", None, "at least one flat region (none given or detected)")
    # hot pixels seen in the dark also sit in the flat regions, adding a two-point
    # mixture: mean + f·Δ and variance + f(1 − f)·Δ² (f hot fraction, Δ excess rate)
    # mixture: mean + f·Δ and variance + f(1 − f)·Δ² (f hot fraction, Δ excess rate).
    # Where Δ stands out of the region's spread (≥ 8 robust s.d.) they are cut out
    # instead (rates above median + Δ/2).
    f_hot = float(hot.sum()) / float(dark.sum()) if dark is not None else 0.0
    delta = float(rate[hot].mean()) - b_mean if hot.any() else 0.0
    flat_px, hot_terms = [], []
    for f in flats:
        x = rate[f]
        med = float(np.median(x))
        rsd = 1.4826 * float(np.median(np.abs(x - med)))
        if dark is None:  # hot pixels unknown: drop gross outliers (6 robust s.d. in log)
            lxs, m, s = _robust_log(x)
            x = x[np.abs(lxs - m) <= 6 * max(s, 1e-9)] if s > 0 else x
            hot_terms.append((0.0, 0.0))
        elif delta > 0 and delta >= 8 * rsd:
            x = x[x <= med + delta / 2]
            hot_terms.append((0.0, 0.0))
        else:
            hot_terms.append((f_hot * delta, f_hot * (1 - f_hot) * delta**2))
        flat_px.append(x)
    means = np.array([x.mean() - h[0] for x, h in zip(flat_px, hot_terms, strict=True)])
    for i, (mu, f) in enumerate(zip(means, flats, strict=True)):
        if np.median(rate[f]) >= SATURATED_RATE:
            raise bad_value(f"flat region {i}", f"median rate {float(np.median(rate[f])):.4g}",
                            f"a region below saturation (median rate < {SATURATED_RATE} spikes "
                            "per readout): a saturated region carries no gain information")
        if mu * t < 10:
            raise bad_value(f"flat region {i}", f"{mu * t:.3g} spikes per pixel",
                            "at least 10 spikes per pixel (a longer capture or brighter region)")
    if levels is None:
        sig = means - b_mean
        if np.any(sig <= 0):
            raise bad_value("flat regions", means.tolist(),
                            f"rates above the dark rate {b_mean:.3g}")
        lv = sig / sig.max()
        notes.append("flat radiances unknown: the brightest flat region defines full scale "
                     "(I = 1), the others are in proportion to their dark-subtracted rates")
    else:
        lv = np.asarray(levels, dtype=np.float64)
    if dark is None and levels is not None and len(flats) >= 2:
        slope, icpt = np.polyfit(lv, means, 1)
        b_mean = max(float(icpt), 0.0)
        big_r = float(slope)
    else:
        big_r = float(np.sum((means - b_mean) * lv) / np.sum(lv**2))
    if not big_r > 0:
        raise bad_value("flat regions", means.tolist(), "rates increasing with radiance")
    var_b = cv_b2 * b_mean**2
    cv_a2_parts, npx = [], []
    for x, (_, hot_var), level in zip(flat_px, hot_terms, lv, strict=True):
        sig = big_r * level
        samp = float(np.mean(theory.count_variance(np.minimum(x, 1), t, x * kappa2))) / t**2
        cv_a2_parts.append(max((float(x.var()) - var_b - hot_var - samp) / sig**2, 0.0))
        npx.append(x.size)
    cv_a2 = float(np.average(cv_a2_parts, weights=npx))
    # 5. un-mixing
    rho = float(mismatch_split)
    s2 = rho * cv_a2
    p2 = max((1 + cv_a2) / (1 + s2) - 1, 0.0)
    cv_d2 = max((1 + cv_b2) / (1 + s2) - 1, 0.0)
    e_inv_t = 1 + s2
    r = big_r / e_inv_t
    if electrons_per_threshold is not None:
        e = float(electrons_per_threshold)
        st2 = max(kappa2 - 1.0 / e, 0.0)
        shot = True
    else:
        st2 = float(temporal_threshold_noise) ** 2
        rest = kappa2 - st2
        if rest > 1e-7:
            e, shot = 1.0 / rest, True
        else:
            e, shot, st2 = 1000.0, False, kappa2
            notes.append("temporal noise at or below the assumed comparator jitter: shot noise "
                         "off, σ_t = κ")
    n_dark = int(dark.sum()) if dark is not None else 0
    n_hot = int(hot.sum())
    hot_rel = 0.0
    if n_hot:
        hot_rel = float(np.mean(rate[hot]) - b_mean) / (r * e_inv_t)
    params = {
        "full_scale_rate": r,
        "electrons_per_threshold": e,
        "shot_noise": shot,
        "dark_current_rel": b_mean / (r * e_inv_t),
        "dark_current_spread": math.sqrt(cv_d2),
        "threshold_mismatch": math.sqrt(s2),
        "prnu": math.sqrt(p2),
        "temporal_threshold_noise": math.sqrt(st2),
        "hot_pixel_fraction": n_hot / n_dark if n_dark else 0.0,
        "hot_pixel_dark_rel": max(hot_rel, 0.0),
    }
    diag = {"kappa2": kappa2, "intervals_used": n_iv, "dark_rate": b_mean, "dark_cv2": cv_b2,
            "response_R": big_r, "response_cv2": cv_a2, "combined_gain_spread": math.sqrt(cv_a2),
            "mismatch_split": rho, "hot_pixels": n_hot, "dark_pixels": n_dark,
            "flat_pixels": [int(f.sum()) for f in flats], "flat_rates": means,
            "notes": notes}
    return params, diag, lv, hot


_LIMITS = {"dark_current_spread": 10.0, "threshold_mismatch": 0.3, "prnu": 0.3,
           "temporal_threshold_noise": 0.1, "hot_pixel_fraction": 1.0}


def calibrate(capture, *, dark_mask=None, flat_masks=None, flat_levels=None,
              detect: bool = True, electrons_per_threshold: float | None = None,
              temporal_threshold_noise: float = 0.006,
              mismatch_split: float = DEFAULT_MISMATCH_SPLIT, cfa: str | None = None,
              clock_hz: float | None = None, height: int | None = None,
              width: int | None = None, flip: bool = True, max_readouts: int | None = None,
              check: bool = True, check_readouts: int | None = 4000, check_seed: int = 1,
              min_pixels: int = 64, progress: bool = False) -> CalibrationResult:
    """Fit a :class:`spikesim.Sensor` with :class:`~spikesim.noise.PhysicalNoise` to a capture.

    Parameters
    ----------
    capture : path, (T, H, W) array, SpikeStream, DatFile or Sequence
        The spike capture (a ``.dat`` needs ``height``/``width``; ``flip`` as in
        :func:`spikesim.io.read_dat`).
    dark_mask : (H, W) bool, optional
        Pixels that saw no light.
    flat_masks : list of (H, W) bool, or (H, W) int labels (0 = none), optional
        Regions of uniform radiance.  When neither mask is given and ``detect``
        is true, both are found by :func:`spikesim.analysis.regions.detect_regions`.
    flat_levels : sequence of float, optional
        Radiance of each flat region in scene units (1 = full scale); see notes.
    electrons_per_threshold, temporal_threshold_noise, mismatch_split :
        Assumptions that resolve the splits the data cannot (module notes).
    max_readouts : int, optional
        Use only the first readouts of the capture.
    check : bool
        Re-simulate the fitted sensor and compare statistics (goodness of fit).
    """
    cap = as_capture(capture, height=height, width=width, flip=flip, cfa=cfa, clock_hz=clock_hz)
    n = cap.n_readouts if max_readouts is None else min(int(max_readouts), cap.n_readouts)
    if n < MIN_READOUTS:
        raise bad_value("capture length", f"{n} readouts",
                        f"at least {MIN_READOUTS} readouts for calibration")
    if not 0 <= float(mismatch_split) <= 1:
        raise bad_value("mismatch_split", mismatch_split, "a share in [0, 1]")
    if electrons_per_threshold is not None and not electrons_per_threshold > 0:
        raise bad_value("electrons_per_threshold", electrons_per_threshold, "a number > 0 or None")
    shape = (cap.height, cap.width)
    dark, flats = check_regions(dark_mask, flat_masks, shape)
    counts = pixel_counts(cap, 0, n, progress=progress)
    rate = counts / n
    detected = False
    if dark is None and not flats:
        if not detect:
            raise bad_value("dark_mask/flat_masks", None, "masks, or detect=True")
        dark, flats = detect_regions(rate, n, min_pixels=min_pixels)
        detected = True
        if not flats:
            raise bad_value("capture", "no flat region found", "a capture with uniform regions "
                            f"of >= {min_pixels} pixels below saturation (or pass masks)")
    if flat_levels is not None:
        flat_levels = np.asarray(flat_levels, dtype=np.float64).ravel()
        if flat_levels.size != len(flats) or np.any(~np.isfinite(flat_levels)) or \
                np.any(flat_levels <= 0):
            raise bad_value("flat_levels", flat_levels.tolist(),
                            f"{len(flats)} finite radiances > 0, one per flat region")
    mom = pixel_intervals(cap, 0, n, progress=progress)
    params, diag, lv, hot = fit_parameters(
        rate, mom, n, dark, flats, flat_levels, electrons_per_threshold,
        temporal_threshold_noise, mismatch_split)
    clipped = []
    for k, hi in _LIMITS.items():
        if params[k] > hi:
            clipped.append(f"{k} = {params[k]:.4g} clipped to the model's limit {hi}")
            params[k] = hi
    noise = ss.noise.PhysicalNoise(**{k: v for k, v in params.items() if k != "full_scale_rate"})
    sensor = ss.Sensor(height=cap.height, width=cap.width, cfa=cap.cfa,
                       clock_hz=cap.clock_hz or 20_000.0, full_scale_rate=params["full_scale_rate"],
                       noise=noise)
    notes_extra = list(diag.pop("notes")) + clipped
    if not cap.clock_hz:
        notes_extra.append("clock unknown: the sensor's clock_hz is set to 20 kHz (rates per "
                           "readout are what was fitted)")
    result = CalibrationResult("calibration", "Calibration of the noise model", {},
                               sensor=sensor, dark_mask=dark, flat_masks=flats,
                               flat_levels=list(map(float, lv)))
    fit = None
    if check:
        from spikesim.analysis.fitcheck import goodness_of_fit

        fit = goodness_of_fit(cap, sensor, rate, dark, flats, lv, hot, n_readouts=min(
            n, check_readouts or n), seed=check_seed, progress=progress)
    result.data = {"capture": {"name": cap.name, "shape": [n, cap.height, cap.width],
                               "cfa": cap.cfa, "clock_hz": cap.clock_hz},
                   "regions": {"detected": detected, "dark_pixels": diag["dark_pixels"],
                               "flat_pixels": diag["flat_pixels"], "flat_levels": lv},
                   "parameters": params, "diagnostics": diag, "sensor": sensor.to_dict(),
                   "goodness_of_fit": fit, "notes": notes_extra}
    result.tables = [("Fitted parameters", ["parameter", "value"],
                      [(k, v) for k, v in params.items()]),
                     ("Diagnostics", ["quantity", "value"],
                      [(k, v) for k, v in diag.items() if not isinstance(v, (list, np.ndarray))])]
    if fit is not None:
        result.tables.append(("Goodness of fit: capture against re-simulation of the fitted "
                              "sensor", fit["headers"], fit["rows"]))
    result.notes = [
        f"Capture {cap.name}: {n} readouts × {cap.height} × {cap.width}; regions "
        f"{'detected automatically' if detected else 'from masks'}: "
        f"{diag['dark_pixels']} dark pixels, flat regions of {diag['flat_pixels']} pixels at "
        f"radiances {[round(float(v), 4) for v in lv]}.",
        "Identifiability: threshold mismatch and PRNU are split with mismatch_split = "
        f"{mismatch_split:.3g} (combined response spread fitted: "
        f"{diag['combined_gain_spread']:.4g}); comparator jitter and shot noise share the "
        f"fitted cycle CV² κ² = {diag['kappa2']:.4g} "
        + ("with E given." if electrons_per_threshold is not None else
           f"with σ_t held at {temporal_threshold_noise}."),
        *notes_extra,
    ]
    if fit is not None:
        result.plot = fit["plot"]
        fit.pop("plot")
    return result
