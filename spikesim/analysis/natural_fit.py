"""Calibration of captures without a flat region: temporal statistics and spatial residuals.

A natural capture (moving content, no uniform static patch) still identifies
most of the model, each from its own statistic (:func:`fit_natural`; the
model and the un-mixing are those of :mod:`spikesim.analysis.calibrate_fit`):

1. **Steady pixels** (:func:`steady_pixels`).  The capture is cut into
   :data:`WINDOWS` windows of ``w`` readouts; under steady light a pixel's
   window counts vary only by the counting noise, of variance
   ``V = w·(q·κ² + σ_q²) + F`` (:func:`spikesim.analysis.theory.count_variance`;
   the clock's rounding ``F`` taken at its largest, 1/4), times ``1 + 1/K`` for the sample variance
   of ``K`` windows whose rounding errors are shared by neighbours in time.  A
   pixel is steady when ``Σ(c_k − c̄)²/((1 + 1/K)·V)`` is within the 99th
   percentile of χ² with ``K − 1`` degrees of freedom, and so is the sum of
   its 3 × 3 block of the same colour plane (variance ``9·V``: nine times the
   counts, so three times as sharp): the test is against the counting
   (shot-noise) expectation, not a fixed tolerance, so at a few spikes per
   window it is loose and at many it is strict.
2. **Temporal noise** κ² from the steady pixels in locally flat
   neighbourhoods (step 3), by their *local* interval variance (successive
   differences, in which slow changes of the light cancel), fitted per octave
   of mean interval (:func:`spikesim.analysis.temporal_fit.kappa2_by_bin`).
   Moving light still adds variance, more the longer the intervals; so does
   charge noise.  Bins start at 5 readouts (:data:`BIN_MIN_MEAN`) and end an
   octave above the pooled pixels' median mean interval (in a bright capture
   the long intervals are dark, textured content next to bright, where motion
   adds most).  From the shortest intervals up, the bins that agree are kept
   (motion adds more the longer the interval: a bin above the others stops
   the run), and the lowest one measured to :data:`BIN_SE` (15 %) is taken
   (:func:`_lowest_bin`); without one the temporal noise is *not identified*.  The charge
   noise is never identified here: without a static region its growth of the
   interval CV cannot be told from moving light's.
   κ² of the first pass (with a generous ``κ² = 0.01`` in the test) sets the
   second pass's steadiness test.
3. **Fixed pattern from spatial residuals** (:func:`find_pools`).  Each
   pixel's scene estimate ``Ŝ_i`` is the mean rate of its 8 neighbours *of
   the same colour plane* (the pixel itself left out, so its own fixed
   pattern and counting noise are not in it); the neighbours' sample
   variance ``D_i`` tests the neighbourhood for flatness against the
   expected spread of a flat one, ``V_i = P²·(Ŝ_i − b̄)² + v_b + c_i``
   (``P²`` the package defaults' response spread, ``v_b`` the dark current's
   variance, ``c_i`` the counting variance of a rate over ``T`` readouts): the
   half of the pixels with the smallest ``D_i/V_i`` is kept
   (:data:`FLAT_QUANTILE`).  For Gaussian noise ``D_i`` is independent of the
   neighbours' mean and of the pixel itself, so this selection does not bias
   the residuals ``x_i − Ŝ_i``, and it leaves out the textured half of the
   scene.  The kept pixels are pooled in half-octave bins of ``Ŝ`` (pixels of
   similar rate); per pool, ``E[(x − Ŝ)²] = (1 + 1/8)·(P²·(Ŝ − b̄)² + v_b + c)``
   gives ``P²`` (:func:`pool_spread`), weighted over the pools by the inverse
   of each estimate's variance.  Hot pixels (beyond 6 robust s.d. of ``x/Ŝ``)
   are left out.  Texture left in the kept neighbourhoods adds to ``P²``.
4. **Dark current** from the dark region when the capture has one (the
   darkest pixels, detected as for the flat path); otherwise the dark
   current, its spread and the hot pixels are *not identified* and keep the
   package defaults.
5. **Scale**: no radiance is known, so full scale (radiance 1) is the
   highest pool rate (the 99th percentile of ``Ŝ`` over the kept pixels),
   unless ``full_scale_rate`` is given.

Every parameter the capture cannot identify keeps its package default and
the report says *not identified* (:func:`spikesim.analysis.calibrate_fit.unmix`
splits as in the flat path).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

import spikesim as ss
from spikesim.analysis import theory
from spikesim.analysis.calibrate_fit import (
    DARK_FALLBACK,
    dark_parameters,
    find_hot_pixels,
    fit_dark,
    unmix,
)
from spikesim.analysis.capture import pixel_counts
from spikesim.analysis.temporal_fit import kappa2_by_bin
from spikesim.errors import bad_value

__all__ = ["fit_natural", "steady_pixels", "find_pools", "pool_spread", "window_counts",
           "local_scene", "smooth_scene", "Pools", "WINDOWS", "MIN_POOL_PIXELS"]

#: Windows the capture is cut into for the steadiness test.
WINDOWS = 4
#: Fewest pixels a pool (rate bin) needs for its spread to count.
MIN_POOL_PIXELS = 32
#: Fewest kept pixels over all pools for the fixed pattern to be identified.
MIN_FPN_PIXELS = 200
#: Share of the usable pixels kept for the fixed pattern: those whose neighbourhood is the
#: flattest relative to the spread expected of a flat one.
FLAT_QUANTILE = 0.5
#: Largest relative standard error of a rate bin's κ² for the temporal fit to use it.
BIN_SE = 0.15
#: Shortest mean interval (readouts) of the temporal fit's bins (as the flat path's
#: ``MIN_MEAN_INTERVAL``): below, the clock's rounding is most of the local variance and its
#: term depends on the cycle's law and on each pixel's mean more than they are known (the
#: 2-4 readout bin read κ² 15-25 % low).
BIN_MIN_MEAN = 5.0
#: Largest relative standard error of a rate bin's κ² for it to count in the run of
#: agreeing bins (:func:`_lowest_bin`).
BIN_USABLE_SE = 0.35
#: Fewest precise rate bins of the run for κ² to be identified without a static region.
MIN_AGREEING_BINS = 1
#: Fewest pixels a rate bin needs for the temporal fit.
BIN_PIXELS = 50
#: Fewest signal spikes per pixel (over the capture) a pooled pixel's scene estimate needs.
MIN_POOL_SPIKES = 2.0
#: First guess of the response spread (the package defaults' combined spread).
_P2_START = 0.045**2 + 0.058**2
#: Generous κ² of the first steadiness test (a 10 % cycle s.d.).
_KAPPA2_START = 0.01


def window_counts(cap, n: int, k: int = WINDOWS) -> np.ndarray:
    """(k, H, W) spikes per pixel in ``k`` equal windows of the first ``n`` readouts."""
    edges = np.linspace(0, n, k + 1).round().astype(int)
    return np.stack([pixel_counts(cap, int(a), int(b)) for a, b in zip(edges[:-1], edges[1:],
                                                                       strict=True)])


def steady_pixels(counts: np.ndarray, window: float, kappa2: float, sigma_q2: float = 0.0,
                  planes=None) -> np.ndarray:
    """(H, W) bool: pixels whose window counts ``counts`` (K, H, W; windows of
    ``window`` readouts) are consistent with steady light, and so are those of
    their 3 × 3 block of the same colour plane (``planes``; module notes, step 1)."""
    c = counts.astype(np.float64)
    ok = _steady(c, window, kappa2, sigma_q2, 1)
    if planes is not None:
        from scipy import ndimage

        block = np.zeros_like(c)
        for p in planes:
            block[:, p.rows, p.cols] = ndimage.uniform_filter(p.sub(c), (1, 3, 3),
                                                              mode="reflect") * 9
        ok &= _steady(block, window, kappa2, sigma_q2, 9)
    return ok


def _steady(c, window, kappa2, sigma_q2, pixels: int) -> np.ndarray:
    """The χ² steadiness test of window counts ``c`` (K, H, W) summed over
    ``pixels`` independent pixels each."""
    from scipy.stats import chi2

    k = c.shape[0]
    mean = c.mean(axis=0)
    q = np.minimum(mean / (window * pixels), 1.0)
    v = (1 + 1 / k) * pixels * (window * (q * kappa2 + sigma_q2) + 0.25)
    stat = ((c - mean) ** 2).sum(axis=0) / v
    return stat <= chi2.ppf(0.99, k - 1)


def local_scene(rate: np.ndarray, planes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(Ŝ, D, inner)``: per pixel the mean and the sample variance of its 8
    neighbours in its colour plane (spikes per readout), and whether it is off
    the plane's border (module notes, step 3)."""
    from scipy import ndimage

    shape = rate.shape
    mean, disp, inner = np.zeros(shape), np.zeros(shape), np.zeros(shape, bool)
    for p in planes:
        x = p.sub(np.asarray(rate, np.float64))
        s1 = ndimage.uniform_filter(x, 3, mode="reflect") * 9 - x
        s2 = ndimage.uniform_filter(x * x, 3, mode="reflect") * 9 - x * x
        m = s1 / 8
        mean[p.rows, p.cols] = m
        disp[p.rows, p.cols] = np.maximum(s2 - 8 * m * m, 0.0) / 7
        ins = np.zeros(x.shape, bool)
        ins[1:-1, 1:-1] = True
        inner[p.rows, p.cols] = ins
    return mean, disp, inner


