"""Distances between a capture and a re-simulation, over the pixels of known radiance.

Three statistics, each computed on the dark and flat regions only (where the
scene is known, so a re-simulation can reproduce it) and summarised by one
number (0 = identical; smaller is closer):

* **rate KS** — per region, the two-sample Kolmogorov–Smirnov distance
  ``D`` between the per-pixel firing rates (spikes/readout) of capture and
  re-simulation; summary: the pixel-weighted mean of ``D`` over the regions.
* **interval CV per rate bin** — pixels with at least ``MIN_INTERVALS``
  intervals are binned by their mean interval ``m`` in octaves (2–4, 4–8, …
  readouts); per bin the clocked interval CV is
  ``sqrt(median_i(Var_i/m_i²))`` (within-pixel variance, so the fixed pattern
  does not enter; the clock's rounding is in both sides alike; the median, so
  that the few pixels of moving content a detected region may hold, whose
  variance is many times the others', do not set it).  Summary: the
  pixel-weighted mean of ``|CV_resim/CV_capture − 1|`` over the bins with at
  least ``MIN_BIN_PIXELS`` pixels on both sides.
* **spatial spread** — per flat region, the pixel-to-pixel relative s.d. of
  the rates (s.d./mean: the fixed pattern plus the counting noise of the
  capture length) after cutting ``TRIM`` (1 %) of the pixels at each end, so
  that the few hot pixels, which fall on different pixels in the
  re-simulation, do not dominate (a median absolute deviation would not do:
  short captures quantise rates to 1/T and it is often 0);
  summary: the pixel-weighted mean of ``|spread_resim/spread_capture − 1|``.

On a capture **without a flat region** (:func:`pool_distances`) the
reference pixels are the pools of :mod:`spikesim.analysis.natural_fit`
(locally flat neighbourhoods, pooled by rate) and the steady pixels, and each
statistic is computed alike on the capture and on the re-simulation:

* **rate KS** — per pool, the KS distance between the per-pixel rates
  *relative to their local scene estimate* ``x_i/Ŝ_i`` (the mean of the 8
  same-plane neighbours of each one's own rate map), pixel-weighted;
* **interval CV per rate bin** — as above but from the *local* interval
  variance (successive differences, :meth:`IntervalMoments.local_var`), so
  that the slow changes of moving light, which a static re-simulation does not
  have, do not enter; over the steady pixels;
* **spatial spread** — per pool the trimmed relative s.d. of ``x_i/Ŝ_i``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["ks_distance", "ks_critical", "cv_by_interval", "summary_distances",
           "pool_distances", "MIN_INTERVALS", "MIN_BIN_PIXELS"]

#: Least closed intervals of a pixel for its CV to be used.
MIN_INTERVALS = 3
#: Share of the pixels cut at each end of a region's rates for the spatial spread.
TRIM = 0.01
#: Smallest relative spread of a pool's rates in the capture for its spread error to count.
MIN_SPREAD = 1e-3
#: Least pixels on each side for a bin of the CV comparison to count.
MIN_BIN_PIXELS = 20


def ks_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Two-sample Kolmogorov–Smirnov statistic (largest gap between the empirical CDFs)."""
    a, b = np.sort(np.asarray(a, float)), np.sort(np.asarray(b, float))
    if a.size == 0 or b.size == 0:
        return float("nan")
    grid = np.concatenate([a, b])
    fa = np.searchsorted(a, grid, side="right") / a.size
    fb = np.searchsorted(b, grid, side="right") / b.size
    return float(np.max(np.abs(fa - fb)))


def ks_critical(n: int, m: int, c_alpha: float = 1.949) -> float:
    """Critical two-sample KS distance (α = 0.001 for the default ``c_alpha``)."""
    return c_alpha * np.sqrt((n + m) / (n * m)) if n and m else float("nan")


def cv_by_interval(mom, mask, local: bool = False) -> list[dict]:
    """Clocked interval CV per octave of mean interval over the pixels of ``mask``
    (``local``: from the local variance of successive intervals).

    Returns one dict per non-empty bin: ``lo``, ``hi`` (readouts), ``pixels``,
    ``cv``.
    """
    sel = mask & (mom.n >= MIN_INTERVALS)
    m = mom.mean()[sel]
    cv2 = (mom.local_var() if local else mom.var())[sel] / m**2
    out = []
    if m.size == 0:
        return out
    top = int(np.ceil(np.log2(max(float(m.max()), 2.0)))) + 1
    for k in range(1, top):
        lo, hi = 2.0**k, 2.0 ** (k + 1)
        inb = (m >= lo) & (m < hi)
        if inb.any():
            out.append({"lo": lo, "hi": hi, "pixels": int(inb.sum()),
                        "cv": float(np.sqrt(np.median(cv2[inb])))})
    return out


