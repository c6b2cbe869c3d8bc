"""Temporal noise from per-pixel interval statistics: cycle CV² κ² and charge noise σ_q².

For a pixel of mean interval ``m`` readouts (charge ``q = 1/m`` thresholds per
readout) the clocked inter-spike interval has variance
(:func:`spikesim.analysis.theory.isi_var_theory`)::

    Var(ISI) = κ²·m² + σ_q²·m³ + F(m, sd),   sd² = κ²·m² + σ_q²·m³

where κ² is the per-cycle CV² (comparator jitter and shot noise), σ_q² the
per-readout variance of an accumulating charge noise (thresholds², its
first-passage time is inverse Gaussian) and ``F`` the clock's rounding term
(:func:`spikesim.analysis.theory.frac_variance`).  Per-cycle noise alone gives
a CV² that does not depend on ``m``; the charge noise makes it grow as
``κ² + σ_q²·m``.

Each pixel's sample variance ``v_i`` over ``n_i`` intervals has variance
``≈ 2·V_i²/(n_i − 1)``; (κ², σ_q²) are fitted by weighted least squares on
``v_i − F_i`` with weights ``(n_i − 1)/(2·V_i²)``, ``V_i`` the model of the
previous iteration (five fixed-point iterations, both terms kept ≥ 0).

**Identified or not.**  σ_q² is kept only when the mean intervals span at
least ``MIN_SPAN`` (×1.5, 10th to 90th percentile), its free estimate is at
least ``MIN_Z`` (3) standard errors above 0 *and* its term adds at least
``MIN_SHARE`` (10 %) to the interval variance at the longest intervals
measured; otherwise the charge noise is *not identified* and keeps its
default 0 (a capture made without charge noise gave 3.2 standard errors from
a term worth under 1 % of the variance: significant, but no prediction the
capture can check depends on it).

**Threshold mismatch.**  The charge noise is fixed in electrons, so a pixel of
threshold ``t_i`` (relative) has ``σ_q/t_i``, and its charge-noise variance is
``σ_q²·m_i³/t_i²``.  Within a static region the mean intervals differ by the
fixed pattern, ``m_i ∝ t_i/g_i``: threshold mismatch alone would make that
variance grow as ``m_i``, not ``m_i³``, and a fit with the ``m³`` column read
much of it as κ² (``E`` 9 % low at the default pattern, 17 % with mismatch
7 %).  ``t_i`` is not observed; its regression on the pixel's interval within
its region (``regions``), ``t̂_i = (m_i/m̄)^ρ`` with ``m̄`` the region's
geometric mean and ``ρ = s²/(s² + p²)`` the mismatch share of the response
spread (``mismatch_share``; the calibration's ``mismatch_split``), divides the
column: ``m_i³/t̂_i²``.

**Moving light** (``local=True``, for captures without static regions): each
pixel's variance is replaced by its local variance, half the mean squared
difference of successive intervals (:meth:`IntervalMoments.local_var`), whose
expectation is ``Var(τ) + 2·F(m, sd) − F(2m, √2·sd)/2``
(:func:`spikesim.analysis.theory.local_frac_term`): a change of the light
that is slow against two intervals cancels in the difference, while it
inflates the plain variance by the variance of the pixel's mean interval
over the capture.

**Outliers.**  A pixel whose interval variance exceeds the 0.999 quantile
(:data:`OUTLIER_P`) of its law under the model (``V·χ²(n − 1)/(n − 1)``, ``n``
its intervals) is left out: first under a robust start, κ² per octave of mean
interval from the median of the pixels' own estimates (:func:`_robust_keep`),
then under the fit, which
is repeated (twice at most; the note counts them): a few pixels of moving
content or edges in a region would otherwise dominate κ², their variance
being many times the model's — and, when κ² is small, pull the least-squares
fit up far enough to look plausible themselves.

**Diffusion.**  Where a pixel's drift ``q = 1/m`` is below ``10·σ_q²`` (the
dark: its charge, held at zero, crosses by diffusion, and the random walk's
law fails, see :func:`spikesim.analysis.theory.theory_holds`) the pixel is
left out after a first fit, and the fit repeated: such pixels made κ² 6–8 %
high.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from spikesim.analysis import theory
from spikesim.errors import bad_value

__all__ = ["TemporalFit", "fit_temporal", "kappa2_by_bin", "BinFit", "MIN_SPAN", "MIN_Z",
           "MIN_SHARE"]

#: Least ratio of the 90th to the 10th percentile of the mean intervals for a slope.
MIN_SPAN = 1.5
#: Least significance (standard errors) of σ_q² for it to be kept.
MIN_Z = 3.0
#: Least share of the interval variance ``κ²·m²`` the charge-noise term ``σ_q²·m³`` must
#: reach at the longest intervals measured (90th percentile) for σ_q² to be kept: a
#: smaller term changes no prediction the capture can check (not identified).
MIN_SHARE = 0.1
#: Quantile of a pixel's variance under the fitted model beyond which it is left out.
OUTLIER_P = 0.999
#: Pixels whose drift ``q`` is below this many σ_q² fire by diffusion (left out).
DIFFUSION_DRIFT = 10.0


@dataclass(frozen=True)
class TemporalFit:
    """κ² (per-cycle CV²), σ_q² (thresholds² per readout) and how they were found."""

    kappa2: float
    sigma_q2: float
    sigma_q2_estimate: float  # the two-term estimate, kept or not
    sigma_q2_se: float
    charge_noise_fitted: bool
    reason: str
    n_pixels: int
    n_intervals: int
    interval_span: tuple[float, float]  # 10th and 90th percentile of the mean intervals
    outliers: int = 0  # pixels left out as implausible (module notes)

    def charge_noise_status(self) -> str | None:
        """None when σ_q² was fitted, else why not: ``not fitted (...)`` when
        turned off, otherwise ``not identified: ...``."""
        if self.charge_noise_fitted:
            return None
        if self.reason.startswith("charge noise not fitted"):
            return "not fitted (fit_charge_noise=False)"
        text = self.reason.removeprefix("charge noise not identified: ")
        return "not identified: " + text.split(": charge")[0].split("; charge")[0]


@dataclass(frozen=True)
class _Pixels:
    """The pixels a fit uses: mean interval, interval variance and count, and the
    charge-noise column ``m³/t̂²`` (module notes)."""

    mean: np.ndarray
    var: np.ndarray
    n: np.ndarray
    m3: np.ndarray
    local: bool = False

    def where(self, keep: np.ndarray) -> _Pixels:
        return _Pixels(self.mean[keep], self.var[keep], self.n[keep], self.m3[keep], self.local)

    def rounding(self, sd: np.ndarray) -> np.ndarray:
        """The clock's rounding term of :attr:`var` (module notes)."""
        if self.local:
            return theory.local_frac_term(self.mean, sd)
        return theory.frac_variance(self.mean, sd)