def smooth_scene(rate: np.ndarray, planes, size: int = 5) -> np.ndarray:
    """(H, W) mean rate over each pixel's ``size × size`` block of its colour
    plane (spikes per readout): a scene for re-simulation without the capture's
    fixed pattern or counting noise (each pixel is 1/25 of its own value)."""
    from scipy import ndimage

    out = np.zeros(rate.shape)
    for p in planes:
        out[p.rows, p.cols] = ndimage.uniform_filter(p.sub(np.asarray(rate, np.float64)), size,
                                                     mode="reflect")
    return out


def _counting(s, t: int, kappa2: float, sigma_q2: float):
    """Counting variance of a rate ``s`` measured over ``t`` readouts (spikes²/readout²):
    ``(t·(s·κ² + σ_q²) + 1/6)/t²`` (1/6: the rounding averaged over the phases of
    pixels whose charges differ by more than a count)."""
    return (t * (np.minimum(s, 1.0) * kappa2 + sigma_q2) + 1.0 / 6.0) / t**2


@dataclass
class Pools:
    """Pixels of the spatial-residual fit: ``kept`` (H, W) bool, ``scene`` the
    scene estimate ``Ŝ`` (spikes per readout), ``label`` the pool (rate bin) of
    each kept pixel (0: none), ``plane`` the plane index of each pixel."""

    kept: np.ndarray
    scene: np.ndarray
    label: np.ndarray
    plane: np.ndarray


