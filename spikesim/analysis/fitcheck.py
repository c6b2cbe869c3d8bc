"""Goodness of fit of a calibrated sensor: capture against re-simulation.

The fitted sensor is simulated on a static scene built from the capture:
radiance 0 on the dark region, the fitted radiance on each flat region and,
elsewhere, each pixel's dark-subtracted rate divided by the fitted response.
The chip's real fixed pattern is unknown, so the re-simulation uses its own
pattern (``fpn_seed`` different from the fitted sensor's) and only
*distributions* are compared, region by region:

* per-pixel firing rates (the fixed-pattern distribution): mean, s.d. and the
  two-sample Kolmogorov–Smirnov distance ``D``;
* inter-spike intervals pooled over the region's pixels: mean, s.d. and ``D``.

``D`` is reported with the critical value ``1.949·sqrt((n + m)/(n·m))`` of the
two-sample test at α = 0.001 (Smirnov's asymptotic law); pooled intervals of
one pixel are not independent, so for intervals it is a guide, not a test.

Each check also carries the three summary distances of
:mod:`spikesim.analysis.gof_stats` (rate KS, interval CV per rate bin,
spatial spread).  :func:`compare_resimulations` runs the check for several
sensors on the same scene and seed — the calibration compares its fitted
sensor with :func:`default_sensor_like`, the package's default
``PhysicalNoise`` at the fitted mean response, so the report shows which one
re-simulates the capture more closely.

A capture without a flat region (:func:`natural_goodness_of_fit`) is
re-simulated on a static scene built from the capture's rates smoothed over
5 × 5 pixels of each colour plane
(:func:`spikesim.analysis.natural_fit.smooth_scene`: the capture's own fixed
pattern is averaged out of the scene, and so is the counting noise that a
narrower estimate would leave as pixel-to-pixel roughness; radiance 0 on the
dark region) and compared on the pools and the steady pixels
(:func:`spikesim.analysis.gof_stats.pool_distances`).  Every
check returns ``curves`` for the side-by-side plot of
:mod:`spikesim.analysis.gof_report`.
"""

from __future__ import annotations

import numpy as np

import spikesim as ss
from spikesim.analysis.capture import as_capture, pixel_counts, pixel_intervals
from spikesim.analysis.gof_stats import (
    ks_critical,
    ks_distance,
    pool_distances,
    summary_distances,
)

__all__ = ["goodness_of_fit", "natural_goodness_of_fit", "compare_resimulations",
           "default_sensor_like", "ks_distance", "ks_critical"]


