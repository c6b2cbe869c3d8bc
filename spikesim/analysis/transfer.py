"""Transfer curve: mean firing rate against flat-field radiance (EMVA 1288 style).

For each radiance ``I`` of a sweep a flat field is simulated and the per-pixel
spike counts are split into non-overlapping windows of ``window`` readouts.
Three quantities are reported per level (rates in spikes per readout):

* **mean rate** over pixels and time, against the ideal ``min(r·I, 1)``
  (one spike per readout at most; ``r`` = ``full_scale_rate``) and against the
  model's prediction ``mean_i rate(q_i)`` with the sensor's own fixed pattern
  (:mod:`spikesim.analysis.theory`);
* **fixed-pattern spread**: standard deviation over pixels of each pixel's
  mean rate over the whole stream; theory
  ``sqrt(var_i rate(q_i) + mean_i Var(count_T)/T²)`` (the second term is the
  temporal sampling error of a mean over ``T`` readouts, negligible for long
  streams);
* **temporal spread**: the standard deviation over time of one pixel's rate
  measured in a window, averaged (in variance) over pixels; theory
  ``sqrt(mean_i Var(count_w))/w`` with ``Var(count_w)`` from
  :func:`~spikesim.analysis.theory.count_variance`.

Reference: EMVA Standard 1288 release 4.0 (2021), §4 (mean, temporal and
spatial variance separated); Dong et al., AAAI 2024, eq. 1.
"""

from __future__ import annotations

import numpy as np

from spikesim.analysis import theory
from spikesim.analysis.report import AnalysisResult
from spikesim.analysis.sweep import check_levels, check_sensor, simulate_flat
from spikesim.errors import bad_value

__all__ = ["transfer_curve", "window_spreads", "DEFAULT_LEVELS"]

#: Default radiance sweep (linear, 1 = full scale): up to 2× the saturation radiance 1/r.
DEFAULT_LEVELS = (0.0, 0.02, 0.05, 0.1, 0.2, 0.35, 0.5, 0.7, 0.9, 1.2, 1.5, 2.0, 3.0)


def window_spreads(spikes: np.ndarray, window: int) -> tuple[np.ndarray, float, float]:
    """Per-pixel mean rate, fixed-pattern s.d. and temporal s.d. of a (T, H, W) stream.

    Returns ``(rate (H, W), fpn_sd, temporal_sd)`` in spikes per readout.
    """
    t = spikes.shape[0]
    nb = t // window
    if nb < 2:
        raise bad_value("window", window, f"at most n_readouts/2 = {t // 2} (two windows)")
    c = spikes[: nb * window].reshape(nb, window, *spikes.shape[1:]).sum(axis=1, dtype=np.int64)
    rate = spikes.mean(axis=0, dtype=np.float64)
    tvar = float(np.mean(c.var(axis=0, ddof=1)))  # counts², per window
    return rate, float(rate.std()), float(np.sqrt(tvar)) / window