def _select(mom, mask, min_mean, min_n, regions=None, mismatch_share=0.0,
            local: bool = False) -> _Pixels:
    sel = mask & (mom.n >= min_n) & (mom.mean() >= min_mean)
    if local:
        sel &= mom.nd >= min_n - 1
    mean = mom.mean()[sel]
    n = (mom.nd[sel] + 1 if local else mom.n[sel]).astype(np.float64)
    m3 = mean**3
    if regions is not None and mismatch_share > 0:  # σ_q/t_i (module notes)
        label = np.asarray(regions)[sel]
        for g in np.unique(label):
            at = label == g
            log_m = np.log(mean[at])
            t_hat = np.exp(mismatch_share * (log_m - np.average(log_m, weights=n[at])))
            m3[at] /= t_hat**2
    return _Pixels(mean, (mom.local_var() if local else mom.var())[sel], n, m3, local)


def _wls(px: _Pixels, two_terms: bool, iterations: int = 5, nonneg: bool = True):
    """Fixed-point WLS of (κ², σ_q²); returns (κ², σ_q², covariance scale, cov).

    ``nonneg=False`` leaves the coefficients free (for the significance of σ_q²);
    the model variance of the weights is always kept ≥ 0."""
    mean, var, n = px.mean, px.var, px.n
    k2, c = 0.0, 0.0
    cols = [mean**2, px.m3] if two_terms else [mean**2]
    x = np.stack(cols, axis=1)
    cov = np.zeros((x.shape[1], x.shape[1]))
    chi2 = 1.0
    for _ in range(iterations):
        sd = np.sqrt(np.maximum(k2 * mean**2 + c * px.m3, 0.0))
        f = px.rounding(sd)
        v_model = np.maximum(k2 * mean**2 + c * px.m3 + f, 1e-3)
        w = (n - 1) / (2 * v_model**2)
        y = var - f
        if nonneg:
            beta, cov = _solve_nonneg(x, y, w)
        else:
            a = x.T @ (w[:, None] * x)
            cov = np.linalg.inv(a)
            beta = cov @ (x.T @ (w * y))
        k2 = float(beta[0])
        c = float(beta[1]) if two_terms else 0.0
        resid = y - x @ beta
        dof = max(mean.size - x.shape[1], 1)
        chi2 = float(np.sum(w * resid**2)) / dof
    return k2, c, max(chi2, 1.0), cov


