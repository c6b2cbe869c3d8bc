"""SNR of intensity estimates against radiance, dark-count rate and dynamic range.

For each flat-field radiance ``I`` the stream is cut into non-overlapping
windows of ``w`` readouts and each window gives a TFP estimate
``Î = count/(w·r)`` (Zhu et al., ICME 2019, §3.1; :func:`spikesim.estimate.tfp`);
TFI estimates ``1/(ISI·r)`` (same paper, §3.2; :func:`spikesim.estimate.tfi`)
are taken at centres spaced ``tfi_stride`` readouts apart, at least three
longest intervals from either end of the stream (not measured when the
stream is too short for that).  The SNR is
``mean(Î)/sd(Î)`` over pixels and windows (total noise: temporal and fixed
pattern, EMVA 1288 §4 "total SNR").

Theory (:mod:`spikesim.analysis.theory`), per pixel of charge ``q_i``:

* TFP: ``E = rate(q_i)/r``, ``Var = Var(count_w)/(w r)²``; pooled over
  pixels the fixed pattern adds ``var_i(q_i)/r²``;
* TFI: the centre falls in an interval of length ``L`` with probability
  ``∝ L·P(L)``, so ``E[Î] = q/r`` and ``E[Î²] = (q/r²)·E[1/L]`` with the
  interval law of :mod:`spikesim.analysis.isi` (noise free: ``⌊1/q⌋`` or
  ``⌈1/q⌉``).

Dark-count rate: the mean rate at ``I = 0`` (spikes per readout, and per
second when the clock is known).  Dynamic range: from the lowest swept
radiance whose dark-subtracted TFP SNR (window ``dr_window``) is at least 1
to the saturation radiance, the highest swept radiance whose mean rate is
below ``1 − 1e-3``; reported as a ratio and in dB (20·log10).
"""

from __future__ import annotations

import numpy as np

from spikesim.analysis import theory
from spikesim.analysis.report import AnalysisResult
from spikesim.analysis.sweep import check_levels, check_sensor, simulate_flat
from spikesim.errors import bad_value
from spikesim.estimate import tfi

__all__ = ["snr_curve", "tfi_moments_theory", "DEFAULT_SNR_LEVELS", "DEFAULT_WINDOWS"]

DEFAULT_SNR_LEVELS = (0.0, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 1.5, 2.0)
DEFAULT_WINDOWS = (11, 41, 161)

_GH_X, _GH_W = np.polynomial.hermite_e.hermegauss(48)
_GH_W = _GH_W / _GH_W.sum()


def tfi_moments_theory(q, kappa2: float, r: float) -> tuple[np.ndarray, np.ndarray]:
    """Mean and second moment of the TFI estimate of pixels with charge ``q`` (0 < q < 1)."""
    q = np.asarray(q, dtype=np.float64)
    sd = np.sqrt(kappa2) / q
    tau = 1.0 / q[..., None] + (sd[..., None] * _GH_X if kappa2 > 0 else 0.0 * _GH_X)
    tau = np.maximum(tau, 1.0)
    n = np.floor(tau)
    f = tau - n
    inv_l = np.sum(_GH_W * ((1 - f) / n + f / (n + 1)), axis=-1)
    return q / r, q / r**2 * inv_l


def _window_estimates(spikes, w, r):
    t = spikes.shape[0]
    nb = t // w
    c = spikes[: nb * w].reshape(nb, w, *spikes.shape[1:]).sum(axis=1, dtype=np.int64)
    return c / (w * r)


