"""Quantization noise: clocked readout against the ideal asynchronous reference.

The clocked sensor reports readout ``n`` as 1 when at least one threshold
crossing lies in ``(n, n+1]`` (docs/model.md); the exact crossing times of the
same noise-free sensor come from :func:`spikesim.ideal_spike_times`.  For a
flat field of radiance ``I`` (charge ``q_i`` thresholds per readout) this
study reports:

* **bit agreement** between the clocked stream and the ideal times mapped to
  readouts (1 for every reset mode while ``q < 1``), and the crossings lost
  to the one-spike-per-readout limit (``q − 1`` per readout above saturation);
* **timing error** ``⌈t⌉ − t`` of the clocked spike against its exact time:
  uniform on [0, 1), mean 1/2 and s.d. ``1/√12`` readouts;
* **intensity error** of TFP over ``window`` readouts against the truth
  ``q_i/r``: no bias below saturation, s.d. ``sqrt(f(1−f))/(w·r)`` with
  ``f = frac(w·q)`` (:func:`spikesim.estimate.tfp_std`); above saturation a
  bias ``1/r − I``; TFI's error likewise;
* **reset modes**: rate of modulo and subtract ``min(q, 1)``, zero reset
  ``1/⌈1/q⌉`` (residual charge lost), and the subtract mode's known hard case:
  after a saturating period of ``N₁`` readouts at charge ``q₁ > 1`` the excess
  ``N₁(q₁ − 1)`` drains at ``1 − q₂`` per readout, so the pixel keeps firing
  every readout for ``N₁(q₁ − 1)/(1 − q₂)`` readouts after the light drops to
  ``q₂`` (modulo: a run of mean ``q₂``, zero: 0).

Reference: Dong et al., AAAI 2024, eq. 1 (integrate and fire); Zhu et al.,
ICME 2019 (TFP, TFI).
"""

from __future__ import annotations

import numpy as np

import spikesim as ss
from spikesim._validate import check_size
from spikesim.analysis import theory
from spikesim.analysis.report import AnalysisResult
from spikesim.analysis.sweep import check_levels, check_sensor
from spikesim.errors import bad_value
from spikesim.estimate import tfi, tfp_std
from spikesim.noise import fixed_pattern
from spikesim.scenes.keyframes import Keyframes

__all__ = ["quantization_study", "saturation_recovery", "DEFAULT_Q_LEVELS", "RESETS"]

DEFAULT_Q_LEVELS = (0.05, 0.1, 0.2, 0.35, 0.5, 0.8, 1.2, 1.5, 2.0, 3.0)
RESETS = ("modulo", "subtract", "zero")


def saturation_recovery(sensor, high: float, low: float, n_readouts: int = 1000,
                        size: tuple[int, int] = (4, 16), seed: int = 0) -> dict:
    """Readouts a pixel keeps firing every readout after a step from ``high`` to ``low``.

    The step is at readout ``n_readouts // 2``.  Returns the measured mean
    run of consecutive spikes after the step and the theory
    ``N₁·max(q₁ − 1, 0)/(1 − q₂)`` for subtract reset; modulo keeps only the
    phase, so the run is 1 with probability ``q₂`` (mean ``q₂`` for ``q₂ < 1/2``);
    zero reset restarts from an empty pixel (0).
    """
    h, w = check_size(size)
    sen = sensor.replace(height=h, width=w, noise=None)
    n1 = n_readouts // 2
    ts = n1 / sen.clock_hz
    eps = 1e-3 / sen.clock_hz
    hi = np.full((h, w), float(high), np.float32)
    lo = np.full((h, w), float(low), np.float32)
    scene = Keyframes([0.0, ts, ts + eps, n_readouts / sen.clock_hz], [hi, hi, lo, lo])
    spikes = ss.simulate(scene, sen, n_readouts, seed=seed).unpack()
    after = spikes[n1 + 1:]
    zeros = after == 0
    run = np.where(zeros.any(axis=0), zeros.argmax(axis=0), after.shape[0])
    r = sen.full_scale_rate
    q1, q2 = r * float(np.float32(high)), r * float(np.float32(low))
    if sen.reset == "subtract" and q2 < 1:
        th = n1 * max(q1 - 1.0, 0.0) / (1.0 - q2)
    elif sen.reset == "modulo" and q2 < 0.5:
        th = q2  # the first readout after the step fires with probability q2 (uniform phase)
    else:
        th = 0.0 if q2 < 0.5 else np.nan
    return {"reset": sen.reset, "high": high, "low": low, "run_mean": float(run.mean()),
            "run_theory": th}


