"""The fit steps of the calibration: rates and interval moments → model parameters.

Model (:mod:`spikesim.noise`, :func:`spikesim.noise.fixed_pattern`): pixel ``i``
collects ``q_i = r·(g_i·I + d_i)/t_i`` thresholds per readout, with gain
``g ~ 1 + prnu·z``, threshold ``t ~ 1 + threshold_mismatch·z``, dark current
``d`` log-normal (mean ``dark_current_rel``, CV ``dark_current_spread``) plus
``hot_pixel_dark_rel`` on a fraction ``hot_pixel_fraction`` of pixels; each
firing cycle has coefficient of variation ``κ² = σ_t² + 1/E`` (comparator
jitter σ_t, shot noise with E electrons per threshold) and an accumulating
charge noise adds ``σ_q² = (σ_e/E)²`` thresholds² per readout
(``charge_noise_electrons`` σ_e).  Let ``s``, ``p`` be the threshold and gain
spreads.  The steps, in order (rates ``λ_i`` = counts/T):

1. :func:`find_hot_pixels` (dark region):
   ``λ_i > max(5·median, exp(m + 6·MADσ), 20/T)`` with ``m`` and ``MADσ`` the
   median and robust s.d. of ``log λ``; the log-normal term is used only when
   the median pixel counts at least 20 spikes (in short captures most dark
   pixels count 0, 1 or 2 spikes and the log rates measure the counting, not
   the dark-current spread); ``hot_pixel_fraction`` = hot/dark pixels.
2. temporal noise (:func:`spikesim.analysis.temporal_fit.fit_temporal`) from
   the interval statistics of every non-hot pixel of the dark and flat
   regions: κ², and σ_q² when the interval CV² grows significantly with the
   interval length.
3. :func:`fit_dark`: ``b̄`` = mean non-hot dark rate; CV² of the dark rates
   minus the counting variance ``Var(count_T)/T²``
   (:func:`spikesim.analysis.theory.count_variance`).  The CV² is kept only
   when its standard error ``sqrt(2/(n − 1))·var/b̄²`` is at most
   ``DARK_CV2_SE`` (0.1); in short captures of weak dark current (a fraction
   of a spike per pixel) the counting variance swamps the spread, which is
   then held at the package default (stated in the notes).
4. :func:`fit_response`: in flat region k of radiance ``I_k``,
   ``mean λ = R·I_k + b̄`` with ``R = r·E[g/t]``; least squares over the
   regions (intercept fitted too when there is no dark region and at least
   two regions of known radiance).  Without known radiances the brightest
   region is taken as ``I = 1`` (full scale) and the others in proportion to
   their dark-subtracted rates.  :func:`response_spread`: the spread of the
   per-pixel response, ``CV_a² = (var λ − var b − hot − counting)/(mean λ − b̄)²``.
   Hot pixels (fraction ``f``, excess rate ``Δ`` measured in the dark) are
   also present in flat regions (:func:`flat_samples`): where ``Δ`` is at
   least 8 robust s.d. of the region's rates they are cut out (rates above
   median + Δ/2), otherwise their two-point mixture is removed from the
   moments: mean − ``f·Δ``, variance − ``f(1 − f)·Δ²``.  When the dark
   region shows no hot pixel (or there is none), gross outliers (beyond 6
   robust s.d. of the log rates, the s.d. at least half a count relative to
   the median count) are dropped instead: a hot pixel may sit in a flat
   region while the dark region holds none.
5. :func:`unmix` with second-order moments: ``1 + CV_a² = (1 + p²)(1 + s²)``,
   ``1 + CV_b² = (1 + cv_d²)(1 + s²)``, ``E[g/t] = E[1/t] = 1 + s²``.

**No dark region** (fallback, stated in the notes): the dark current's mean
is the intercept of the flat-field fit when at least two flat regions of
known radiance exist; otherwise it is held at the package default
(``PhysicalNoise().dark_current_rel`` of full scale, ``b̄ = d₀·R``).  Its
spread and the hot pixels cannot be measured and are held at the package
defaults.
"""

from __future__ import annotations

import math

import numpy as np

import spikesim as ss
from spikesim.analysis import theory
from spikesim.analysis.temporal_fit import fit_temporal
from spikesim.errors import bad_value