def snr_curve(sensor="ideal", levels=DEFAULT_SNR_LEVELS, windows=DEFAULT_WINDOWS,
              n_readouts: int = 3220, size: tuple[int, int] = (24, 24), seed: int = 0,
              tfi_stride: int = 50, dr_window: int | None = None,
              progress: bool = False) -> AnalysisResult:
    """SNR of TFP (each window length) and TFI against radiance; dark rate; dynamic range."""
    sensor = check_sensor(sensor)
    lv = np.unique(check_levels(levels))
    wins = [int(w) for w in windows]
    if not wins or any(w < 1 for w in wins):
        raise bad_value("windows", windows, "one or more window lengths >= 1 readout")
    if n_readouts < 2 * max(wins):
        raise bad_value("n_readouts", n_readouts, f">= 2·max(windows) = {2 * max(wins)}")
    dr_window = max(wins) if dr_window is None else int(dr_window)
    if dr_window not in wins:
        raise bad_value("dr_window", dr_window, f"one of windows {wins}")
    r = sensor.full_scale_rate
    kappa2 = theory.cycle_cv2(sensor.noise)
    res = {f"tfp_snr_w{w}": [] for w in wins}
    res.update({f"tfp_snr_theory_w{w}": [] for w in wins})
    res.update(tfi_snr=[], tfi_snr_theory=[], mean_rate=[])
    dark = None
    it = lv
    if progress:
        from tqdm.auto import tqdm

        it = tqdm(lv, desc="snr", unit="level")
    dark_mean = {}
    for level in it:
        run = simulate_flat(sensor, level, n_readouts, seed, size)
        q = run.q
        model = theory.rate_theory(q, sensor.reset)
        v1 = theory.charge_variance_per_readout(q, sensor.noise, r, level)
        res["mean_rate"].append(float(run.spikes.mean()))
        for w in wins:
            est = _window_estimates(run.spikes, w, r)
            m, s = float(est.mean()), float(est.std())
            if level == 0:
                dark_mean[w] = m
            res[f"tfp_snr_w{w}"].append(m / s if s > m * 1e-9 else np.inf)
            cvar = np.where(q < 1, theory.count_variance(np.minimum(q, 1), w, v1), 0.0)
            var_th = model.var() / r**2 + cvar.mean() / (w * r) ** 2
            mean_th = model.mean() / r
            if np.any((q > 0.95) & (q < 1)) and sensor.noise is not None:
                snr_th = np.nan  # the count theory is not valid this close to saturation
            elif var_th > 0:
                snr_th = mean_th / np.sqrt(var_th)
            else:
                snr_th = np.inf if mean_th > 0 else np.nan
            res[f"tfp_snr_theory_w{w}"].append(snr_th)
            res.setdefault(f"mean_tfp_w{w}", []).append(m)
        qmin = float(q.min())
        margin = int(np.ceil(3.0 / qmin)) if qmin > 0 else n_readouts
        centres = np.arange(margin, n_readouts - margin, tfi_stride)
        if centres.size >= 2:
            vals = np.stack([tfi(run.spikes, int(c), rate=r, no_spike="bound") for c in centres])
            m, s = float(vals.mean()), float(vals.std())
            res["tfi_snr"].append(m / s if s > m * 1e-9 else np.inf)
        else:  # intervals too long for this stream: TFI not measured
            res["tfi_snr"].append(np.nan)
        ok = (q > 0) & (q < 0.95)
        if centres.size >= 2 and ok.all():
            e1, e2 = tfi_moments_theory(q, kappa2, r)
            var = e2.mean() - e1.mean() ** 2
            res["tfi_snr_theory"].append(e1.mean() / np.sqrt(var) if var > 1e-18 else np.inf)
        else:
            res["tfi_snr_theory"].append(np.nan)
        if level == 0:
            dark = {"rate_per_readout": float(run.spikes.mean()),
                    "pixel_sd": float(run.spikes.mean(axis=0).std()),
                    "model_rate": float(model.mean())}
    # dynamic range from the dr_window TFP estimates
    base = dark_mean.get(dr_window, 0.0)
    snr_dr = []
    for i in range(len(lv)):
        m = res[f"mean_tfp_w{dr_window}"][i]
        snr = res[f"tfp_snr_w{dr_window}"][i]
        snr_dr.append(snr * (m - base) / m if m > 0 else 0.0)
    usable = [lv[i] for i in range(len(lv)) if lv[i] > 0 and snr_dr[i] >= 1]
    unsat = [lv[i] for i in range(len(lv)) if res["mean_rate"][i] < 1 - 1e-3]
    i_min = min(usable) if usable else np.nan
    i_max = max(unsat) if unsat else np.nan
    dr = {"window": dr_window, "i_min": i_min, "i_max": i_max,
          "ratio": i_max / i_min if usable and unsat else np.nan,
          "db": 20 * np.log10(i_max / i_min) if usable and unsat else np.nan,
          "saturation_theory": 1.0 / r}
    if dark is not None and sensor.clock_hz:
        dark["rate_hz"] = dark["rate_per_readout"] * sensor.clock_hz
    headers = ["radiance I", "mean rate"] + [f"TFP SNR w={w}" for w in wins] + \
        [f"theory w={w}" for w in wins] + ["TFI SNR", "TFI theory"]
    rows = []
    for i, level in enumerate(lv):
        rows.append([level, res["mean_rate"][i]] + [res[f"tfp_snr_w{w}"][i] for w in wins]
                    + [res[f"tfp_snr_theory_w{w}"][i] for w in wins]
                    + [res["tfi_snr"][i], res["tfi_snr_theory"][i]])
    data = {"sensor": sensor.to_dict(), "levels": lv, "windows": wins, "n_readouts": n_readouts,
            "size": list(size), "seed": seed, "kappa2": kappa2, **res, "dark": dark,
            "dynamic_range": dr}
    notes = [
        f"Flat fields, {size[0]}×{size[1]} pixels, {n_readouts} readouts; SNR = mean/sd of the "
        "estimate over pixels and windows (temporal + fixed-pattern noise).",
        f"Dark-count rate: {dark['rate_per_readout']:.4g} spikes/readout "
        f"(model {dark['model_rate']:.4g}, per-pixel sd {dark['pixel_sd']:.3g})"
        + (f", {dark['rate_hz']:.4g} Hz." if "rate_hz" in dark else ".")
        if dark else "No I = 0 level in the sweep: dark-count rate not measured.",
        f"Dynamic range (TFP, w = {dr_window}, dark-subtracted SNR ≥ 1 up to saturation): "
        f"I_min = {i_min:.4g}, I_max = {i_max:.4g} (saturation theory 1/r = {1 / r:.4g}), "
        f"{dr['db']:.1f} dB.",
    ]

    def plot(fig):
        ax1, ax2 = fig.subplots(1, 2)
        pos = lv > 0
        for w in wins:
            y = np.array(res[f"tfp_snr_w{w}"], float)[pos]
            line = ax1.loglog(lv[pos], np.where(np.isfinite(y), y, np.nan), "o", ms=4,
                              label=f"TFP w={w}")
            yt = np.array(res[f"tfp_snr_theory_w{w}"], float)[pos]
            ax1.loglog(lv[pos], np.where(np.isfinite(yt), yt, np.nan), "-",
                       color=line[0].get_color(), lw=0.8)
        y = np.array(res["tfi_snr"], float)[pos]
        ax1.loglog(lv[pos], np.where(np.isfinite(y), y, np.nan), "k^", ms=4, label="TFI")
        ax1.axhline(1.0, color="grey", lw=0.5)
        ax1.set(xlabel="radiance I", ylabel="SNR", title="SNR (lines: theory)")
        ax1.legend(fontsize=7)
        ax2.loglog(lv[pos], np.array(res["mean_rate"])[pos], "o", ms=4, label="mean rate")
        ax2.loglog(lv[pos], np.minimum(r * lv[pos], 1), "k--", label="min(r·I, 1)")
        if dark:
            ax2.axhline(dark["rate_per_readout"] or np.nan, color="r", lw=0.8, label="dark rate")
        if np.isfinite(i_min):
            ax2.axvspan(i_min, i_max, color="g", alpha=0.1, label="dynamic range")
        ax2.set(xlabel="radiance I", ylabel="spikes / readout", title="response and range")
        ax2.legend(fontsize=7)

    return AnalysisResult("snr", "SNR, dark counts and dynamic range", data,
                          [("SNR against radiance", headers, rows)], notes, plot)
