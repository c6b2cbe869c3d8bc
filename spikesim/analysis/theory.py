"""Closed-form predictions of the integrate-and-fire model used by every study.

Notation: ``q`` is the charge per readout in units of the pixel's own
threshold (``q = r·(g·I + d)/t``, see :func:`spikesim.noise.fixed_pattern`),
``w`` a window in readouts.  Derivations (docs/model.md, Dong et al. AAAI 2024
eq. 1 for the pixel, eq. 5 for paper-mode noise):

* **Rate.**  Modulo and subtract reset fire ``min(q, 1)`` spikes per readout
  on average (one spike per readout at most); zero reset discards the residual
  charge, so a cycle lasts ``ceil(1/q)`` readouts and the rate is
  ``1/ceil(1/q)`` (``q ≥ 1``: 1).
* **Count over a window.**  The count is ``floor(a + X) − floor(a)`` for a
  uniform phase ``a`` and the window's charge ``X`` (thresholds).  Given X the
  count is ``⌊X⌋`` or ``⌊X⌋+1`` with ``P = frac(X)``, so
  ``E = E[X]`` and ``Var = Var(X) + E[frac(X)(1 − frac(X))]``.  Noise free,
  ``Var = f(1 − f)`` with ``f = frac(w·q)``.
* **Per-readout charge variance** ``v1`` (thresholds²): Poisson shot noise on
  ``E`` electrons per threshold gives ``q/E``; comparator jitter of relative
  s.d. ``σ_t`` per firing cycle gives ``q·σ_t²`` (one draw per threshold
  crossed); together ``q·κ²`` with the **cycle coefficient of variation**
  ``κ² = σ_t² + 1/E``.  A charge noise of ``σ_e`` electrons per readout
  (``charge_noise_electrons``) adds ``σ_q² = (σ_e/E)²`` per readout whatever
  the charge.
* **Paper mode** (eq. 5): each readout collects ``r·max(I + s·z, 0)`` with
  ``s = sqrt(σ_g² + σ_p²·y)/255``, ``y = 255·I``: a rectified normal, of mean
  ``r·(I·Φ(a) + s·φ(a))`` and variance ``r²·((I² + s²)·Φ(a) + I·s·φ(a)) −
  mean²``, ``a = I/s`` (:func:`paper_charge`).  So negative light clipped to
  zero raises the mean charge (in the dark: ``r·s/√(2π)``, a dark rate), and
  the independent per-readout charges accumulate like a charge noise:
  ``κ² = 0`` and ``σ_q²`` = that variance (:func:`temporal_terms`).
* **Inter-spike interval.**  The unclocked cycle length is
  ``τ ~ (1/q)·(1 + κ·z)`` readouts (renewal, independent cycles), so
  ``Var(τ) = κ²/q²``.  Clocking maps ``τ`` to ``⌈τ − u⌉`` with the phase ``u``
  of the previous spike, i.e. ``⌊τ⌋`` or ``⌊τ⌋+1`` with ``P = frac(τ)``:
  ``E[ISI] = 1/q`` and ``Var(ISI) = κ²/q² + E[frac(τ)(1 − frac(τ))]``.
  Noise free this is ``p(1 − p)``, ``p = frac(1/q)``: intervals of
  ``floor(1/q)`` and ``ceil(1/q)`` readouts only.  With ``sd(τ) ≳ 0.5``
  readouts the second term is 1/6.
* **Accumulating charge noise.**  Independent Gaussian charges of variance
  ``σ_q²`` per readout make the charge a random walk with drift ``q``; the
  time to gain one threshold is its first passage time (inverse Gaussian),
  of variance ``σ_q²/q³``.  So ``Var(τ) = κ²/q² + σ_q²/q³`` and the cycle
  CV² is ``κ² + σ_q²·m`` with ``m = 1/q``: it grows with the interval length,
  unlike per-cycle noise (:func:`isi_cv2_theory`).

* **Charge loss at reset** (``reset_charge_loss`` f): the readout after each
  firing collects ``(1 − f)·q``.  Noise free, over N readouts with S spikes
  the charge collected is ``N·q − S·f·q`` and (modulo, subtract) each spike
  consumes one threshold, so the rate is ``q/(1 + f·q)`` (at most 1) and the
  mean interval ``1/q + f`` readouts; zero reset needs
  ``⌈1/q + f⌉`` readouts per cycle.  With temporal noise the cycle is the
  deterministic shift ``f`` plus the time to gain one threshold, so
  ``Var(τ)`` is unchanged and the cycle CV² is
  ``(κ² + σ_q²·m₀)·(m₀/(m₀ + f))²`` with ``m₀ = 1/q``: the loss lowers the
  CV of short intervals only, by a factor ``(1 − f/m)²`` at interval ``m``
  (f = 0.002, m = 17…38: at most 1.2e-4 relative), so it cannot make the CV
  grow with the interval length as accumulating charge noise does.

The expectation ``E[frac(X)(1 − frac(X))]`` over a Gaussian ``X`` is computed
from the Fourier series of the sawtooth (:func:`frac_variance`).
"""