def find_pools(rate, t: int, planes, usable, b_mean: float, var_b: float, kappa2: float,
               sigma_q2: float) -> Pools:
    """The flattest half of the usable pixels' neighbourhoods (module notes,
    step 3), pooled in half-octave bins of their scene estimate."""
    scene, disp, inner = local_scene(rate, planes)
    sig = scene - b_mean
    expect = _P2_START * sig**2 + var_b + _counting(scene, t, kappa2, sigma_q2)
    kept = usable & inner & (sig * t >= MIN_POOL_SPIKES) & (scene < 0.9)
    if kept.any():
        flatness = disp / np.maximum(expect, 1e-18)
        kept &= flatness <= np.quantile(flatness[kept], FLAT_QUANTILE)
    ratio = np.where(kept, rate / np.maximum(scene, 1e-12), np.nan)
    if kept.any():  # hot pixels and other gross outliers of x/Ŝ
        r = ratio[kept]
        med = float(np.median(r))
        rsd = max(1.4826 * float(np.median(np.abs(r - med))), 1e-6)
        kept &= np.abs(np.nan_to_num(ratio, nan=med) - med) <= 6 * rsd
    label = np.zeros(rate.shape, np.int64)
    if kept.any():
        lo = float(scene[kept].min())
        label[kept] = 1 + np.floor(2 * np.log2(scene[kept] / lo)).astype(np.int64)
    plane = np.zeros(rate.shape, np.int64)
    for i, p in enumerate(planes):
        plane[p.rows, p.cols] = i
    return Pools(kept, scene, label, plane)