__all__ = ["fit_parameters", "find_hot_pixels", "fit_dark", "flat_samples", "fit_response",
           "region_spreads",
           "response_spread", "unmix", "dark_parameters", "SATURATED_RATE", "MIN_FLAT_SPIKES",
           "DARK_FALLBACK",
           "DARK_CV2_SE"]

#: Regions whose median rate is at least this are saturated (no gain information).
SATURATED_RATE = 0.95
#: Fewest spikes per pixel a flat region needs over the capture: below, the counting noise
#: (about 0.4 spikes s.d. whatever the rate) swamps a fixed pattern of a few per cent.  A
#: dim sky of a public 200-readout sample counts about 6.6.
MIN_FLAT_SPIKES = 4
#: Dark-current parameters held at the package defaults when no dark region exists.
DARK_FALLBACK = {k: getattr(ss.noise.PhysicalNoise(), k) for k in (
    "dark_current_rel", "dark_current_spread", "hot_pixel_fraction", "hot_pixel_dark_rel")}
#: Largest standard error of the dark rates' CV² for the dark-current spread to be fitted.
DARK_CV2_SE = 0.1


def _robust_log(x):
    lx = np.log(np.maximum(x, 1e-12))
    m = float(np.median(lx))
    s = 1.4826 * float(np.median(np.abs(lx - m)))
    return lx, m, s


def _counting_var(x, t, kappa2, sigma_q2):
    """Counting variance of the rates ``x`` of one region over ``t`` readouts
    (spikes²/readout²), averaged over its pixels.

    A pixel's count over ``t`` readouts has variance ``t·v1 + E[f(1 − f)]``
    with ``f = frac(X)`` (:mod:`spikesim.analysis.theory`, count over a
    window).  The charges ``X`` of the region's pixels spread around their
    mean by the fixed pattern, which smooths ``f`` like temporal noise does:
    ``E[f(1 − f)] = frac_variance(mean X, sqrt(σ_X² + t·v1))`` with
    ``σ_X² = Var(count) − t·v1 − E[f(1 − f)]`` solved by fixed-point
    iteration.  (The measured counts themselves cannot be used: they are
    integers, whose fractional part is 0.)
    """
    c = np.minimum(x, 1.0) * t
    mean_c, var_c = float(c.mean()), float(c.var())
    tv1 = t * (float(np.mean(np.minimum(x, 1.0))) * kappa2 + sigma_q2)
    sx2 = var_c
    f = 0.0
    for _ in range(6):
        f = float(theory.frac_variance(mean_c, np.sqrt(sx2 + tv1)))
        sx2 = max(var_c - tv1 - f, 0.0)
    return (tv1 + f) / t**2


def find_hot_pixels(rate, dark, t: int) -> np.ndarray:
    """(H, W) bool: the dark region's hot pixels (step 1)."""
    hot = np.zeros(rate.shape, bool)
    if dark is not None:
        med = float(np.median(rate[dark]))
        thr = max(5 * med, 20.0 / t)
        if med * t >= 20:
            _, m, s = _robust_log(rate[dark])
            thr = max(thr, math.exp(m + 6 * s))
        hot[dark] = rate[dark] > thr
    return hot


def fit_dark(rate, good_dark, t: int, kappa2: float, sigma_q2: float
             ) -> tuple[float, float | None]:
    """Mean dark rate (spikes/readout) and CV² of the dark current (step 3);
    the CV² is ``None`` when the capture cannot measure it (module notes)."""
    b = rate[good_dark]
    b_mean = float(b.mean())
    if b_mean <= 0:
        return 0.0, None
    var = float(b.var())
    if np.sqrt(2.0 / max(b.size - 1, 1)) * var / b_mean**2 > DARK_CV2_SE:
        return b_mean, None
    samp = _counting_var(b, t, kappa2, sigma_q2)
    return b_mean, max((var - samp) / b_mean**2, 0.0)


