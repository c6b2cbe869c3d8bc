"""Noise models of the spike sensor (docs/model.md).

Two families, each source optional; a source whose parameter is zero (or
``False``) draws no random numbers and adds no work to the kernel.

*Paper mode* — :class:`PaperNoise`, eq. 3 and 5 of Dong et al., "Joint
Demosaicing and Denoising for Spike Camera" (AAAI 2024): in every readout the
latent intensity of each pixel is ``ỹ = y + n``, ``n ~ N(0, σ_g² + σ_p²·y)``,
with y and σ in 8-bit digital numbers (DN, 0..255 for 0..1 radiance) and
negative light clipped at 0.  ``σ_p = 0`` is the Gaussian (GN) case,
``σ_p > 0`` Poisson–Gaussian (GPN).

*Physical mode* — :class:`PhysicalNoise`: per-pixel fixed patterns
(threshold mismatch, photo-response non-uniformity, dark current with spread,
hot pixels) and temporal noise (Poisson photon shot noise on the collected
electrons, drawn per spike by ``spikesim._event``; comparator threshold noise
per firing cycle; optional accumulating charge noise), plus an optional charge
loss at reset.  Default
magnitudes follow published circuit-level figures for spike-camera pixels
(SCSim, Zhao et al. 2024): threshold FPN 4.5 %, PRNU 5.8 %, temporal threshold
noise 0.6 % per comparison, dark current 0.5 % of full scale with 39 %
pixel-to-pixel spread.  ``electrons_per_threshold`` and the hot-pixel figures
are our stated assumptions, not measured values; fit them to a capture.

Fixed patterns are a property of the chip, so they are keyed on ``fpn_seed``
(not on the simulation seed): the same sensor keeps its pattern across runs.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from spikesim import rng
from spikesim._validate import check_real, is_real
from spikesim.errors import bad_value

__all__ = ["PaperNoise", "PhysicalNoise", "noise_from_dict", "FixedPattern", "fixed_pattern",
           "NO_NOISE_PARAMS", "ELECTRONS_PER_THRESHOLD_RANGE"]

#: Accepted ``electrons_per_threshold`` (e⁻), the range the event-driven
#: shot-noise kernel's arithmetic supports with a wide margin (``spikesim._event``):
#:
#: * below: a pixel's electrons ``E·t`` (``t`` ≥ 0.05, the threshold-mismatch
#:   floor of :func:`fixed_pattern`) under 2⁻⁵³ make the modulo reset's
#:   ``lead = need − ⌈need⌉`` round to −1 and ``⌈lead + E⌉`` to −1, an index
#:   outside the kernel's shape tables (a segmentation fault, seen at
#:   ``E`` = 1e-17 and below); and a run's per-readout charge ``λ = q·E·t`` is kept
#:   on a grid of 2⁻³² e⁻ (``CHARGE_GRID``), which at ``E`` = 1e-3 still holds
#:   every pixel at or above the default dark current (q ≥ 0.003) to 0.1 %;
#: * above: the charge of a readout is capped at ``LAMBDA_MAX`` = 2⁶² e⁻
#:   (``spikesim._poisson``), harmless only while that cap is many thresholds
#:   (at 1e9 e⁻ and t ≤ 3.5: over 10⁹ thresholds a readout), and the Poisson
#:   sampler's float64 acceptance test, whose terms grow as ``λ·ln λ``, errs
#:   by about 2e-6 at λ = 1e9.  At 1e20 the cap left a sensor dark where
#:   it should fire 0.3 spikes a readout.
ELECTRONS_PER_THRESHOLD_RANGE = (1e-3, 1e9)
#: The kernel's noise parameters of an ideal sensor (see ``kernel_params``).
NO_NOISE_PARAMS = {"paper_sg2": 0.0, "paper_sp2": 0.0, "paper_only": False, "jitter": 0.0,
                   "loss": 0.0}


class _NoiseBase:
    kind: str = ""

    def to_dict(self) -> dict:
        return {"type": self.kind, **dataclasses.asdict(self)}

    def replace(self, **changes):
        """A copy with some fields changed (validated again)."""
        known = {f.name for f in dataclasses.fields(self)}
        unknown = sorted(set(changes) - known)
        if unknown:
            raise bad_value(f"{type(self).__name__} field", unknown,
                            f"fields among {sorted(known)}")
        return dataclasses.replace(self, **changes)


@dataclass(frozen=True)
class PaperNoise(_NoiseBase):
    """Per-readout Gaussian / Poisson–Gaussian noise on the latent intensity.

    Parameters
    ----------
    sigma_g : float
        Signal-independent standard deviation, 8-bit DN (0..255 scale).
    sigma_p : float
        Signal-dependent coefficient, sqrt(DN): the variance is
        ``sigma_g**2 + sigma_p**2 * y`` with ``y`` in DN.
    """

    sigma_g: float = 0.0
    sigma_p: float = 0.0
    kind = "paper"

    def __post_init__(self):
        object.__setattr__(self, "sigma_g", check_real("sigma_g", self.sigma_g, 0, 255.0))
        object.__setattr__(self, "sigma_p", check_real("sigma_p", self.sigma_p, 0, 255.0))

    @property
    def per_readout(self) -> bool:
        """True when the model draws a random number per pixel and readout."""
        return self.sigma_g > 0 or self.sigma_p > 0

    def kernel_params(self) -> dict:
        """This model's scalar inputs of the kernel: eq. 5 variances in DN²
        (``paper_sg2 = σ_g²``, ``paper_sp2 = σ_p²``), ``paper_only`` (its vector
        fast path applies), no comparator jitter.  Per-pixel inputs come from
        :func:`fixed_pattern`."""
        return {"paper_sg2": self.sigma_g**2, "paper_sp2": self.sigma_p**2, "paper_only": True,
                "jitter": 0.0, "loss": 0.0}

    def variance_dn(self, y_dn):
        """Noise variance (DN²) at latent intensity ``y_dn`` (DN), eq. 5."""
        return self.sigma_g**2 + self.sigma_p**2 * np.asarray(y_dn, dtype=np.float64)


@dataclass(frozen=True)
class PhysicalNoise(_NoiseBase):
    """Circuit-level noise sources of an integrate-and-fire spike pixel.

    Parameters
    ----------
    electrons_per_threshold : float
        Photo-electrons that fill one nominal threshold θ (e⁻), in
        :data:`ELECTRONS_PER_THRESHOLD_RANGE` (1e-3 to 1e9: what the kernel's
        arithmetic supports).  Sets the photon shot noise: the relative noise
        of one firing cycle is ``1/sqrt(electrons_per_threshold)``.
        Assumption (default 1000 e⁻).
    shot_noise : bool
        Draw the collected electrons of each readout from a Poisson law.
    dark_current_rel : float
        Mean dark current as a fraction of the full-scale photo-current
        (radiance-equivalent; 0.005 = 0.5 %).
    dark_current_spread : float
        Pixel-to-pixel relative standard deviation of the dark current
        (log-normal with mean 1, coefficient of variation = this value).
    threshold_mismatch : float
        Relative standard deviation of each pixel's threshold (fixed pattern).
    prnu : float
        Photo-response non-uniformity: relative standard deviation of each
        pixel's gain (fixed pattern).
    temporal_threshold_noise : float
        Relative standard deviation of the threshold, drawn anew for every
        firing cycle (comparator noise).
    hot_pixel_fraction : float
        Fraction of pixels that are hot (0..1).
    hot_pixel_dark_rel : float
        Extra dark current of a hot pixel, as a fraction of full scale.
    charge_noise_electrons : float
        Standard deviation (e⁻) of a Gaussian charge added to every readout's
        integrated charge, independent between readouts (temporal noise that
        accumulates with integration time, e.g. leakage and reset noise): over
        a cycle of ``m`` readouts it adds ``m·σ²`` to the charge variance, so
        the interval CV grows with the interval length,
        ``CV² = κ² + m·(σ/E)²`` (:mod:`spikesim.analysis.theory`).  The
        accumulator may dip below the reset level.  Default 0 (off).  With
        shot noise on, this source makes the simulator draw the shot noise per
        readout instead of per spike (slower; same law).
    reset_charge_loss : float
        Fraction in [0, 1) of the charge collected in the readout right after
        each firing (reset) that is lost (SCSim models a retention of 0.998,
        i.e. 0.002).  The mean charge of that readout is scaled by ``1 − f``
        before shot noise (a thinned Poisson count is Poisson); noise free the
        rate becomes ``q/(1 + f·q)`` and the mean interval ``1/q + f`` readouts
        (:mod:`spikesim.analysis.theory`).  Default 0 (off).
    fpn_seed : int
        Seed of the chip's fixed patterns (independent of the simulation seed).
    """

    electrons_per_threshold: float = 1000.0
    shot_noise: bool = True
    dark_current_rel: float = 0.005
    dark_current_spread: float = 0.39
    threshold_mismatch: float = 0.045
    prnu: float = 0.058
    temporal_threshold_noise: float = 0.006
    hot_pixel_fraction: float = 1e-4
    hot_pixel_dark_rel: float = 0.2
    fpn_seed: int = 0
    charge_noise_electrons: float = 0.0
    reset_charge_loss: float = 0.0
    kind = "physical"

    def __post_init__(self):
        e = self.electrons_per_threshold
        lo, hi = ELECTRONS_PER_THRESHOLD_RANGE
        if not (is_real(e) and math.isfinite(float(e)) and lo <= float(e) <= hi):
            raise bad_value("electrons_per_threshold", e,
                            f"a number of electrons in [{lo:g}, {hi:g}] (the range the "
                            "shot-noise kernel's arithmetic supports)")
        object.__setattr__(self, "electrons_per_threshold", float(e))
        if not isinstance(self.shot_noise, (bool, np.bool_)):
            raise bad_value("shot_noise", self.shot_noise, "True or False")
        object.__setattr__(self, "shot_noise", bool(self.shot_noise))
        for name, upper in (
            ("dark_current_rel", 1e6),
            ("dark_current_spread", 10.0),
            ("threshold_mismatch", 0.3),
            ("prnu", 0.3),
            ("temporal_threshold_noise", 0.1),
            ("hot_pixel_fraction", 1.0),
            ("hot_pixel_dark_rel", 1e6),
            ("charge_noise_electrons", 1e9),
        ):
            object.__setattr__(self, name, check_real(name, getattr(self, name), 0, upper))
        loss = self.reset_charge_loss
        if not (is_real(loss) and math.isfinite(float(loss)) and 0.0 <= float(loss) < 1.0):
            raise bad_value("reset_charge_loss", loss,
                            "a fraction in [0, 1) of the next readout's charge (0.002 for 0.998 "
                            "retention)")
        object.__setattr__(self, "reset_charge_loss", float(loss))
        if not isinstance(self.fpn_seed, (int, np.integer)) or self.fpn_seed < 0:
            raise bad_value("fpn_seed", self.fpn_seed, "a non-negative integer")
        object.__setattr__(self, "fpn_seed", int(self.fpn_seed))

    @property
    def per_readout(self) -> bool:
        """True when the model needs the clocked, stateful kernel path: temporal
        noise (shot, threshold, charge) or charge loss at reset."""
        return (self.shot_noise or self.temporal_threshold_noise > 0
                or self.charge_noise_electrons > 0 or self.reset_charge_loss > 0)

    @property
    def event_driven(self) -> bool:
        """True when the kernel draws the shot noise per spike (spikesim._event):
        shot noise on and no per-readout charge noise."""
        return self.shot_noise and self.charge_noise_electrons == 0

    def kernel_params(self) -> dict:
        """This model's scalar inputs of the kernel: ``jitter`` = σ_t (relative
        threshold s.d. per firing cycle), ``loss`` the charge loss at reset;
        no paper-mode terms.  Shot noise and charge noise are per pixel
        (:func:`fixed_pattern`)."""
        return {"paper_sg2": 0.0, "paper_sp2": 0.0, "paper_only": False,
                "jitter": self.temporal_threshold_noise, "loss": self.reset_charge_loss}

    @property
    def has_fixed_pattern(self) -> bool:
        return (
            self.threshold_mismatch > 0
            or self.prnu > 0
            or self.dark_current_rel > 0
            or (self.hot_pixel_fraction > 0 and self.hot_pixel_dark_rel > 0)
        )


def noise_from_dict(d: dict | None):
    """Rebuild a noise model from ``to_dict()`` output (``None`` → no noise)."""
    if d is None:
        return None
    if not isinstance(d, dict) or "type" not in d:
        raise bad_value("noise", d, "None or a dict with a 'type' key ('paper' or 'physical')")
    params = {k: v for k, v in d.items() if k != "type"}
    classes = {"paper": PaperNoise, "physical": PhysicalNoise}
    cls = classes.get(d["type"])
    if cls is None:
        raise bad_value("noise.type", d["type"], f"one of {sorted(classes)}")
    known = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(params) - known)
    if unknown:
        raise bad_value(f"noise ({d['type']}) keys", unknown, f"keys among {sorted(known)}")
    return cls(**params)


@dataclass(frozen=True)
class FixedPattern:
    """Per-pixel constants of the charge model, in units of the pixel's own threshold.

    The deterministic charge of one readout is ``gain · Ī + offset`` thresholds,
    where ``Ī`` is the mean radiance of the readout (relative units).
    ``electrons`` is the number of electrons in the pixel's threshold (for
    shot noise), or ``None`` when shot noise is off; ``charge_sd`` the s.d.
    of the per-readout charge noise in the pixel's thresholds, or ``None``.
    """

    gain: np.ndarray  # (H, W) float64, thresholds per readout at radiance 1
    offset: np.ndarray  # (H, W) float64, thresholds per readout (dark current)
    electrons: np.ndarray | None  # (H, W) float64 e⁻ per threshold
    charge_sd: np.ndarray | None = None  # (H, W) float64 thresholds per readout


def fixed_pattern(noise, height: int, width: int, full_scale_rate: float) -> FixedPattern:
    """Draw the chip's fixed patterns (or uniform constants for an ideal sensor).

    With threshold θ_i = θ·t_i, gain g_i and dark current d_i (radiance
    equivalent), the charge per readout in units of θ_i is
    ``r·(g_i·Ī + d_i)/t_i`` with r = ``full_scale_rate``.
    """
    shape = (height, width)
    r = float(full_scale_rate)
    if not isinstance(noise, PhysicalNoise):
        return FixedPattern(np.full(shape, r), np.zeros(shape), None)
    n_pix = height * width
    seed = noise.fpn_seed
    t_rel = np.ones(n_pix)
    if noise.threshold_mismatch > 0:
        z = rng.pixel_normals(rng.stream_key(seed, rng.STREAM_FPN_THRESHOLD), n_pix)
        t_rel = np.maximum(1.0 + noise.threshold_mismatch * z, 0.05)
    g = np.ones(n_pix)
    if noise.prnu > 0:
        z = rng.pixel_normals(rng.stream_key(seed, rng.STREAM_FPN_GAIN), n_pix)
        g = np.maximum(1.0 + noise.prnu * z, 0.0)
    dark = np.zeros(n_pix)
    if noise.dark_current_rel > 0:
        dark = np.full(n_pix, noise.dark_current_rel)
        if noise.dark_current_spread > 0:
            s2 = math.log1p(noise.dark_current_spread**2)
            z = rng.pixel_normals(rng.stream_key(seed, rng.STREAM_FPN_DARK), n_pix)
            dark = dark * np.exp(-0.5 * s2 + math.sqrt(s2) * z)
    if noise.hot_pixel_fraction > 0 and noise.hot_pixel_dark_rel > 0:
        u = rng.pixel_uniforms(rng.stream_key(seed, rng.STREAM_FPN_HOT), n_pix)
        dark = dark + np.where(u < noise.hot_pixel_fraction, noise.hot_pixel_dark_rel, 0.0)
    gain = (r * g / t_rel).reshape(shape)
    offset = (r * dark / t_rel).reshape(shape)
    electrons = (noise.electrons_per_threshold * t_rel).reshape(shape) if noise.shot_noise else None
    charge_sd = None
    if noise.charge_noise_electrons > 0:
        charge_sd = (noise.charge_noise_electrons
                     / (noise.electrons_per_threshold * t_rel)).reshape(shape)
    return FixedPattern(gain, offset, electrons, charge_sd)