def goodness_of_fit(cap, sensor, rate, dark, flats, levels, hot, n_readouts: int,
                    seed: int = 1, progress: bool = False) -> dict:
    """Compare the capture's first ``n_readouts`` readouts with a re-simulation (see notes)."""
    cap = as_capture(cap)
    noise = sensor.noise
    r = sensor.full_scale_rate
    resp = r * (1 + noise.threshold_mismatch**2)
    b = noise.dark_current_rel * resp
    img = np.maximum(rate - b, 0.0) / resp
    if dark is not None:
        img[dark] = 0.0
    for f, level in zip(flats, levels, strict=True):
        img[f] = level
    sim_sensor = sensor.replace(noise=noise.replace(fpn_seed=noise.fpn_seed + 7919 + seed))
    stream = ss.simulate(ss.scenes.Static(img.astype(np.float32)), sim_sensor, n_readouts,
                         seed=seed, progress=progress)
    sim = as_capture(stream)
    regions = ([("dark", dark)] if dark is not None else []) + \
        [(f"flat {i} (I={levels[i]:.3g})", f) for i, f in enumerate(flats)]
    keep = {name: m for name, m in regions}
    m_cap = pixel_intervals(cap, 0, n_readouts, keep=keep, max_samples=200_000)
    m_sim = pixel_intervals(sim, 0, n_readouts, keep=keep, max_samples=200_000)
    c_rate = _counts(cap, n_readouts) / n_readouts
    s_rate = _counts(sim, n_readouts) / n_readouts
    rows, out = [], {}
    for name, m in regions:
        a, bb = c_rate[m], s_rate[m]
        d = ks_distance(a, bb)
        crit = ks_critical(a.size, bb.size)
        ia, ib = m_cap.samples[name], m_sim.samples[name]
        di = ks_distance(ia, ib)
        criti = ks_critical(ia.size, ib.size)
        out[name] = {"rate": {"capture_mean": a.mean(), "resim_mean": bb.mean(),
                              "capture_sd": a.std(), "resim_sd": bb.std(), "ks": d,
                              "ks_critical": crit},
                     "isi": {"capture_mean": ia.mean() if ia.size else np.nan,
                             "resim_mean": ib.mean() if ib.size else np.nan,
                             "capture_sd": ia.std() if ia.size else np.nan,
                             "resim_sd": ib.std() if ib.size else np.nan, "ks": di,
                             "ks_critical": criti}}
        rows.append((name, "pixel rate", a.mean(), bb.mean(), a.std(), bb.std(), d, crit))
        rows.append((name, "interval", out[name]["isi"]["capture_mean"],
                     out[name]["isi"]["resim_mean"], out[name]["isi"]["capture_sd"],
                     out[name]["isi"]["resim_sd"], di, criti))
    headers = ["region", "statistic", "capture mean", "re-sim mean", "capture sd", "re-sim sd",
               "KS D", "D crit (α=0.001)"]

    def plot(fig):
        ax1, ax2 = fig.subplots(1, 2)
        shown = regions if len(regions) <= 4 else [regions[0], regions[1],
                                                  regions[len(regions) // 2], regions[-1]]
        for i, (name, m) in enumerate(shown):
            for src, vals, ls in (("capture", c_rate[m], "-"), ("re-sim", s_rate[m], "--")):
                v = np.sort(vals)
                ax1.plot(v, np.linspace(0, 1, v.size), ls, color=f"C{i}",
                         label=f"{name} {src}")
        ax1.set(xscale="log", xlabel="pixel rate (spikes/readout)", ylabel="CDF",
                title="per-pixel rate distributions (some regions)")
        ax1.legend(fontsize=6)
        name = regions[-1][0]
        ia, ib = m_cap.samples[name], m_sim.samples[name]
        if ia.size and ib.size:
            bins = np.arange(0, max(ia.max(), ib.max()) + 2) - 0.5
            ax2.hist(ia, bins=bins, density=True, alpha=0.5, label="capture")
            ax2.hist(ib, bins=bins, density=True, histtype="step", color="k", label="re-sim")
        ax2.set(xlabel="interval (readouts)", ylabel="probability",
                title=f"interval histogram, {name}")
        ax2.legend(fontsize=7)

    summary = summary_distances(c_rate, s_rate, m_cap, m_sim, dark, flats)
    big = regions[-1][1] if not flats else max(flats, key=lambda f: int(f.sum()))
    curves = {"rates": (c_rate[big], s_rate[big]),
              "rate_label": "rate, largest flat region" if flats else "rate, dark region"}
    return {"n_readouts": n_readouts, "fpn_seed": sim_sensor.noise.fpn_seed, "seed": seed,
            "regions": out, "summary": summary, "headers": headers, "rows": rows, "plot": plot,
            "curves": curves}


def _resimulate(sensor, img, n_readouts, seed, progress):
    """The re-simulation of the static scene ``img`` by ``sensor`` with a fixed
    pattern of its own (module notes) and the re-simulating sensor."""
    noise = sensor.noise
    sim_sensor = sensor.replace(noise=noise.replace(fpn_seed=noise.fpn_seed + 7919 + seed))
    stream = ss.simulate(ss.scenes.Static(img.astype(np.float32)), sim_sensor, n_readouts,
                         seed=seed, progress=progress)
    return as_capture(stream), sim_sensor


def natural_goodness_of_fit(cap, sensor, dark, pools, steady, planes, n_readouts: int,
                            seed: int = 1, progress: bool = False, rate=None) -> dict:
    """Compare a capture without a flat region with a re-simulation (module notes).

    ``pools``: :class:`spikesim.analysis.natural_fit.Pools`; ``steady``: (H, W)
    bool, the pixels of the interval statistic; ``planes``: the colour planes;
    ``rate``: the capture's (H, W) rates for the re-simulated scene (default:
    over its first ``n_readouts``).
    """
    from spikesim.analysis.natural_fit import local_scene, smooth_scene

    cap = as_capture(cap)
    noise = sensor.noise
    resp = sensor.full_scale_rate * (1 + noise.threshold_mismatch**2)
    base = _counts(cap, n_readouts) / n_readouts if rate is None else rate
    img = np.maximum(smooth_scene(base, planes) - noise.dark_current_rel * resp, 0.0) / resp
    if dark is not None:
        img[dark] = 0.0
    sim, sim_sensor = _resimulate(sensor, img, n_readouts, seed, progress)
    c_rate = _counts(cap, n_readouts) / n_readouts
    s_rate = _counts(sim, n_readouts) / n_readouts
    c_scene = local_scene(c_rate, planes)[0]
    s_scene = local_scene(s_rate, planes)[0]
    m_cap = pixel_intervals(cap, 0, n_readouts)
    m_sim = pixel_intervals(sim, 0, n_readouts)
    summary = pool_distances(c_rate, s_rate, c_scene, s_scene, pools.label, m_cap, m_sim, steady)
    labels, sizes = np.unique(pools.label[pools.label > 0], return_counts=True)
    curves = {"rates": (np.zeros(0), np.zeros(0)), "rate_label": "rate / local scene"}
    if labels.size:
        at = pools.label == labels[np.argmax(sizes)]
        curves["rates"] = (c_rate[at] / np.maximum(c_scene[at], 1e-12),
                           s_rate[at] / np.maximum(s_scene[at], 1e-12))
        curves["rate_label"] = f"rate / local scene, pool at {float(np.mean(c_scene[at])):.2g}"
    return {"n_readouts": n_readouts, "fpn_seed": sim_sensor.noise.fpn_seed, "seed": seed,
            "summary": summary, "curves": curves, "pools": int(labels.size),
            "pool_pixels": int(sizes.sum()) if sizes.size else 0,
            "steady_pixels": int(steady.sum())}


def _counts(cap, n):
    return pixel_counts(cap, 0, n).astype(np.float64)


def default_sensor_like(sensor, scale_known: bool = True):
    """``sensor`` with the package's default :class:`~spikesim.noise.PhysicalNoise`
    (same ``fpn_seed``) and ``full_scale_rate`` chosen so the mean response
    ``r·E[1/t] = r·(1 + s²)`` equals the fitted one: only the noise differs.

    ``scale_known=False`` (flat radiances unknown, so full scale is only the
    brightest region): the currents relative to full scale
    (``dark_current_rel``, ``hot_pixel_dark_rel``) keep their fitted values,
    as the defaults' fractions of an arbitrary full scale mean nothing."""
    fitted = sensor.noise
    default = ss.noise.PhysicalNoise(fpn_seed=fitted.fpn_seed)
    if not scale_known:
        default = default.replace(dark_current_rel=fitted.dark_current_rel,
                                  hot_pixel_dark_rel=fitted.hot_pixel_dark_rel)
    resp = sensor.full_scale_rate * (1 + fitted.threshold_mismatch**2)
    return sensor.replace(noise=default,
                          full_scale_rate=resp / (1 + default.threshold_mismatch**2))


def compare_resimulations(cap, sensors: dict, rate, dark, flats, levels, hot, n_readouts: int,
                          seed: int = 1, progress: bool = False, natural=None) -> dict:
    """:func:`goodness_of_fit` of each named sensor (same scene and seed) and a table
    of the summary distances, one row per sensor; the smallest per column is closest.

    ``natural``: ``(pools, steady, planes)`` for a capture without a flat
    region (:func:`natural_goodness_of_fit`; ``flats`` is then empty)."""
    if natural is not None:
        fits = {name: natural_goodness_of_fit(cap, s, dark, *natural, n_readouts, seed=seed,
                                              progress=progress, rate=rate)
                for name, s in sensors.items()}
    else:
        fits = {name: goodness_of_fit(cap, s, rate, dark, flats, levels, hot, n_readouts,
                                      seed=seed, progress=progress)
                for name, s in sensors.items()}
    headers = ["sensor", "rate KS (mean D)", "interval CV error", "spatial spread error"]
    rows = [(name, f["summary"]["rate_ks"], f["summary"]["interval_cv_error"],
             f["summary"]["spatial_spread_error"]) for name, f in fits.items()]
    return {"fits": fits, "headers": headers, "rows": rows}