def flat_samples(rate, flats, dark, hot, b_mean: float, t: int):
    """Per flat region: the pixel rates used and the hot-pixel (mean, variance) to remove."""
    f_hot = float(hot.sum()) / float(dark.sum()) if dark is not None else 0.0
    delta = float(rate[hot].mean()) - b_mean if hot.any() else 0.0
    flat_px, hot_terms = [], []
    for f in flats:
        x = rate[f]
        if f_hot == 0:  # no hot pixel known: drop gross outliers (module notes)
            lxs, m, s = _robust_log(x)
            s = max(s, 0.5 / max(float(np.median(x)) * t, 1.0))
            x = x[np.abs(lxs - m) <= 6 * s]
            hot_terms.append((0.0, 0.0))
            flat_px.append(x)
            continue
        med = float(np.median(x))
        rsd = 1.4826 * float(np.median(np.abs(x - med)))
        if delta > 0 and delta >= 8 * rsd:
            x = x[x <= med + delta / 2]
            hot_terms.append((0.0, 0.0))
        else:
            hot_terms.append((f_hot * delta, f_hot * (1 - f_hot) * delta**2))
        flat_px.append(x)
    return flat_px, hot_terms


def _check_flat_means(means, flats, rate, t, names):
    for name, mu, f in zip(names, means, flats, strict=True):
        if np.median(rate[f]) >= SATURATED_RATE:
            raise bad_value(name, f"median rate {float(np.median(rate[f])):.4g}",
                            f"a region below saturation (median rate < {SATURATED_RATE} spikes "
                            "per readout): a saturated region carries no gain information")
        if mu * t < MIN_FLAT_SPIKES:
            raise bad_value(name, f"{mu * t:.3g} spikes per pixel",
                            f"at least {MIN_FLAT_SPIKES} spikes per pixel (a longer capture or "
                            "brighter region)")


def fit_response(means, levels, b_mean: float, dark_known: bool, notes: list,
                 response: float | None = None):
    """Radiances, response ``R`` (spikes/readout at I = 1) and dark rate (step 4).

    ``b_mean`` is the measured dark rate when ``dark_known``; otherwise the dark
    rate comes from the intercept (two or more known radiances) or from the
    package default ``d₀`` as ``b̄ = d₀·R``.  ``response``: a known ``R``
    (from a known ``full_scale_rate``) that places radiances unknown as
    ``(mean − b̄)/R``; else the brightest region is ``I = 1``.
    """
    d0 = DARK_FALLBACK["dark_current_rel"]
    if not dark_known and levels is not None and len(means) >= 2:
        slope, icpt = np.polyfit(levels, means, 1)
        notes.append("no dark region: dark rate from the intercept of the flat-field fit; its "
                     "spread and the hot pixels held at the package defaults")
        return np.asarray(levels, float), float(slope), max(float(icpt), 0.0)
    if not dark_known:
        notes.append(f"no dark region: dark current held at the package default "
                     f"({d0:g} of full scale), its spread and the hot pixels too")
    b = b_mean if dark_known else 0.0
    for _ in range(1 if dark_known else 4):  # fixed point b = d0·R without a dark region
        if levels is None:
            sig = means - b
            if np.any(sig <= 0):
                raise bad_value("flat regions", means.tolist(),
                                f"rates above the dark rate {b:.3g}")
            lv = sig / (sig.max() if response is None else response)
        else:
            lv = np.asarray(levels, dtype=np.float64)
        big_r = float(np.sum((means - b) * lv) / np.sum(lv**2))
        if not dark_known:
            b = d0 * max(big_r, 0.0)
    if levels is None and response is None:
        notes.append("flat radiances unknown: the brightest flat region defines full scale "
                     "(I = 1), the others are in proportion to their dark-subtracted rates")
    return lv, big_r, b


def response_spread(flat_px, hot_terms, lv, big_r, var_b, t, kappa2, sigma_q2) -> float:
    """Pixel-weighted CV² of the per-pixel response over the flat regions (step 4)."""
    parts, npx = [], []
    for x, (_, hot_var), level in zip(flat_px, hot_terms, lv, strict=True):
        sig = big_r * level
        samp = _counting_var(x, t, kappa2, sigma_q2)
        parts.append(max((float(x.var()) - var_b - hot_var - samp) / sig**2, 0.0))
        npx.append(x.size)
    return float(np.average(parts, weights=npx))


def region_spreads(flat_px, hot_terms, lv, big_r, var_b, t, kappa2, sigma_q2) -> list:
    """Per flat region, ``(CV², standard error)`` of its response spread (as
    :func:`response_spread`; the error ``sqrt(2/(n − 1))·var/sig²``)."""
    out = []
    for x, (_, hot_var), level in zip(flat_px, hot_terms, lv, strict=True):
        sig2 = (big_r * level) ** 2
        var = float(x.var())
        cv2 = (var - var_b - hot_var - _counting_var(x, t, kappa2, sigma_q2)) / sig2
        out.append((cv2, float(np.sqrt(2.0 / max(x.size - 1, 1))) * var / sig2))
    return out


