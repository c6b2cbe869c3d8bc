"""Inter-spike-interval (ISI) statistics per intensity, against theory.

Theory (derived in :mod:`spikesim.analysis.theory`): a pixel with charge ``q``
thresholds per readout (``q < 1``) fires with unclocked cycle lengths
``τ = (1/q)(1 + κz)``, κ² = σ_t² + 1/E (comparator jitter and shot noise,
Dong et al. AAAI 2024 eq. 1 with the noise of :mod:`spikesim.noise`).  The
clocked interval is ``⌊τ⌋`` or ``⌊τ⌋+1`` with ``P = frac(τ)``, hence

* noise free: only ``floor(1/q)`` and ``ceil(1/q)`` readouts occur, the
  longer with probability ``p = frac(1/q)``; mean ``1/q``, variance ``p(1−p)``;
* with temporal noise: mean ``1/q``, within-pixel variance
  ``κ²/q² + E[frac(τ)(1−frac(τ))]`` (→ ``κ²/q² + 1/6`` once sd(τ) ≳ 0.5);
* fixed-pattern noise (gain, threshold, dark current) leaves each pixel's
  interval law as above with its own ``q_i``: it broadens the histogram pooled
  over pixels (``Var_pooled = mean_i Var_i + var_i(1/q_i)``) but not the
  within-pixel variance.
"""

from __future__ import annotations

import numpy as np

from spikesim.analysis import theory
from spikesim.analysis.capture import as_capture, pixel_intervals
from spikesim.analysis.report import AnalysisResult
from spikesim.analysis.sweep import check_levels, check_sensor, simulate_flat
from spikesim.errors import bad_value
from spikesim.noise import PaperNoise

__all__ = ["isi_statistics", "interval_summary", "DEFAULT_ISI_LEVELS"]

DEFAULT_ISI_LEVELS = (0.02, 0.05, 0.1, 0.2, 0.35, 0.5, 0.8, 1.2)


def interval_summary(moments, mask=None, min_intervals: int = 2) -> dict:
    """Pooled statistics of :class:`~spikesim.analysis.capture.IntervalMoments` over ``mask``.

    Returns the number of intervals, the mean of per-pixel mean intervals,
    the pooled within-pixel variance ``Σ(s2 − s1²/n)/Σ(n − 1)`` and the
    variance of all intervals pooled over pixels (readouts²).
    """
    sel = np.ones(moments.n.shape, bool) if mask is None else np.asarray(mask, bool)
    sel = sel & (moments.n >= min_intervals)
    n = moments.n[sel].astype(np.float64)
    if n.size == 0 or n.sum() < 2:
        raise bad_value("capture length", f"{int(moments.n.sum())} intervals",
                        f"at least {min_intervals} intervals in some pixel of the region "
                        "(use a longer capture or a brighter region)")
    s1, s2 = moments.s1[sel], moments.s2[sel]
    within = float(np.sum(s2 - s1**2 / n) / np.sum(n - 1))
    tot_n = n.sum()
    pooled_mean = s1.sum() / tot_n
    pooled_var = float(s2.sum() / tot_n - pooled_mean**2) * tot_n / (tot_n - 1)
    return {"intervals": int(tot_n), "pixels": int(n.size),
            "mean": float(np.mean(s1 / n)), "pooled_mean": float(pooled_mean),
            "within_var": within, "pooled_var": pooled_var}