def _solve_nonneg(x, y, w):
    """Weighted least squares with every coefficient ≥ 0 (drop negative ones, refit)."""
    active = list(range(x.shape[1]))
    beta = np.zeros(x.shape[1])
    while active:
        xa = x[:, active]
        a = xa.T @ (w[:, None] * xa)
        b = xa.T @ (w * y)
        sol = np.linalg.solve(a, b)
        if np.all(sol >= 0):
            beta[:] = 0.0
            beta[active] = sol
            cov = np.zeros((x.shape[1], x.shape[1]))
            cov[np.ix_(active, active)] = np.linalg.inv(a)
            return beta, cov
        active.pop(int(np.argmin(sol)))
    return beta, np.zeros((x.shape[1], x.shape[1]))


def fit_temporal(mom, mask, fit_charge_noise: bool = True, min_mean: float = 5.0,
                 min_n: int = 3, regions=None, mismatch_share: float = 0.0,
                 local: bool = False) -> TemporalFit:
    """Fit κ² and, when supported, σ_q² to the pixels of ``mask`` (see module notes).

    Parameters
    ----------
    mom : :class:`spikesim.analysis.capture.IntervalMoments`
    mask : (H, W) bool
        Pixels of stationary rate (dark and flat regions, hot pixels removed).
    min_mean, min_n :
        Pixels used: mean interval ≥ ``min_mean`` readouts (the rounding term
        dominates below) and at least ``min_n`` intervals.
    regions : (H, W) int, optional
        The static region of each pixel of ``mask`` (labels), for the
        threshold-mismatch correction (module notes; ``None``: none).
    mismatch_share : float
        ``ρ = s²/(s² + p²)``, the threshold mismatch's share of the response
        spread (0: no correction).
    local : bool
        Fit the local variance of successive intervals instead of the
        variance (module notes, *moving light*).
    """
    px = _select(mom, mask, min_mean, min_n, regions, mismatch_share, local)
    if px.mean.size == 0:
        raise bad_value("capture length", f"no pixel with >= {min_n} intervals of >= "
                        f"{min_mean:g} readouts", "a longer capture, or flat regions of "
                        f"<= {1 / min_mean:g} spikes per readout, to measure temporal noise")
    keep = _robust_keep(px)
    outliers = 0
    if not keep.all() and keep.sum() >= 3:
        outliers = int((~keep).sum())
        px = px.where(keep)
    fit = dataclasses.replace(_fit(px, fit_charge_noise), outliers=outliers)
    for _ in range(2):  # leave out pixels whose variance the model cannot have, and fit again
        keep = _plausible(px, fit)
        if keep.all() or keep.sum() < 3:
            break
        px = px.where(keep)
        refit = _fit(px, fit_charge_noise)
        fit = dataclasses.replace(refit, outliers=fit.outliers + int((~keep).sum()))
    if fit.outliers:
        fit = dataclasses.replace(fit, reason=fit.reason + (
            f" ({fit.outliers} pixel{'s' if fit.outliers != 1 else ''} whose interval variance "
            f"exceeds the model's {OUTLIER_P:g} quantile left out: moving light or edges)"))
    if fit.sigma_q2 > 0:  # leave out the pixels that fire by diffusion, and fit again
        drifting = px.mean < 1.0 / (DIFFUSION_DRIFT * fit.sigma_q2)
        if not drifting.all() and drifting.sum() >= 3:
            again = _fit(px.where(drifting), fit_charge_noise)
            if again.charge_noise_fitted:
                left = int(px.mean.size - drifting.sum())
                return dataclasses.replace(again, reason=again.reason + (
                    f" ({left} pixel{'s' if left != 1 else ''} whose drift is below "
                    f"{DIFFUSION_DRIFT:g}·σ_q² left out: they fire by diffusion)"))
    return fit