def plane_spreads(flat_px, hot_terms, lv, big_r, var_b, t, kappa2, sigma_q2, planes, means,
                  b_mean, levels, split) -> list[dict]:
    """Per colour plane: its flat regions' response spread (CV², as
    :func:`response_spread`) and its split into threshold mismatch and PRNU
    (second-order, ``s² = split·CV²``); with known radiances also the plane's
    response (spikes per readout at radiance 1, least squares over its
    regions).  ``planes[i]`` names the plane of flat region ``i``."""
    rows = []
    for name in dict.fromkeys(planes):
        idx = [i for i, p in enumerate(planes) if p == name]
        cv2 = response_spread([flat_px[i] for i in idx], [hot_terms[i] for i in idx],
                              [lv[i] for i in idx], big_r, var_b, t, kappa2, sigma_q2)
        s2 = split * cv2
        row = {"plane": name, "regions": len(idx), "pixels": int(sum(flat_px[i].size
                                                                    for i in idx)),
               "response_cv2": cv2, "combined_gain_spread": math.sqrt(cv2),
               "threshold_mismatch": math.sqrt(s2),
               "prnu": math.sqrt(max((1 + cv2) / (1 + s2) - 1, 0.0)),
               "mean_rate": float(np.mean([means[i] for i in idx]))}
        if levels is not None:
            lvp = np.asarray([levels[i] for i in idx], np.float64)
            row["response_R"] = float(np.sum((np.asarray([means[i] for i in idx]) - b_mean)
                                             * lvp) / np.sum(lvp**2))
        rows.append(row)
    return rows


def unmix(cv_a2, cv_b2, big_r, kappa2, sigma_q2, config, notes):
    """Split the fitted moments into model parameters (step 5 and the temporal split)."""
    rho = float(config.mismatch_split)
    s2 = rho * cv_a2
    p2 = max((1 + cv_a2) / (1 + s2) - 1, 0.0)
    cv_d2 = max((1 + cv_b2) / (1 + s2) - 1, 0.0)
    e_inv_t = 1 + s2
    if config.electrons_per_threshold is not None:
        e = float(config.electrons_per_threshold)
        st2 = max(kappa2 - 1.0 / e, 0.0)
        shot = True
    else:
        st2 = float(config.temporal_threshold_noise) ** 2
        rest = kappa2 - st2
        if rest > 1e-7:
            e, shot = 1.0 / rest, True
        else:
            e, shot, st2 = 1000.0, False, kappa2
            notes.append("temporal noise at or below the assumed comparator jitter: shot noise "
                         "off, σ_t = κ")
    return {"full_scale_rate": big_r / e_inv_t, "electrons_per_threshold": e,
            "shot_noise": shot, "dark_current_spread": math.sqrt(cv_d2),
            "threshold_mismatch": math.sqrt(s2), "prnu": math.sqrt(p2),
            "temporal_threshold_noise": math.sqrt(st2),
            "charge_noise_electrons": math.sqrt(sigma_q2) * e}


def dark_parameters(params, rate, dark, hot, b_mean, big_r, dark_known, spread_known):
    """Into ``params``: the dark current relative to full scale, and the hot
    pixels' fraction of the dark region and their extra dark rate (from the
    ``dark`` and ``hot`` masks of ``rate``); the defaults
    (:data:`DARK_FALLBACK`) where the capture cannot tell (no dark region, or
    no dark-current spread)."""
    params["dark_current_rel"] = b_mean / big_r
    if not spread_known:
        params["dark_current_spread"] = DARK_FALLBACK["dark_current_spread"]
    if dark_known:
        n_hot = int(hot.sum())
        params["hot_pixel_fraction"] = n_hot / int(dark.sum())
        params["hot_pixel_dark_rel"] = max(float(np.mean(rate[hot]) - b_mean) / big_r, 0.0) \
            if n_hot else 0.0
    else:
        params["hot_pixel_fraction"] = DARK_FALLBACK["hot_pixel_fraction"]
        params["hot_pixel_dark_rel"] = DARK_FALLBACK["hot_pixel_dark_rel"]


