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

from dataclasses import dataclass

import numpy as np

from spikesim.analysis import theory
from spikesim.analysis.report import AnalysisResult
from spikesim.analysis.sweep import check_levels, check_sensor, simulate_flat
from spikesim.errors import bad_value
from spikesim.estimate import tfi

__all__ = ["snr_curve", "measure_snr", "snr_report", "dynamic_range", "SNRConfig",
           "tfi_moments_theory", "DEFAULT_SNR_LEVELS", "DEFAULT_WINDOWS"]

DEFAULT_SNR_LEVELS = (0.0, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 1.5, 2.0)
DEFAULT_WINDOWS = (11, 41, 161)

_GH_X, _GH_W = np.polynomial.hermite_e.hermegauss(48)
_GH_W = _GH_W / _GH_W.sum()


def tfi_moments_theory(q, kappa2: float, r: float, sigma_q2: float = 0.0,
                       loss: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Mean and second moment of the TFI estimate of pixels with charge ``q`` (0 < q < 1):
    the cycle ``τ`` is Gaussian of mean ``1/q + f`` and variance ``κ²/q² + σ_q²/q³``
    (:mod:`spikesim.analysis.theory`, charge loss ``f`` and accumulating charge noise
    ``σ_q²``), clocked to ``⌊τ⌋`` or ``⌈τ⌉`` readouts."""
    q = np.asarray(q, dtype=np.float64)
    sd = np.sqrt(kappa2 / q**2 + sigma_q2 / q**3)
    noisy = kappa2 > 0 or sigma_q2 > 0
    tau = 1.0 / q[..., None] + loss + (sd[..., None] * _GH_X if noisy else 0.0 * _GH_X)
    tau = np.maximum(tau, 1.0)
    n = np.floor(tau)
    f = tau - n
    inv_l = np.sum(_GH_W * ((1 - f) / n + f / (n + 1)), axis=-1)
    mean_l = 1.0 / q + loss  # a centre falls in an interval with probability ∝ its length
    return 1.0 / (mean_l * r), inv_l / (mean_l * r**2)


def _window_estimates(spikes, w, r):
    t = spikes.shape[0]
    nb = t // w
    c = spikes[: nb * w].reshape(nb, w, *spikes.shape[1:]).sum(axis=1, dtype=np.int64)
    return c / (w * r)


@dataclass(frozen=True)
class SNRConfig:
    """How :func:`snr_curve` measures: window lengths (readouts), stream length and size,
    seed, spacing of TFI centres and the window that defines the dynamic range."""

    windows: tuple[int, ...] = DEFAULT_WINDOWS
    n_readouts: int = 3220
    size: tuple[int, int] = (24, 24)
    seed: int = 0
    tfi_stride: int = 50
    dr_window: int | None = None  # None: the longest window

    def __post_init__(self):
        wins = tuple(int(w) for w in self.windows)
        if not wins or any(w < 1 for w in wins):
            raise bad_value("windows", self.windows, "one or more window lengths >= 1 readout")
        if self.n_readouts < 2 * max(wins):
            raise bad_value("n_readouts", self.n_readouts, f">= 2·max(windows) = {2 * max(wins)}")
        dr = max(wins) if self.dr_window is None else int(self.dr_window)
        if dr not in wins:
            raise bad_value("dr_window", self.dr_window, f"one of windows {list(wins)}")
        object.__setattr__(self, "windows", wins)
        object.__setattr__(self, "dr_window", dr)


def _tfp_snr_theory(model, q, v1, w, r, noise) -> float:
    """SNR of the TFP estimate over window ``w`` from the rate and count theory (NaN where
    :func:`spikesim.analysis.theory.theory_holds` says it does not hold)."""
    if not theory.theory_holds(q, v1, noise, near_saturation=False) or (
            noise is not None and np.any((q > 0.95) & (q < 1))):
        return np.nan  # in the dark with charge noise, or this close to saturation
    qe, v1e = theory.with_reset_loss(q, v1, theory.reset_loss(noise))
    cvar = np.where(qe < 1, theory.count_variance(np.minimum(qe, 1), w, v1e), 0.0)
    var_th = model.var() / r**2 + cvar.mean() / (w * r) ** 2
    mean_th = model.mean() / r
    if var_th > 0:
        return mean_th / np.sqrt(var_th)
    return np.inf if mean_th > 0 else np.nan


def _tfi_snr(spikes, q, cfg: SNRConfig, noise, r: float, level: float) -> tuple[float, float]:
    """Measured and theoretical SNR of TFI at centres ``tfi_stride`` apart (NaN when the
    stream is too short for three of the longest intervals on either side); ``q`` the
    mean charges (:func:`spikesim.analysis.theory.effective_charge`) at radiance ``level``."""
    qmin = float(q.min())
    margin = int(np.ceil(3.0 / qmin)) if qmin > 0 else cfg.n_readouts
    centres = np.arange(margin, cfg.n_readouts - margin, cfg.tfi_stride)
    measured = theory_snr = np.nan
    if centres.size >= 2:
        vals = np.stack([tfi(spikes, int(c), rate=r, no_spike="bound") for c in centres])
        m, s = float(vals.mean()), float(vals.std())
        measured = m / s if s > m * 1e-9 else np.inf
        if ((q > 0) & (q < 0.95)).all():
            kappa2, sigma_q2 = theory.temporal_terms(noise, r, level)
            e1, e2 = tfi_moments_theory(q, kappa2, r, sigma_q2, theory.reset_loss(noise))
            var = e2.mean() - e1.mean() ** 2
            theory_snr = e1.mean() / np.sqrt(var) if var > 1e-18 else np.inf
    return measured, theory_snr


def measure_snr(sensor, levels: np.ndarray, cfg: SNRConfig, progress: bool = False) -> dict:
    """Simulate each flat field and measure TFP (every window) and TFI SNR, the mean rate,
    their theory, the dark counts and the dynamic range (the data :func:`snr_report` shows)."""
    r = sensor.full_scale_rate
    kappa2 = theory.cycle_cv2(sensor.noise)
    wins = cfg.windows
    res = {f"tfp_snr_w{w}": [] for w in wins}
    res.update({f"tfp_snr_theory_w{w}": [] for w in wins})
    res.update(tfi_snr=[], tfi_snr_theory=[], mean_rate=[])
    dark, dark_mean = None, {}
    it = levels
    if progress:
        from tqdm.auto import tqdm

        it = tqdm(levels, desc="snr", unit="level")
    for level in it:
        run = simulate_flat(sensor, level, cfg.n_readouts, cfg.seed, cfg.size)
        q, v1 = theory.effective_charge(run.q, sensor.noise, r, level)
        model = theory.rate_theory(q, sensor.reset, theory.reset_loss(sensor.noise))
        res["mean_rate"].append(float(run.spikes.mean()))
        for w in wins:
            est = _window_estimates(run.spikes, w, r)
            m, s = float(est.mean()), float(est.std())
            if level == 0:
                dark_mean[w] = m
            res[f"tfp_snr_w{w}"].append(m / s if s > m * 1e-9 else np.inf)
            res[f"tfp_snr_theory_w{w}"].append(
                _tfp_snr_theory(model, q, v1, w, r, sensor.noise))
            res.setdefault(f"mean_tfp_w{w}", []).append(m)
        measured, predicted = _tfi_snr(run.spikes, q, cfg, sensor.noise, r, level)
        res["tfi_snr"].append(measured)
        res["tfi_snr_theory"].append(predicted)
        if level == 0:
            dark = {"rate_per_readout": float(run.spikes.mean()),
                    "pixel_sd": float(run.spikes.mean(axis=0).std()),
                    "model_rate": float(model.mean())}
    if dark is not None and sensor.clock_hz:
        dark["rate_hz"] = dark["rate_per_readout"] * sensor.clock_hz
    return {"sensor": sensor.to_dict(), "levels": levels, "windows": list(wins),
            "n_readouts": cfg.n_readouts, "size": list(cfg.size), "seed": cfg.seed,
            "kappa2": kappa2, **res, "dark": dark,
            "dynamic_range": dynamic_range(levels, res, dark_mean.get(cfg.dr_window, 0.0),
                                           cfg.dr_window, r)}


def dynamic_range(levels, res: dict, dark_tfp: float, window: int, r: float) -> dict:
    """From the lowest radiance whose dark-subtracted TFP SNR (window ``window``) is >= 1 to
    the highest whose mean rate is below ``1 − 1e-3``; ratio and dB (20·log10)."""
    snr_dr = []
    for i in range(len(levels)):
        m = res[f"mean_tfp_w{window}"][i]
        snr = res[f"tfp_snr_w{window}"][i]
        snr_dr.append(snr * (m - dark_tfp) / m if m > 0 else 0.0)
    usable = [levels[i] for i in range(len(levels)) if levels[i] > 0 and snr_dr[i] >= 1]
    unsat = [levels[i] for i in range(len(levels)) if res["mean_rate"][i] < 1 - 1e-3]
    i_min = min(usable) if usable else np.nan
    i_max = max(unsat) if unsat else np.nan
    return {"window": window, "i_min": i_min, "i_max": i_max,
            "ratio": i_max / i_min if usable and unsat else np.nan,
            "db": 20 * np.log10(i_max / i_min) if usable and unsat else np.nan,
            "saturation_theory": 1.0 / r}


def snr_report(data: dict) -> AnalysisResult:
    """The table, notes and plot of :func:`measure_snr`'s data."""
    lv, wins, dark = data["levels"], data["windows"], data["dark"]
    dr = data["dynamic_range"]
    i_min, i_max = dr["i_min"], dr["i_max"]
    r = 1.0 / dr["saturation_theory"]
    size, n_readouts = data["size"], data["n_readouts"]
    headers = ["radiance I", "mean rate"] + [f"TFP SNR w={w}" for w in wins] + \
        [f"theory w={w}" for w in wins] + ["TFI SNR", "TFI theory"]
    rows = []
    for i, level in enumerate(lv):
        rows.append([level, data["mean_rate"][i]] + [data[f"tfp_snr_w{w}"][i] for w in wins]
                    + [data[f"tfp_snr_theory_w{w}"][i] for w in wins]
                    + [data["tfi_snr"][i], data["tfi_snr_theory"][i]])
    notes = [
        f"Flat fields, {size[0]}×{size[1]} pixels, {n_readouts} readouts; SNR = mean/sd of the "
        "estimate over pixels and windows (temporal + fixed-pattern noise).",
        f"Dark-count rate: {dark['rate_per_readout']:.4g} spikes/readout "
        f"(model {dark['model_rate']:.4g}, per-pixel sd {dark['pixel_sd']:.3g})"
        + (f", {dark['rate_hz']:.4g} Hz." if "rate_hz" in dark else ".")
        if dark else "No I = 0 level in the sweep: dark-count rate not measured.",
        f"Dynamic range (TFP, w = {dr['window']}, dark-subtracted SNR ≥ 1 up to saturation): "
        f"I_min = {i_min:.4g}, I_max = {i_max:.4g} (saturation theory 1/r = {1 / r:.4g}), "
        f"{dr['db']:.1f} dB.",
    ]

    def plot(fig):
        ax1, ax2 = fig.subplots(1, 2)
        pos = lv > 0
        for w in wins:
            y = np.array(data[f"tfp_snr_w{w}"], float)[pos]
            line = ax1.loglog(lv[pos], np.where(np.isfinite(y), y, np.nan), "o", ms=4,
                              label=f"TFP w={w}")
            yt = np.array(data[f"tfp_snr_theory_w{w}"], float)[pos]
            ax1.loglog(lv[pos], np.where(np.isfinite(yt), yt, np.nan), "-",
                       color=line[0].get_color(), lw=0.8)
        y = np.array(data["tfi_snr"], float)[pos]
        ax1.loglog(lv[pos], np.where(np.isfinite(y), y, np.nan), "k^", ms=4, label="TFI")
        ax1.axhline(1.0, color="grey", lw=0.5)
        ax1.set(xlabel="radiance I", ylabel="SNR", title="SNR (lines: theory)")
        ax1.legend(fontsize=7)
        ax2.loglog(lv[pos], np.array(data["mean_rate"])[pos], "o", ms=4, label="mean rate")
        ax2.loglog(lv[pos], np.minimum(r * lv[pos], 1), "k--", label="min(r·I, 1)")
        if dark:
            ax2.axhline(dark["rate_per_readout"] or np.nan, color="r", lw=0.8, label="dark rate")
        if np.isfinite(i_min):
            ax2.axvspan(i_min, i_max, color="g", alpha=0.1, label="dynamic range")
        ax2.set(xlabel="radiance I", ylabel="spikes / readout", title="response and range")
        ax2.legend(fontsize=7)

    return AnalysisResult("snr", "SNR, dark counts and dynamic range", data,
                          [("SNR against radiance", headers, rows)], notes, plot)


def snr_curve(sensor="ideal", levels=DEFAULT_SNR_LEVELS, windows=DEFAULT_WINDOWS,
              n_readouts: int = 3220, size: tuple[int, int] = (24, 24), seed: int = 0,
              tfi_stride: int = 50, dr_window: int | None = None,
              progress: bool = False) -> AnalysisResult:
    """SNR of TFP (each window length) and TFI against radiance; dark rate; dynamic range.

    The two steps are :func:`measure_snr` (simulation and measurement, configured by
    :class:`SNRConfig`) and :func:`snr_report` (table, notes, plot).
    """
    sensor = check_sensor(sensor)
    cfg = SNRConfig(tuple(windows), n_readouts, tuple(size), seed, tfi_stride, dr_window)
    return snr_report(measure_snr(sensor, np.unique(check_levels(levels)), cfg, progress))