def _robust_keep(px: _Pixels) -> np.ndarray:
    """The pixels plausible under a robust start: per octave of mean interval,
    κ² from the median over its pixels of ``(v_i/c_i − F_i)/m_i²`` (three
    fixed-point rounds of the rounding term ``F``; ``c_i = (1 − 2/(9·(n_i −
    1)))³`` the median of a sample variance over its mean, Wilson–Hilferty),
    then the :data:`OUTLIER_P` test.  A few pixels of moving content, whose
    variance is many times the others', do not move a median, so the test
    finds them (the least-squares fit, which they pull up, makes them look
    plausible when κ² is small); per octave, so that a CV² growing with the
    interval (charge noise) is no outlier."""
    from scipy.stats import chi2

    dof = np.maximum(px.n - 1, 1)
    corr = (1 - 2 / (9 * dof)) ** 3
    octave = np.floor(np.log2(np.maximum(px.mean, 1.0))).astype(int)
    model = np.empty(px.mean.size)
    for o in np.unique(octave):
        at = octave == o
        m, v = px.mean[at], px.var[at]
        k2 = 0.0
        for _ in range(3):
            f = px.where(at).rounding(np.sqrt(k2) * m)
            k2 = max(float(np.median((v / corr[at] - f) / m**2)), 0.0)
        model[at] = k2 * m**2 + px.where(at).rounding(np.sqrt(k2) * m)
    return px.var <= model * chi2.ppf(OUTLIER_P, dof) / dof


def _plausible(px: _Pixels, fit: TemporalFit) -> np.ndarray:
    """Pixels whose sample variance is below the :data:`OUTLIER_P` quantile of
    its law under the fitted model, ``V·χ²(n − 1)/(n − 1)``."""
    from scipy.stats import chi2

    sd = np.sqrt(np.maximum(fit.kappa2 * px.mean**2 + fit.sigma_q2 * px.m3, 0.0))
    model = fit.kappa2 * px.mean**2 + fit.sigma_q2 * px.m3 + px.rounding(sd)
    dof = np.maximum(px.n - 1, 1)
    return px.var <= model * chi2.ppf(OUTLIER_P, dof) / dof


def _fit(px: _Pixels, fit_charge_noise: bool) -> TemporalFit:
    """:func:`fit_temporal` on the pixels ``px``."""
    lo, hi = (float(v) for v in np.percentile(px.mean, [10, 90]))
    k1, _, _, _ = _wls(px, two_terms=False)
    common = dict(n_pixels=int(px.mean.size), n_intervals=int(px.n.sum()),
                  interval_span=(lo, hi))
    if not fit_charge_noise:
        return TemporalFit(k1, 0.0, float("nan"), float("nan"), False,
                           "charge noise not fitted (fit_charge_noise=False)", **common)
    if px.mean.size < 3 or hi < MIN_SPAN * lo:
        return TemporalFit(k1, 0.0, float("nan"), float("nan"), False,
                           f"mean intervals span {lo:.3g}-{hi:.3g} readouts (10th-90th "
                           f"percentile), less than x{MIN_SPAN:g}: no slope of CV² to fit",
                           **common)
    _, c_free, scale, cov = _wls(px, two_terms=True, nonneg=False)
    se = float(np.sqrt(max(cov[1, 1], 0.0) * scale))
    k2, c, _, _ = _wls(px, two_terms=True)
    share = c * hi / k2 if k2 > 0 else float("inf")
    if c_free > 0 and c_free >= MIN_Z * se and c > 0 and share < MIN_SHARE:
        return TemporalFit(k1, 0.0, c_free, se, False,
                           f"charge noise not identified: σ_q² = {c:.3g} ± {se:.2g} is "
                           f"{c_free / se:.3g} standard errors above 0 but would add only "
                           f"{share:.1%} to the interval variance at the longest intervals "
                           f"measured ({hi:.3g} readouts; {MIN_SHARE:.0%} needed): "
                           "charge_noise_electrons kept at its default 0", **common)
    if c_free > 0 and c_free >= MIN_Z * se and c > 0:
        return TemporalFit(k2, c, c, se, True,
                           f"CV² grows with the interval: σ_q² = {c:.3g} ± {se:.2g} "
                           "thresholds² per readout", **common)
    return TemporalFit(k1, 0.0, c_free, se, False, _no_slope_reason(c_free, se), **common)