from __future__ import annotations

import numpy as np

from spikesim.errors import bad_value
from spikesim.noise import PaperNoise, PhysicalNoise
from spikesim.sensor import RESET_MODES

__all__ = [
    "local_frac_term",
    "rate_theory",
    "frac_variance",
    "count_variance",
    "cycle_cv2",
    "charge_variance_per_readout",
    "isi_mean_theory",
    "isi_var_theory",
    "isi_cv2_theory",
    "charge_noise_var",
    "paper_charge",
    "effective_charge",
    "temporal_terms",
    "reset_loss",
    "with_reset_loss",
    "theory_holds",
    "isi_clean_pmf",
]

#: Terms of the Fourier series in :func:`frac_variance`.
_FOURIER_TERMS = 400
_M = np.arange(1, _FOURIER_TERMS + 1, dtype=np.float64)[None, :]


def _numbers(value, name: str) -> np.ndarray:
    """``value`` as float64 when it holds real numbers (not strings), else an error."""
    raw = np.asarray(value)
    if raw.dtype.kind not in "biuf":
        raise bad_value(name, value, "real numbers (a number or an array of them)")
    return raw.astype(np.float64)


def _noise_model(noise):
    """``noise`` when it is a noise model or None, else an error naming it."""
    if noise is not None and not isinstance(noise, (PaperNoise, PhysicalNoise)):
        raise bad_value("noise", noise, "a spikesim.noise model (PaperNoise, PhysicalNoise) "
                        "or None")
    return noise


def _charge(q, interval: bool = False) -> np.ndarray:
    """``q`` as float64, checked: finite and ≥ 0; for interval statistics
    ``0 < q ≤ 1`` (a pixel at q ≥ 1 fires at every readout: no interval to describe)."""
    arr = _numbers(q, "q")
    if not np.all(np.isfinite(arr)):
        raise bad_value("q", q, "finite charges per readout (thresholds)")
    if interval and (np.any(arr <= 0) or np.any(arr > 1)):
        raise bad_value("q", q, "charges per readout in (0, 1] thresholds (at q >= 1 every "
                        "readout fires; at 0 none does)")
    if np.any(arr < 0):
        raise bad_value("q", q, "charges per readout >= 0 thresholds")
    return arr


def _fraction(value, name: str) -> float:
    """A charge loss in [0, 1)."""
    v = float(value)
    if not 0.0 <= v < 1.0:
        raise bad_value(name, value, "a fraction in [0, 1)")
    return v


def _variance(value, name: str) -> float:
    v = float(value)
    if not (np.isfinite(v) and v >= 0.0):
        raise bad_value(name, value, "a finite variance >= 0")
    return v


def rate_theory(q, reset: str = "modulo", loss: float = 0.0) -> np.ndarray:
    """Mean spikes per readout at charge ``q`` thresholds/readout for a reset
    mode, with charge loss ``loss`` at reset (module notes): modulo and
    subtract ``min(q/(1 + f·q), 1)``, zero ``1/⌈1/q + f⌉``."""
    if reset not in RESET_MODES:
        raise bad_value("reset", reset, f"one of {RESET_MODES}")
    q = _charge(q)
    f = _fraction(loss, "loss")
    if reset == "zero":
        with np.errstate(divide="ignore"):
            cyc = np.ceil(np.where(q > 0, 1.0 / np.maximum(q, 1e-300), np.inf) + f - 1e-12)
        return np.where(q * (1.0 - f) >= 1.0, 1.0, np.where(q > 0, 1.0 / np.maximum(cyc, 1.0),
                                                            0.0))
    return np.minimum(q / (1.0 + f * q), 1.0)