def fit_parameters(rate, mom, n_readouts, dark, flats, levels, config, names=None,
                   planes=None):
    """Fit the model to per-pixel rates and interval moments (see module notes).

    Parameters
    ----------
    rate : (H, W) float
        Spikes per readout.
    mom : :class:`spikesim.analysis.capture.IntervalMoments`
    dark, flats : (H, W) bool mask or None, list of (H, W) bool masks
    levels : sequence of float or None
        Radiance of each flat region (1 = full scale), or None (unknown).
    config : :class:`spikesim.analysis.calibration_config.CalibrationConfig`
    names : list of str or None
        What errors call each flat region (:func:`spikesim.analysis.masks.flat_names`;
        None: ``flat region i``).
    planes : list of str or None
        The colour plane of each flat region (:mod:`spikesim.analysis.planes`;
        None: one monochrome plane); the diagnostics give each plane's
        response spread and PRNU (:func:`plane_spreads`).

    Returns ``(params, diagnostics, used_levels, hot_mask)``; ``params`` are
    keyword arguments of :class:`spikesim.noise.PhysicalNoise` plus
    ``full_scale_rate``.
    """
    if not flats:
        raise bad_value("flat_masks", None, "at least one flat region (none given or detected; "
                        "a dark_mask alone needs detect=True to find the flat regions)")
    t = n_readouts
    notes: list[str] = []
    hot = find_hot_pixels(rate, dark, t)
    good_dark = dark & ~hot if dark is not None else None
    pool = np.zeros(rate.shape, bool) if good_dark is None else good_dark.copy()
    regions = pool.astype(np.int64)  # 1: dark, 2…: the flat regions
    for k, f in enumerate(flats):
        pool |= f
        regions[f] = k + 2
    tf = _temporal(mom, pool, config, regions, notes)
    kappa2, sigma_q2 = tf.kappa2, tf.sigma_q2
    notes.append(tf.reason)
    dark_known = good_dark is not None and bool(good_dark.any())
    b_mean, cv_b2 = fit_dark(rate, good_dark, t, kappa2, sigma_q2) if dark_known else (0.0, None)
    spread_known = cv_b2 is not None
    if dark_known and not spread_known:
        notes.append("dark current too weak for this capture length to measure its spread "
                     "(counting noise dominates): dark_current_spread held at the package "
                     f"default {DARK_FALLBACK['dark_current_spread']:g}")
    if not spread_known:
        cv_b2 = DARK_FALLBACK["dark_current_spread"] ** 2
    flat_px, hot_terms = flat_samples(rate, flats, dark, hot, b_mean, t)
    means = np.array([x.mean() - h[0] for x, h in zip(flat_px, hot_terms, strict=True)])
    _check_flat_means(means, flats, rate, t,
                      names or [f"flat region {i}" for i in range(len(flats))])
    b_dark, known = b_mean, config.full_scale_rate
    rescale = known is not None and levels is None
    lv, big_r, b_mean = fit_response(means, levels, b_dark, dark_known, [] if rescale else notes)
    if not big_r > 0:
        raise bad_value("flat regions", means.tolist(), "rates increasing with radiance")
    cv_a2 = response_spread(flat_px, hot_terms, lv, big_r, cv_b2 * b_mean**2, t, kappa2,
                            sigma_q2)
    params = unmix(cv_a2, cv_b2, big_r, kappa2, sigma_q2, config, notes)
    if rescale:  # the scale from the known rate at I = 1
        response = float(known) * (1 + params["threshold_mismatch"] ** 2)
        lv, big_r, b_mean = fit_response(means, None, b_dark, dark_known, notes, response)
        cv_a2 = response_spread(flat_px, hot_terms, lv, big_r, cv_b2 * b_mean**2, t, kappa2,
                                sigma_q2)
        params = unmix(cv_a2, cv_b2, big_r, kappa2, sigma_q2, config, [])
        params["full_scale_rate"] = float(known)
        notes.append(f"flat radiances unknown: placed by the known full_scale_rate {known:g} "
                     f"(dark-subtracted rate over the mean response {response:.4g}): "
                     + ", ".join(f"{v:.4g}" for v in lv))
    per_plane = plane_spreads(flat_px, hot_terms, lv, big_r, cv_b2 * b_mean**2, t, kappa2,
                              sigma_q2, planes or ["mono"] * len(flats), means, b_mean,
                              levels, float(config.mismatch_split))
    dark_parameters(params, rate, dark, hot, b_mean, big_r, dark_known, spread_known)
    n_dark = int(dark.sum()) if dark is not None else 0  # (for the report)
    n_hot = int(hot.sum())
    order = ("full_scale_rate", "electrons_per_threshold", "shot_noise", "dark_current_rel",
             "dark_current_spread", "threshold_mismatch", "prnu", "temporal_threshold_noise",
             "hot_pixel_fraction", "hot_pixel_dark_rel", "charge_noise_electrons")
    if tf.n_pixels == 0:  # temporal noise not identified: the package defaults (or E given)
        default = ss.noise.PhysicalNoise()
        params.update(electrons_per_threshold=float(config.electrons_per_threshold or
                                                    default.electrons_per_threshold),
                      temporal_threshold_noise=default.temporal_threshold_noise,
                      shot_noise=default.shot_noise, charge_noise_electrons=0.0)
    params = {k: params[k] for k in order}
    identified = _unidentified(tf, dark_known, spread_known, levels)
    diag = {"kappa2": kappa2, "sigma_q2": sigma_q2, "charge_noise_fitted": tf.charge_noise_fitted,
            "sigma_q2_estimate": tf.sigma_q2_estimate, "sigma_q2_se": tf.sigma_q2_se,
            "interval_span": list(tf.interval_span), "intervals_used": tf.n_intervals,
            "dark_rate": b_mean, "dark_cv2": cv_b2, "response_R": big_r, "response_cv2": cv_a2,
            "combined_gain_spread": math.sqrt(cv_a2), "mismatch_split": config.mismatch_split,
            "hot_pixels": n_hot, "dark_pixels": n_dark,
            "flat_pixels": [int(f.sum()) for f in flats], "flat_rates": means,
            "planes": per_plane, "identified": identified, "notes": notes,
            "region_spreads": region_spreads(flat_px, hot_terms, lv, big_r, cv_b2 * b_mean**2,
                                             t, kappa2, sigma_q2)}
    return params, diag, lv, hot