def _cv_error(cap_bins, sim_bins):
    sim = {(b["lo"], b["hi"]): b for b in sim_bins}
    errs, w, rows = [], [], []
    for b in cap_bins:
        s = sim.get((b["lo"], b["hi"]))
        if s is None or min(b["pixels"], s["pixels"]) < MIN_BIN_PIXELS or b["cv"] <= 0:
            continue
        errs.append(abs(s["cv"] / b["cv"] - 1))
        w.append(b["pixels"])
        rows.append({"lo": b["lo"], "hi": b["hi"], "capture_pixels": b["pixels"],
                     "resim_pixels": s["pixels"], "capture_cv": b["cv"], "resim_cv": s["cv"]})
    return (float(np.average(errs, weights=w)) if errs else float("nan")), rows


def _robust_spread(x) -> float:
    x = np.sort(np.asarray(x, np.float64))
    cut = int(np.ceil(TRIM * x.size))
    core = x[cut: x.size - cut] if x.size > 2 * cut + 1 else x
    mean = float(core.mean())
    return float(core.std()) / mean if mean > 0 else float("nan")


def summary_distances(c_rate, s_rate, m_cap, m_sim, dark, flats) -> dict:
    """The three summary statistics (module notes) and their per-region/bin parts."""
    regions = ([dark] if dark is not None else []) + list(flats)
    ks = [ks_distance(c_rate[m], s_rate[m]) for m in regions]
    npx = [int(m.sum()) for m in regions]
    spreads = [(_robust_spread(c_rate[f]), _robust_spread(s_rate[f])) for f in flats]
    sp_err = [abs(s / c - 1) if c > 0 else float("nan") for c, s in spreads]
    union = np.zeros(c_rate.shape, bool)
    for m in regions:
        union |= m
    cv_err, cv_rows = _cv_error(cv_by_interval(m_cap, union), cv_by_interval(m_sim, union))
    return {
        "rate_ks": float(np.average(ks, weights=npx)),
        "interval_cv_error": cv_err,
        "spatial_spread_error": float(np.average(sp_err, weights=[int(f.sum()) for f in flats]))
        if flats else float("nan"),
        "cv_bins": cv_rows,
        "spatial_spread": [{"capture": c, "resim": s} for c, s in spreads],
    }


def pool_distances(c_rate, s_rate, c_scene, s_scene, labels, m_cap, m_sim, steady) -> dict:
    """The three statistics on a capture without a flat region (module notes):
    ``c_rate``/``s_rate`` the capture's and the re-simulation's rates,
    ``c_scene``/``s_scene`` their local scene estimates, ``labels`` the pool of
    each reference pixel (0: none), ``steady`` the pixels of the CV statistic."""
    ks, sp_err, npx, spreads = [], [], [], []
    for g in np.unique(labels[labels > 0]):
        at = labels == g
        if at.sum() < MIN_BIN_PIXELS:
            continue
        a = c_rate[at] / np.maximum(c_scene[at], 1e-12)
        b = s_rate[at] / np.maximum(s_scene[at], 1e-12)
        ks.append(ks_distance(a, b))
        c, s = _robust_spread(a), _robust_spread(b)
        spreads.append({"pool": int(g), "pixels": int(at.sum()),
                        "rate": float(np.mean(c_scene[at])), "capture": c, "resim": s})
        # (a pool whose rates the capture shows all alike has no spread to compare)
        sp_err.append(abs(s / c - 1) if c > MIN_SPREAD else float("nan"))
        npx.append(int(at.sum()))
    cv_err, cv_rows = _cv_error(cv_by_interval(m_cap, steady, local=True),
                                cv_by_interval(m_sim, steady, local=True))
    return {
        "rate_ks": float(np.average(ks, weights=npx)) if ks else float("nan"),
        "interval_cv_error": cv_err,
        "spatial_spread_error": _nan_average(sp_err, npx),
        "cv_bins": cv_rows,
        "spatial_spread": spreads,
    }


def _nan_average(values, weights) -> float:
    """Weighted mean of the finite ``values`` (NaN when none is)."""
    v, w = np.asarray(values, float), np.asarray(weights, float)
    ok = np.isfinite(v)
    return float(np.average(v[ok], weights=w[ok])) if ok.any() else float("nan")