def frac_variance(mean, sd) -> np.ndarray:
    """``E[frac(X)(1 − frac(X))]`` for ``X ~ N(mean, sd²)`` (``sd = 0``: exact value).

    Uses the Fourier series of the periodic function
    ``f(1 − f) = 1/6 − Σ_m cos(2πm f)/(π² m²)`` and
    ``E[cos(2πmX)] = cos(2πm·mean)·exp(−2π²m²sd²)`` (exact up to truncation at
    :data:`_FOURIER_TERMS` terms, error < 1/(π²·M)).
    """
    mean = _numbers(mean, "mean")
    sd = _numbers(sd, "sd")
    if np.any(~(sd >= 0)):
        raise bad_value("sd", sd, "standard deviations >= 0")
    mean, sd = np.broadcast_arrays(mean, sd)
    f0 = mean - np.floor(mean)
    out = f0 * (1.0 - f0)
    noisy = sd > 0
    if np.any(noisy):
        mu, s = mean[noisy][:, None], sd[noisy][:, None]
        series = np.cos(2 * np.pi * _M * (mu - np.floor(mu))) * np.exp(
            -2 * np.pi**2 * _M**2 * s**2) / (np.pi**2 * _M**2)
        out = np.array(out, dtype=np.float64)
        out[noisy] = 1.0 / 6.0 - series.sum(axis=1)
    return np.clip(out, 0.0, 0.25)


def local_frac_term(mean, sd) -> np.ndarray:
    """Rounding term of the *local* interval variance ``E[(I[k+1] − I[k])²]/2``.

    Clocked intervals are ``I[k] = τ[k] + u[k+1] − u[k]`` with ``u`` the wait from
    a threshold crossing to the next readout; for cycles ``τ ~ N(mean, sd²)``
    (readouts) and a uniform phase, averaging over the phase gives
    ``E[(I[k+1] − I[k])²] = 2·Var(τ) + 2g(τ) + 2g(τ') − g(τ + τ')`` with
    ``g(x) = frac(x)(1 − frac(x))`` (the phase-averaged bridge covariance
    ``min(x, y) − xy`` equals ``(g(x) + g(y) − g(x − y))/2``), so the local
    variance is ``Var(τ) + 2·F(mean, sd) − F(2·mean, √2·sd)/2`` with ``F``
    :func:`frac_variance`.  Large noise: ``1/3 − 1/12 = 1/4`` (``F → 1/6``).
    """
    mean = _numbers(mean, "mean")
    sd = _numbers(sd, "sd")
    return 2 * frac_variance(mean, sd) - frac_variance(2 * mean, np.sqrt(2.0) * sd) / 2


def cycle_cv2(noise) -> float:
    """Squared coefficient of variation κ² of one firing cycle (physical noise)."""
    if not isinstance(_noise_model(noise), PhysicalNoise):
        return 0.0
    k2 = noise.temporal_threshold_noise**2
    if noise.shot_noise:
        k2 += 1.0 / noise.electrons_per_threshold
    return float(k2)


def charge_noise_var(noise) -> float:
    """``σ_q²`` (thresholds² per readout) of the accumulating charge noise
    (nominal threshold; 0 for other models)."""
    if not isinstance(_noise_model(noise), PhysicalNoise):
        return 0.0
    return float((noise.charge_noise_electrons / noise.electrons_per_threshold) ** 2)


def with_reset_loss(q, v1, loss: float):
    """``(q_eff, v1_eff)``: the charge and per-readout variance that make
    :func:`count_variance` describe a pixel with charge loss ``f`` at reset.  A count
    over many cycles is a renewal count: mean ``w/E[τ]``, variance ``w·Var(τ)/E[τ]³``;
    without loss ``E[τ] = 1/q`` and ``w·Var(τ)·q³ = w·v1``, and the loss only moves
    ``E[τ]`` to ``1/q + f``, so ``q_eff = q/(1 + f·q)`` and ``v1_eff = v1·(q_eff/q)³``."""
    q = np.asarray(q, dtype=np.float64)
    v1 = np.asarray(v1, dtype=np.float64)
    f = _fraction(loss, "loss")
    if f == 0.0:
        return q, v1
    ratio = 1.0 / (1.0 + f * q)  # q_eff / q
    return q * ratio, v1 * ratio**3