def quantization_study(sensor="ideal", levels=DEFAULT_Q_LEVELS, n_readouts: int = 2000,
                       size: tuple[int, int] = (16, 16), window: int = 41, seed: int = 0,
                       resets=RESETS, progress: bool = False) -> AnalysisResult:
    """Compare the clocked stream with the ideal asynchronous reference (see module notes).

    ``sensor`` must have no per-readout noise (fixed patterns are allowed);
    its reset mode is replaced by each of ``resets`` in turn.
    """
    sensor = check_sensor(sensor)
    if sensor.noise is not None and sensor.noise.per_readout:
        raise bad_value("sensor.noise", sensor.noise.to_dict(),
                        "no per-readout noise and no reset_charge_loss (the ideal reference is "
                        "deterministic and unclocked)")
    lv = check_levels(levels)
    if np.any(lv <= 0):
        raise bad_value("levels", levels, "radiances > 0")
    for m in resets:
        if m not in RESETS:
            raise bad_value("resets", resets, f"reset modes among {RESETS}")
    if n_readouts < 2 * window:
        raise bad_value("n_readouts", n_readouts, f">= 2·window = {2 * window}")
    h, w = check_size(size)
    base = sensor.replace(height=h, width=w)
    r = base.full_scale_rate
    pat = fixed_pattern(base.noise, h, w, r)
    nb = n_readouts // window
    rows, reset_rows = [], []
    out = {k: [] for k in ("agreement", "lost_per_readout", "lost_theory", "timing_mean",
                           "timing_sd", "tfp_bias", "tfp_rms", "tfp_rms_theory", "tfi_rms")}
    rates = {m: [] for m in resets}
    rates_th = {m: [] for m in resets}
    it = lv
    if progress:
        from tqdm.auto import tqdm

        it = tqdm(lv, desc="quantization", unit="level")
    for level in it:
        scene = ss.scenes.procedural("flat", size=(h, w), level=float(level))
        q = pat.gain * float(np.float32(level)) + pat.offset
        ideal = ss.ideal_spike_times(scene, base.replace(reset="modulo"), n_readouts, seed)
        for m in resets:
            sp = ss.simulate(scene, base.replace(reset=m), n_readouts, seed=seed).unpack()
            rates[m].append(float(sp.mean()))
            rates_th[m].append(float(theory.rate_theory(q, m).mean()))
            if m == resets[0]:
                clocked = sp
        agree = float(np.mean(clocked == ideal.clocked(n_readouts)))
        lost = (ideal.count.sum() - clocked.sum(dtype=np.int64)) / (n_readouts * h * w)
        lost_th = float(np.maximum(q - 1.0, 0.0).mean())
        t = ideal.times[ideal.times > 0]
        err = np.ceil(t) - t
        c = clocked[: nb * window].reshape(nb, window, h, w).sum(axis=1) / (window * r)
        truth = q / r
        e = c - truth
        th = float(np.sqrt(np.mean(tfp_std(truth, window, r) ** 2))) if q.max() < 1 else np.nan
        centres = np.arange(window, n_readouts - window, window)
        ti = np.stack([tfi(clocked, int(k), rate=r, window=None) for k in centres])
        vals = (agree, lost, lost_th, float(err.mean()), float(err.std()),
                float(e.mean()), float(np.sqrt(np.mean(e**2))), th,
                float(np.sqrt(np.mean((ti - truth) ** 2))))
        for k, v in zip(out, vals, strict=True):
            out[k].append(v)
        rows.append((level, *vals))
        reset_rows.append((level, *[v for m in resets for v in (rates[m][-1], rates_th[m][-1])]))
    recovery = [saturation_recovery(base.replace(reset=m), high=1.5 / r, low=0.2,
                                    n_readouts=min(n_readouts, 1000), seed=seed)
                for m in resets]
    headers = ["radiance I", "bit agreement", "lost/readout", "theory max(q−1,0)",
               "timing err mean", "timing err sd", f"TFP bias (w={window})", "TFP rms",
               "TFP rms theory", "TFI rms"]
    rh = ["radiance I"] + [f"{m} {k}" for m in resets for k in ("rate", "theory")]
    rec_rows = [(d["reset"], d["run_mean"], d["run_theory"]) for d in recovery]
    data = {"sensor": base.to_dict(), "levels": lv, "n_readouts": n_readouts, "window": window,
            "seed": seed, **out, "reset_rates": rates, "reset_rates_theory": rates_th,
            "recovery": recovery, "timing_theory": {"mean": 0.5, "sd": 1 / np.sqrt(12)}}
    notes = [
        f"Flat fields {h}×{w}, {n_readouts} readouts, r = {r}. Ideal reference: "
        "spikesim.ideal_spike_times (exact crossing times); timing error ⌈t⌉ − t in readouts "
        "(theory: mean 0.5, sd 0.2887). Intensity errors in scene units (1 = full scale).",
        "Reset modes: modulo/subtract rate min(q, 1), zero 1/⌈1/q⌉. Saturation recovery: "
        f"readouts of continuous firing after a step from I = {1.5 / r:.3g} to 0.2 at mid-stream.",
    ]

    def plot(fig):
        ax1, ax2 = fig.subplots(1, 2)
        ax1.loglog(lv, out["tfp_rms"], "o", ms=4, label=f"TFP rms (w={window})")
        ax1.loglog(lv, np.abs(out["tfp_bias"]), "x", ms=5, label="|TFP bias|")
        ax1.loglog(lv, out["tfp_rms_theory"], "-", label="theory (no bias)")
        ax1.loglog(lv, out["tfi_rms"], "^", ms=4, label="TFI rms")
        ax1.axvline(1 / r, color="grey", lw=0.5)
        ax1.set(xlabel="radiance I", ylabel="error (scene units)",
                title="quantization error of estimates")
        ax1.legend(fontsize=7)
        for m in resets:
            line = ax2.plot(lv, rates[m], "o", ms=4, label=f"{m}")
            ax2.plot(lv, rates_th[m], "-", lw=0.8, color=line[0].get_color())
        ax2.set(xlabel="radiance I", ylabel="spikes / readout", title="reset modes")
        ax2.legend(fontsize=7)

    return AnalysisResult(
        "quantization", "Quantization: clocked vs ideal asynchronous", data,
        [("Clocked against ideal", headers, rows),
         ("Rate by reset mode (measured, theory)", rh, reset_rows),
         ("Saturation recovery (readouts of continuous firing after the light drops)",
          ["reset", "measured", "theory"], rec_rows)], notes, plot)