def isi_statistics(sensor="ideal", levels=DEFAULT_ISI_LEVELS, n_readouts: int = 5000,
                   size: tuple[int, int] = (16, 16), seed: int = 0,
                   progress: bool = False) -> AnalysisResult:
    """ISI mean, within-pixel and pooled variance per flat-field radiance, with theory.

    Levels whose ideal rate ``r·I`` is 0 or 1 or more (one spike every readout) are
    skipped, with a note naming them.  Raises when a level yields fewer than two intervals per pixel
    (``n_readouts`` too short for that intensity).
    """
    sensor = check_sensor(sensor)
    asked = check_levels(levels)
    lv = asked[(asked > 0) & (asked * sensor.full_scale_rate < 1)]
    left_out = [float(v) for v in asked if v not in lv]
    if lv.size == 0:
        raise bad_value("levels", levels, "some radiance with 0 < r·I < 1 (r = full_scale_rate)")
    paper, r = isinstance(sensor.noise, PaperNoise), sensor.full_scale_rate
    kappa2, sigma_q2 = theory.temporal_terms(sensor.noise, r)
    loss = theory.reset_loss(sensor.noise)
    rows = []
    keys = ("mean", "mean_theory", "within_var", "within_var_theory", "pooled_var",
            "pooled_var_theory", "clean_fraction")
    out = {k: [] for k in keys} | ({"sigma_q2": []} if paper else {})
    hists = []
    it = lv
    if progress:
        from tqdm.auto import tqdm

        it = tqdm(lv, desc="isi", unit="level")
    for level in it:
        run = simulate_flat(sensor, level, n_readouts, seed, size)
        q = np.minimum(theory.effective_charge(run.q, sensor.noise, r, level)[0], 1.0)
        if paper:  # its per-readout variance depends on the radiance
            kappa2, sigma_q2 = theory.temporal_terms(sensor.noise, r, level)
            out["sigma_q2"].append(sigma_q2)
        if np.mean(q) * n_readouts < 3:
            raise bad_value("n_readouts", n_readouts,
                            f">= {int(np.ceil(3 / max(np.mean(q), 1e-12)))} for radiance "
                            f"{level} (at least two intervals per pixel)")
        mom = pixel_intervals(as_capture(run.spikes), keep={"all": np.ones(q.shape, bool)})
        s = interval_summary(mom)
        ok = q > 0
        wvar_i = theory.isi_var_theory(q[ok], kappa2, sigma_q2, loss)
        mean_i = theory.isi_mean_theory(q[ok], loss)
        within_th = float(np.average(wvar_i, weights=mom.n[ok] + 1e-9))
        pooled_th = float(np.mean(wvar_i) + np.var(mean_i))
        pmf = theory.isi_clean_pmf(float(np.median(q)))
        iv = mom.samples["all"]
        clean_frac = float(np.isin(iv, list(pmf)).mean()) if iv.size else np.nan
        vals = (s["mean"], float(np.mean(mean_i)), s["within_var"], within_th,
                s["pooled_var"], pooled_th, clean_frac)
        for k, v in zip(keys, vals, strict=True):
            out[k].append(v)
        rows.append((level, s["intervals"], *vals))
        hists.append((level, iv, pmf))
    headers = ["radiance I", "intervals", "mean ISI", "theory 1/q + f", "within-pixel var",
               "theory", "pooled var", "theory", "in {⌊1/q⌋,⌈1/q⌉}"]
    data = {"sensor": sensor.to_dict(), "levels": lv, "n_readouts": n_readouts,
            "size": list(size), "seed": seed, "kappa2": kappa2, "sigma_q2": sigma_q2,
            "reset_charge_loss": loss, **out}
    terms = (f"Paper-mode noise: κ² = 0, and each readout's independent rectified charge "
             f"r·max(I + s·z, 0) (mean q, above r·I near the dark) has variance σ_q² = "
             f"{', '.join(f'{v:.3g}' for v in out['sigma_q2'])} thresholds² at the radiances "
             "below, which accumulates like a charge noise" if paper else
             f"Cycle CV² κ² = σ_t² + 1/E = {kappa2:.3g}; accumulating charge noise "
             f"σ_q² = (σ_e/E)² = {sigma_q2:.3g} thresholds² per readout")
    notes = [
        f"Flat fields, {size[0]}×{size[1]} pixels, {n_readouts} readouts; intervals in "
        f"readouts. {terms}; charge loss at reset f = {loss:g}.",
        "Theory: mean 1/q + f; within-pixel variance κ²/q² + σ_q²/q³ + "
        "E[frac(τ)(1−frac(τ))] (p(1−p) noise free); pooled variance adds the fixed-pattern "
        "spread var_i(1/q_i). Last column: "
        "fraction of intervals equal to floor or ceil of 1/q at the median pixel (1 when "
        "noise free and without fixed pattern).",
    ]
    if left_out:
        notes.append(f"Radiances left out: {left_out} (r·I = 0 or >= 1: no spike, or one "
                     "every readout, so no interval to describe).")

    def plot(fig):
        axes = fig.subplots(1, 2)
        ax = axes[0]
        ax.loglog(lv, out["mean"], "o", ms=4, label="mean ISI")
        ax.loglog(lv, out["mean_theory"], "-", label="1/q")
        ax.loglog(lv, np.sqrt(out["within_var"]), "s", ms=4, label="sd within pixel")
        ax.loglog(lv, np.sqrt(out["within_var_theory"]), "--", label="sd theory")
        ax.set(xlabel="radiance I", ylabel="readouts", title="ISI vs intensity")
        ax.legend(fontsize=7)
        ax = axes[1]
        level, iv, pmf = hists[len(hists) // 2]
        if iv.size:
            bins = np.arange(iv.min(), iv.max() + 2) - 0.5
            ax.hist(iv, bins=bins, density=True, alpha=0.6, label="measured")
        ax.bar(list(pmf), list(pmf.values()), width=0.3, color="k", label="noise-free law")
        ax.set(xlabel="interval (readouts)", ylabel="probability",
               title=f"ISI histogram at I = {level:g}")
        ax.legend(fontsize=7)

    return AnalysisResult("isi", "Inter-spike intervals", data,
                          [("ISI statistics", headers, rows)], notes, plot)