def transfer_curve(sensor="ideal", levels=DEFAULT_LEVELS, n_readouts: int = 2000,
                   size: tuple[int, int] = (32, 32), window: int = 100, seed: int = 0,
                   progress: bool = False) -> AnalysisResult:
    """Measure the transfer curve of ``sensor`` over a flat-field sweep.

    Parameters
    ----------
    sensor : Sensor or preset name
        Its size is replaced by ``size``; noise, reset and rate are kept.
    levels : sequence of float
        Flat-field radiances (linear, 1 = full scale).
    n_readouts : int
        Readouts per level (at least ``2·window``).
    window : int
        Readouts per window of the temporal spread.
    """
    sensor = check_sensor(sensor)
    lv = check_levels(levels)
    if isinstance(window, bool) or not isinstance(window, int) or window < 1:
        raise bad_value("window", window, "an integer number of readouts >= 1")
    if not isinstance(n_readouts, int) or n_readouts < 2 * window:
        raise bad_value("n_readouts", n_readouts, f"an integer >= 2·window = {2 * window}")
    r = sensor.full_scale_rate
    rows, out = [], {k: [] for k in ("mean_rate", "ideal_rate", "model_rate", "fpn_sd",
                                     "fpn_sd_theory", "temporal_sd", "temporal_sd_theory")}
    it = lv
    if progress:
        from tqdm.auto import tqdm

        it = tqdm(lv, desc="transfer", unit="level")
    for level in it:
        run = simulate_flat(sensor, level, n_readouts, seed, size)
        rate, fpn, tsd = window_spreads(run.spikes, window)
        loss = theory.reset_loss(sensor.noise)
        qm, v1 = theory.effective_charge(run.q, sensor.noise, r, level)
        model = theory.rate_theory(qm, sensor.reset, loss)
        holds = theory.theory_holds(qm, v1, sensor.noise)
        qe, v1e = theory.with_reset_loss(qm, v1, loss)
        qc = np.minimum(qe, 1)
        cvar = np.where(qe < 1, theory.count_variance(qc, window, v1e), 0.0)
        tot = np.where(qe < 1, theory.count_variance(qc, n_readouts, v1e), 0.0)
        fpn_theory = float(np.sqrt(model.var() + tot.mean() / n_readouts**2))
        temporal = float(np.sqrt(cvar.mean())) / window
        vals = (float(rate.mean()), min(r * level, 1.0),
                float(model.mean()) if holds else np.nan, fpn,
                fpn_theory if holds else np.nan, tsd,
                temporal if holds and sensor.reset != "zero" else np.nan)
        for k, v in zip(out, vals, strict=True):
            out[k].append(v)
        rows.append((level, *vals))
    headers = ["radiance I", "mean rate", "ideal min(rI,1)", "model", "FPN sd", "FPN sd theory",
               f"temporal sd ({window} r.)", "temporal sd theory"]
    data = {"sensor": sensor.to_dict(), "levels": lv, "n_readouts": n_readouts,
            "size": list(size), "window": window, "seed": seed, **out}
    notes = [
        f"Flat-field sweep, {size[0]}×{size[1]} pixels, {n_readouts} readouts per level, "
        f"full_scale_rate r = {r}, reset = {sensor.reset}, noise = "
        f"{sensor.noise.to_dict() if sensor.noise else None}.",
        "Rates in spikes per readout. *model* uses the sensor's own fixed pattern "
        "(q_i = r·(g_i·I + d_i)/t_i); FPN = spread of per-pixel mean rates; temporal = "
        f"spread of one pixel's rate over {window}-readout windows; the charge loss at "
        "reset is included, and paper-mode noise as the rectified charge r·max(I + s·z, 0) "
        "(negative light clipped: a dark rate). With noise the theory columns are not given "
        "(–) where some pixel's charge per readout is within 0.05 + 3 noise s.d. of one "
        "threshold, or, with accumulating charge noise σ_q², below 10·σ_q² (spikes from diffusion "
        "alone); the temporal theory is not given for zero reset.",
    ]

    def plot(fig):
        ax1, ax2 = fig.subplots(1, 2)
        ax1.plot(lv, out["ideal_rate"], "k--", label="ideal min(r·I, 1)")
        ax1.plot(lv, out["model_rate"], "c-", label="model (fixed pattern)")
        ax1.plot(lv, out["mean_rate"], "o", ms=4, label="measured")
        ax1.set(xlabel="radiance I (1 = full scale)", ylabel="spikes / readout",
                title="transfer curve")
        ax1.legend(fontsize=7)
        ax2.plot(lv, out["fpn_sd"], "o", ms=4, label="FPN measured")
        ax2.plot(lv, out["fpn_sd_theory"], "-", label="FPN theory")
        ax2.plot(lv, out["temporal_sd"], "s", ms=4, label="temporal measured")
        ax2.plot(lv, out["temporal_sd_theory"], "--", label="temporal theory")
        ax2.set(xlabel="radiance I", ylabel="s.d. of rate (spikes/readout)",
                title="fixed-pattern vs temporal spread")
        ax2.legend(fontsize=7)

    return AnalysisResult("transfer", "Transfer curve", data,
                          [("Transfer curve", headers, rows)], notes, plot)