#: Shortest mean interval (readouts) of the temporal fit: below, the clock's rounding is
#: most of the interval variance, and its term depends on each pixel's mean interval more
#: steeply than that mean is measured (a chip of E = 3000 e⁻ read 7-10 times its κ² from
#: intervals of 4-5 readouts).
MIN_MEAN_INTERVAL = 5.0


def _temporal(mom, pool, config, regions, notes):
    """:func:`fit_temporal` on the regions' pixels; when none has intervals of
    :data:`MIN_MEAN_INTERVAL` readouts or more (bright regions), the temporal noise is
    not identified: the package defaults' κ², flagged by ``n_pixels == 0``."""
    from spikesim.analysis.temporal_fit import TemporalFit
    from spikesim.errors import SpikeSimValueError

    try:
        return fit_temporal(mom, pool, config.fit_charge_noise, min_mean=MIN_MEAN_INTERVAL,
                            regions=regions, mismatch_share=config.mismatch_split)
    except SpikeSimValueError:
        why = (f"temporal noise not identified: no region pixel has 3 or more intervals of "
               f"{MIN_MEAN_INTERVAL:g} or more readouts (the regions fire faster than one "
               f"spike per {MIN_MEAN_INTERVAL:g} readouts, where the clock's rounding is the "
               "interval variance; a dimmer region helps)")
        return TemporalFit(theory.cycle_cv2(ss.noise.PhysicalNoise()), 0.0, float("nan"),
                           float("nan"), False, why, 0, 0, (float("nan"), float("nan")))


def _unidentified(tf, dark_known: bool, spread_known: bool, levels) -> dict:
    """The parameters this fit could not identify, each with the reason."""
    out = {}
    if tf.n_pixels == 0:  # no interval statistics at all
        why = "not identified: " + tf.reason.split(": ", 1)[1].split(" (")[0]
        out.update(electrons_per_threshold=why, temporal_threshold_noise=why,
                   charge_noise_electrons=why)
    elif not tf.charge_noise_fitted:
        out["charge_noise_electrons"] = tf.charge_noise_status()
    if not dark_known:
        why = "not identified: no dark region"
        if levels is None or len(levels) < 2:
            out["dark_current_rel"] = why
        out.update(dark_current_spread=why, hot_pixel_fraction=why, hot_pixel_dark_rel=why)
    elif not spread_known:
        out["dark_current_spread"] = ("not identified: the dark current is too weak for this "
                                      "capture length (counting noise dominates)")
    return out