def theory_holds(q, v1, noise, near_saturation: bool = True) -> bool:
    """Whether the count and rate theory describes pixels of charge ``q`` (thresholds per
    readout) with per-readout charge variance ``v1``: not with noise where some pixel's
    charge is within ``0.05 + 3·sqrt(v1)`` of one threshold (the per-readout clipping
    couples the sources; checked when ``near_saturation``), nor with accumulating
    charge noise ``σ_q²`` where some pixel's drift ``q < 10·σ_q²`` (the charge, held at
    0, then crosses by diffusion alone)."""
    if noise is None:
        return True
    q = np.asarray(q, dtype=np.float64)
    near = np.abs(q - 1.0) < 0.05 + 3.0 * np.sqrt(np.maximum(np.asarray(v1, float), 0.0))
    s2 = charge_noise_var(noise)
    return not ((near_saturation and np.any(near)) or (s2 > 0 and np.any(q < 10.0 * s2)))


def reset_loss(noise) -> float:
    """The charge loss at reset ``f`` (``reset_charge_loss``; 0 for other models)."""
    return float(noise.reset_charge_loss) if isinstance(_noise_model(noise), PhysicalNoise) \
        else 0.0


def charge_variance_per_readout(q, noise, full_scale_rate: float, intensity=None):
    """Per-readout variance of the charge (thresholds²) at mean charge ``q``.

    Physical mode: ``q·κ² + σ_q²`` (see module notes; fixed-pattern electrons
    per threshold are ignored to first order).  Paper mode (eq. 5): the
    variance of the rectified charge at radiance ``intensity``
    (:func:`paper_charge`; ``r²·(σ_g² + σ_p²·y)/255²`` far above zero).
    """
    return effective_charge(q, noise, full_scale_rate, intensity)[1]


def _rectified(mu, s):
    """Mean and variance of ``max(X, 0)`` for ``X ~ N(mu, s²)``, ``s ≥ 0``."""
    from scipy.special import ndtr

    mu, s = np.broadcast_arrays(np.asarray(mu, np.float64), np.asarray(s, np.float64))
    noisy = s > 0
    a = mu / np.where(noisy, s, 1.0)
    cdf, pdf = ndtr(a), np.exp(-0.5 * a * a) / np.sqrt(2.0 * np.pi)
    clean = np.maximum(mu, 0.0)
    mean = np.where(noisy, mu * cdf + s * pdf, clean)
    second = np.where(noisy, (mu * mu + s * s) * cdf + mu * s * pdf, clean * clean)
    return mean, np.maximum(second - mean * mean, 0.0)


def paper_charge(noise, full_scale_rate: float, intensity):
    """Mean (thresholds) and variance (thresholds²) of one readout's paper-mode
    charge ``r·max(I + s·z, 0)`` at radiance ``intensity``, ``s =
    sqrt(σ_g² + σ_p²·255·I)/255`` (Dong et al. eq. 5, negative light clipped
    to zero: the rectified normal, module notes)."""
    if not isinstance(noise, PaperNoise):
        raise bad_value("noise", noise, "a PaperNoise")
    if not (np.isfinite(full_scale_rate) and full_scale_rate > 0):
        raise bad_value("full_scale_rate", full_scale_rate, "a rate > 0 (spikes per readout)")
    level = _numbers(intensity, "intensity")
    if np.any(level < 0):
        raise bad_value("intensity", intensity, "radiances >= 0")
    sd = np.sqrt(noise.variance_dn(255.0 * level)) / 255.0
    mean, var = _rectified(level, sd)
    return full_scale_rate * mean, full_scale_rate**2 * var