def _no_slope_reason(c_free: float, se: float) -> str:
    """Why σ_q² is kept at 0: a free estimate ``c_free`` (thresholds² per
    readout, standard error ``se``) at least :data:`MIN_Z` standard errors
    below 0 is a misfit (the model's CV² cannot fall with the interval),
    otherwise the slope is not significant."""
    if c_free < 0 and -c_free >= MIN_Z * se:
        return (f"CV² falls with the interval length (σ_q² = {c_free:.3g} ± {se:.2g}, "
                f"{-c_free / se:.3g} standard errors below 0): a model misfit, the model's CV² "
                "can only grow with the interval (moving content or non-stationary light in "
                "the regions?); charge noise kept at 0")
    return (f"charge noise not identified: CV² slope not significant (σ_q² = {c_free:.3g} ± "
            f"{se:.2g}, needs {MIN_Z:g} standard errors): charge_noise_electrons kept at its "
            "default 0")


@dataclass(frozen=True)
class BinFit:
    """κ² of the pixels whose mean interval lies in ``[lo, hi)`` readouts: its
    estimate, standard error, pixels and intervals."""

    lo: float
    hi: float
    kappa2: float
    se: float
    n_pixels: int
    n_intervals: int


def kappa2_by_bin(mom, mask, local: bool = True, min_pixels: int = 30,
                  min_mean: float = 2.0, min_n: int = 3) -> list[BinFit]:
    """κ² fitted separately over the pixels of ``mask`` in each octave of mean
    interval (2–4, 4–8, … readouts), per-cycle noise only (no charge-noise
    term), from the local variance (``local``) or the variance.  Outliers are
    left out as in :func:`fit_temporal`.  Anything that adds interval variance
    and grows with the interval — moving light, charge noise — raises the
    estimates of the longer bins; the per-cycle noise is the same in all.
    Bins of fewer than ``min_pixels`` pixels are skipped."""
    px = _select(mom, mask, min_mean, min_n, local=local)
    out = []
    if px.mean.size == 0:
        return out
    top = int(np.ceil(np.log2(max(float(px.mean.max()), 2.0)))) + 1
    for k in range(1, top):
        lo, hi = 2.0**k, 2.0 ** (k + 1)
        sel = (px.mean >= lo) & (px.mean < hi)
        if sel.sum() < min_pixels:
            continue
        part = px.where(sel)
        keep = _robust_keep(part)
        if not keep.all() and keep.sum() >= min_pixels:
            part = part.where(keep)
        for _ in range(2):
            k2, _, scale, cov = _wls(part, two_terms=False)
            fit = TemporalFit(k2, 0.0, float("nan"), float("nan"), False, "", 0, 0, (lo, hi))
            keep = _plausible(part, fit)
            if keep.all() or keep.sum() < min_pixels:
                break
            part = part.where(keep)
        k2, _, scale, cov = _wls(part, two_terms=False)
        se = float(np.sqrt(max(cov[0, 0], 0.0) * scale))
        out.append(BinFit(lo, hi, k2, se, int(part.mean.size), int(part.n.sum())))
    return out