def pool_spread(rate, pools: Pools, t: int, b_mean: float, var_b: float, kappa2: float,
                sigma_q2: float, select=None) -> tuple[float, int]:
    """``(P², pixels)``: the response spread from the pools' residuals (module
    notes, step 3) over the pools of at least :data:`MIN_POOL_PIXELS` pixels
    (``select``: an extra (H, W) mask, e.g. one plane), each weighted by the
    inverse of its estimate's variance, ``n·sig⁴/(2·V²)`` with ``V`` the
    expected residual variance (a dim pool, where the dark current's spread
    and the counting noise are most of it, counts little); ``(nan, 0)`` when no
    pool is large enough."""
    parts, weights, npx = [], [], 0
    keep = pools.kept if select is None else pools.kept & select
    for g in np.unique(pools.label[keep]):
        at = keep & (pools.label == g)
        n = int(at.sum())
        if n < MIN_POOL_PIXELS:
            continue
        s = pools.scene[at]
        sig2 = float(np.mean((s - b_mean) ** 2))
        noise = var_b + float(np.mean(_counting(s, t, kappa2, sigma_q2)))
        y = float(np.mean((rate[at] - s) ** 2)) / (1 + 1 / 8) - noise
        parts.append(y / sig2)
        weights.append(n * sig2**2 / (_P2_START * sig2 + noise) ** 2)
        npx += n
    if not parts:
        return float("nan"), 0
    return max(float(np.average(parts, weights=weights)), 0.0), npx