def effective_charge(q, noise, full_scale_rate: float, intensity=None):
    """``(mean, variance)`` of the charge per readout (thresholds, thresholds²) of
    pixels of nominal charge ``q``: ``(q, q·κ² + σ_q²)`` in physical mode,
    :func:`paper_charge` at radiance ``intensity`` (default 0) in paper mode, ``(q, 0)``
    without noise.  The rate and count theory take this mean."""
    q = _charge(q)
    if not (np.isfinite(full_scale_rate) and full_scale_rate > 0):
        raise bad_value("full_scale_rate", full_scale_rate, "a rate > 0 (spikes per readout)")
    if isinstance(_noise_model(noise), PhysicalNoise):
        return q, q * cycle_cv2(noise) + charge_noise_var(noise)
    if isinstance(noise, PaperNoise):
        mean, var = paper_charge(noise, full_scale_rate, 0.0 if intensity is None else intensity)
        return mean + 0.0 * q, var + 0.0 * q
    return q, np.zeros_like(q)


def temporal_terms(noise, full_scale_rate: float, intensity=None) -> tuple[float, float]:
    """``(κ², σ_q²)`` of the interval theory: per-cycle CV² and the per-readout
    variance that accumulates (thresholds²).  Physical mode: :func:`cycle_cv2`,
    :func:`charge_noise_var`; paper mode: ``0`` and the variance of
    :func:`paper_charge` at radiance ``intensity`` (its charges are independent per
    readout, so they accumulate like a charge noise)."""
    if isinstance(noise, PaperNoise):
        return 0.0, float(np.mean(paper_charge(noise, full_scale_rate,
                                               0.0 if intensity is None else intensity)[1]))
    return cycle_cv2(noise), charge_noise_var(noise)


def count_variance(q, window: int, v1=0.0) -> np.ndarray:
    """Variance of the spike count over ``window`` readouts (non-saturating ``q < 1``)."""
    q = _charge(q)
    if isinstance(window, bool) or not isinstance(window, int | np.integer) or window < 1:
        raise bad_value("window", window, "an integer >= 1 readouts")
    v1 = _numbers(v1, "v1")
    if np.any(~(v1 >= 0)):
        raise bad_value("v1", v1, "per-readout variances >= 0")
    vx = window * v1
    return vx + frac_variance(window * q, np.sqrt(vx))


def isi_mean_theory(q, loss: float = 0.0) -> np.ndarray:
    """Mean inter-spike interval (readouts) at charge ``q < 1``: ``1/q + f``
    with charge loss ``f`` at reset (0: ``1/q``)."""
    return 1.0 / _charge(q, interval=True) + _fraction(loss, "loss")


def isi_var_theory(q, kappa2: float = 0.0, sigma_q2: float = 0.0,
                   loss: float = 0.0) -> np.ndarray:
    """Variance of the clocked inter-spike interval (readouts²), see module
    notes: ``Var(τ) + E[frac(τ)(1 − frac(τ))]`` with
    ``Var(τ) = κ²/q² + σ_q²/q³`` and ``E[τ] = 1/q + f``."""
    q = _charge(q, interval=True)
    kappa2, sigma_q2 = _variance(kappa2, "kappa2"), _variance(sigma_q2, "sigma_q2")
    sd = np.sqrt(kappa2 / q**2 + sigma_q2 / q**3)
    return sd**2 + frac_variance(1.0 / q + _fraction(loss, "loss"), sd)


def isi_cv2_theory(q, kappa2: float = 0.0, sigma_q2: float = 0.0,
                   loss: float = 0.0) -> np.ndarray:
    """Squared CV of the unclocked cycle length, ``(κ² + σ_q²·m₀)·(m₀/(m₀ + f))²``
    with ``m₀ = 1/q`` readouts and charge loss ``f``: constant for per-cycle
    noise without loss, growing linearly with the interval for accumulating
    charge noise; the loss only lowers it for short intervals."""
    m0 = 1.0 / _charge(q, interval=True)
    kappa2, sigma_q2 = _variance(kappa2, "kappa2"), _variance(sigma_q2, "sigma_q2")
    return (kappa2 + sigma_q2 * m0) * (m0 / (m0 + _fraction(loss, "loss"))) ** 2


def isi_clean_pmf(q: float) -> dict[int, float]:
    """Noise-free interval distribution: ``{floor(1/q): 1 − p, ceil(1/q): p}``."""
    if np.ndim(q) != 0:
        raise bad_value("q", q, "one charge per readout (a number; use isi_var_theory for "
                        "arrays)")
    inv = 1.0 / float(_charge(q, interval=True))
    n = int(np.floor(inv))
    p = inv - n
    if p < 1e-12:
        return {n: 1.0}
    return {n: 1.0 - p, n + 1: p}