def fit_natural(rate, mom, counts, n_readouts: int, dark, planes, config):
    """Fit the model to a capture without a flat region (module notes).

    Parameters
    ----------
    rate : (H, W) float
        Spikes per readout over the ``n_readouts`` readouts.
    mom : :class:`spikesim.analysis.capture.IntervalMoments`
    counts : (K, H, W) int
        Window counts (:func:`window_counts`).
    dark : (H, W) bool or None
        The dark region, when one was found or given.
    planes : list of :class:`spikesim.analysis.planes.Plane`
    config : :class:`spikesim.analysis.calibration_config.CalibrationConfig`

    Returns ``(params, diagnostics, hot, pools, steady, identified)``:
    ``identified`` maps each parameter to ``True`` or the reason it is not.
    """
    t = n_readouts
    notes: list[str] = []
    hot = find_hot_pixels(rate, dark, t)
    good_dark = dark & ~hot if dark is not None else None
    dark_known = good_dark is not None and bool(good_dark.any())
    usable = ~hot & (rate < 0.95)
    if dark is not None:
        usable &= ~dark
    b_mean, cv_b2 = fit_dark(rate, good_dark, t, _KAPPA2_START, 0.0) if dark_known \
        else (0.0, None)
    spread_known = cv_b2 is not None
    if not spread_known:
        cv_b2 = DARK_FALLBACK["dark_current_spread"] ** 2
    kappa2, chosen, bins = _KAPPA2_START, None, []
    pools, steady = None, None
    for _ in range(2):
        pools = find_pools(rate, t, planes, usable, b_mean, cv_b2 * b_mean**2, kappa2, 0.0)
        steady = steady_pixels(counts, t / counts.shape[0], 2 * kappa2, 0.0, planes) & \
            pools.kept
        bins = kappa2_by_bin(mom, steady, local=True, min_pixels=BIN_PIXELS,
                             min_mean=BIN_MIN_MEAN)
        typical = float(np.nanmedian(mom.mean()[pools.kept])) if pools.kept.any() else 0.0
        chosen = _lowest_bin([b for b in bins if b.lo <= 2 * typical])
        if chosen is None:
            break
        kappa2 = chosen.kappa2
    sigma_q2 = 0.0
    identified: dict[str, object] = {
        "charge_noise_electrons": "not identified: without a static region the growth of the "
                                  "interval CV with the interval length that charge noise "
                                  "brings cannot be told from moving light"}
    if chosen is None:
        kappa2 = theory.cycle_cv2(ss.noise.PhysicalNoise())
        why = (f"not identified: no octave of mean interval (from {BIN_MIN_MEAN:g} readouts to "
               f"an octave above the typical one) with {BIN_PIXELS} or more steady pixels in "
               f"locally flat neighbourhoods measures κ² to {BIN_SE:.0%}")
        identified.update(electrons_per_threshold=why, temporal_threshold_noise=why)
        notes.append("temporal noise " + why + "; held at the package defaults")
    else:
        notes.append(f"temporal noise from the local interval variance of {chosen.n_pixels} "
                     f"steady pixels of mean interval {chosen.lo:g}-{chosen.hi:g} readouts: "
                     f"κ² = {chosen.kappa2:.4g} ± {chosen.se:.2g} (the lowest of the rate bins "
                     "measured to "
                     f"{BIN_SE:.0%}, " + ", ".join(f"{b.lo:g}-{b.hi:g}: {b.kappa2:.3g}"
                                                    for b in bins)
                     + "; moving light and charge noise only raise it)")
    if dark_known:
        b_mean, cv_b2 = fit_dark(rate, good_dark, t, kappa2, sigma_q2)
        spread_known = cv_b2 is not None
        if not spread_known:
            cv_b2 = DARK_FALLBACK["dark_current_spread"] ** 2
    big_r = _scale(rate, pools, config, notes)
    if not dark_known:
        b_mean = DARK_FALLBACK["dark_current_rel"] * big_r
        why = "not identified: the capture has no dark region"
        identified.update(dark_current_rel=why, dark_current_spread=why,
                          hot_pixel_fraction=why, hot_pixel_dark_rel=why)
        notes.append("no dark region: the dark current, its spread and the hot pixels are "
                     "not identified and held at the package defaults")
    elif not spread_known:
        identified["dark_current_spread"] = ("not identified: the dark current is too weak "
                                             "for this capture length (counting noise "
                                             "dominates)")
    p2, fpn_px = pool_spread(rate, pools, t, b_mean, cv_b2 * b_mean**2, kappa2, 0.0)
    if fpn_px < MIN_FPN_PIXELS or not math.isfinite(p2):
        p2 = _P2_START
        why = (f"not identified: {fpn_px} pixels in locally flat neighbourhoods, fewer than "
               f"{MIN_FPN_PIXELS}")
        identified.update(prnu=why, threshold_mismatch=why)
        notes.append("fixed pattern " + why + "; the package defaults' response spread kept")
    params = unmix(p2, cv_b2, big_r, kappa2, sigma_q2, config, notes)
    dark_parameters(params, rate, dark, hot, b_mean, big_r, dark_known, spread_known)
    n_dark = int(dark.sum()) if dark is not None else 0  # (for the report)
    n_hot = int(hot.sum())
    if chosen is None:
        default = ss.noise.PhysicalNoise()
        params.update(electrons_per_threshold=default.electrons_per_threshold,
                      temporal_threshold_noise=default.temporal_threshold_noise,
                      shot_noise=default.shot_noise)
    per_plane = []
    for i, p in enumerate(planes):
        cv2, npx = pool_spread(rate, pools, t, b_mean, cv_b2 * b_mean**2, kappa2, sigma_q2,
                               select=pools.plane == i)
        row = {"plane": p.name, "pixels": npx, "response_cv2": cv2,
               "combined_gain_spread": math.sqrt(cv2) if math.isfinite(cv2) else float("nan")}
        s2 = float(config.mismatch_split) * cv2
        row["threshold_mismatch"] = math.sqrt(s2) if math.isfinite(s2) else float("nan")
        row["prnu"] = math.sqrt(max((1 + cv2) / (1 + s2) - 1, 0.0)) if math.isfinite(cv2) \
            else float("nan")
        per_plane.append(row)
    diag = {"kappa2": kappa2, "sigma_q2": sigma_q2, "charge_noise_fitted": False,
            "kappa2_se": chosen.se if chosen else float("nan"),
            "kappa2_bins": [vars(b) for b in bins],
            "interval_span": [chosen.lo, chosen.hi] if chosen else [],
            "intervals_used": chosen.n_intervals if chosen else 0,
            "steady_pixels": int(steady.sum()) if steady is not None else 0,
            "pool_pixels": fpn_px, "dark_rate": b_mean, "dark_cv2": cv_b2,
            "response_R": big_r, "response_cv2": p2, "combined_gain_spread": math.sqrt(p2),
            "mismatch_split": config.mismatch_split, "hot_pixels": n_hot,
            "dark_pixels": n_dark, "planes": per_plane, "notes": notes}
    if chosen is not None:  # the interval statistic where the temporal fit holds
        steady = steady & (mom.mean() < chosen.hi)
    return params, diag, hot, pools, steady, identified


def _lowest_bin(bins):
    """The rate bin whose κ² the fit takes (module notes, step 2), or None.

    From the shortest mean intervals up (where moving light adds least), the
    bins measured to :data:`BIN_USABLE_SE` are taken while each agrees with
    the weighted mean of those before it (within 2.5 standard errors): a
    longer bin that moving light or charge noise raises stops the run.  Of
    the run's bins measured to :data:`BIN_SE` the lowest is taken, when there
    are :data:`MIN_AGREEING_BINS` of them."""
    usable = sorted((b for b in bins if b.kappa2 > 0 and b.se <= BIN_USABLE_SE * b.kappa2),
                    key=lambda b: b.lo)
    run = usable[:1]
    for b in usable[1:]:
        w = np.array([1 / r.se**2 for r in run])
        mean = float(np.sum(w * [r.kappa2 for r in run]) / w.sum())
        if abs(b.kappa2 - mean) > 2.5 * float(np.sqrt(1 / w.sum() + b.se**2)):
            break
        run.append(b)
    good = [b for b in run if b.se <= BIN_SE * b.kappa2]
    if len(good) < MIN_AGREEING_BINS:
        return None
    return min(good, key=lambda b: b.kappa2)


def _scale(rate, pools, config, notes) -> float:
    """The response ``R`` (spikes per readout at radiance 1): from a known
    ``full_scale_rate`` (times ``1 + s²``), else the 99th percentile of the
    pooled pixels' scene estimates (or of all rates when none is pooled)."""
    if config.full_scale_rate is not None:
        s2 = float(config.mismatch_split) * _P2_START
        return float(config.full_scale_rate) * (1 + s2)
    vals = pools.scene[pools.kept] if pools is not None and pools.kept.any() else rate.ravel()
    big_r = float(np.percentile(vals, 99))
    if not big_r > 0:
        raise bad_value("capture", "no spikes", "a capture with light in it")
    notes.append(f"no radiance known: full scale (radiance 1) is the 99th percentile of the "
                 f"pooled pixels' scene estimates, {big_r:.4g} spikes per readout "
                 "(full_scale_rate= sets it)")
    return big_r
