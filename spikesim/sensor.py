"""Sensor configuration: geometry, clock, integrate-and-fire parameters, noise.

The physics these parameters feed is in ``spikesim/_kernels.py`` and
docs/model.md.  A pixel integrates ``A(t) = ∫ η I dτ`` and fires when ``A``
reaches the threshold θ (Dong et al., AAAI 2024, eq. 1); the sensor checks
every pixel once per readout period ``1/clock_hz`` and emits one bit.

Units: radiance is linear light in relative units (1 = full scale);
``full_scale_rate`` is the expected number of spikes per readout at radiance 1,
so the charge per readout at radiance I is ``full_scale_rate · I · θ``.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass

from spikesim._validate import check_int, check_real
from spikesim.cfa import normalize_cfa
from spikesim.errors import bad_value
from spikesim.noise import PaperNoise, PhysicalNoise, noise_from_dict

__all__ = ["Sensor", "RESET_MODES", "INIT_MODES", "list_presets"]

RESET_MODES = ("modulo", "subtract", "zero")
INIT_MODES = ("uniform", "zero")
MAX_SIDE = 1 << 16


@dataclass(frozen=True)
class Sensor:
    """A spike sensor, optionally with a Bayer colour filter.

    Parameters
    ----------
    height, width : int
        Pixels; row 0 is the top of the image.
    cfa : str or None
        Bayer pattern ``"RGGB"``, ``"BGGR"``, ``"GRBG"``, ``"GBRG"``, or
        ``None``/``"mono"`` for a monochrome sensor (which sees Rec. 709
        luminance).
    clock_hz : float
        Readout clock (Hz); one bit per pixel every ``1/clock_hz`` seconds.
    threshold : float
        Firing threshold θ in charge units; the charge per readout is
        ``full_scale_rate · I · θ``, so θ only sets the unit of charge.
    full_scale_rate : float
        Expected spikes per readout at radiance 1 (e.g. 0.6 as in the REDS
        spike data of Spk2ImgNet / Spike-Zoo).
    reset : {"modulo", "subtract", "zero"}
        What firing does to the accumulator: keep the excess modulo θ
        (eq. 1; bounded under any light), subtract θ once (the excess of
        saturating light accumulates without bound), or reset to zero.
    init : {"uniform", "zero"}
        Initial accumulator: uniform in [0, θ) drawn from the seed, or zero.
    noise : PaperNoise, PhysicalNoise or None
        Noise model (``spikesim.noise``); ``None`` is an ideal sensor.
    """

    height: int = 256
    width: int = 256
    cfa: str | None = "RGGB"
    clock_hz: float = 20_000.0
    threshold: float = 1.0
    full_scale_rate: float = 0.6
    reset: str = "modulo"
    init: str = "uniform"
    noise: PaperNoise | PhysicalNoise | None = None

    def __post_init__(self):
        set_ = object.__setattr__
        set_(self, "height", check_int("height", self.height, 1, MAX_SIDE, "pixels"))
        set_(self, "width", check_int("width", self.width, 1, MAX_SIDE, "pixels"))
        set_(self, "cfa", normalize_cfa(self.cfa))
        for name, unit in (("clock_hz", "Hz"), ("threshold", "charge units"),
                           ("full_scale_rate", "spikes per readout at radiance 1")):
            set_(self, name, check_real(name, getattr(self, name), 0, low_open=True, unit=unit))
        if self.reset not in RESET_MODES:
            raise bad_value("reset", self.reset, f"one of {RESET_MODES}")
        if self.init not in INIT_MODES:
            raise bad_value("init", self.init, f"one of {INIT_MODES}")
        if isinstance(self.noise, dict):
            set_(self, "noise", noise_from_dict(self.noise))
        if self.noise is not None and not isinstance(self.noise, (PaperNoise, PhysicalNoise)):
            raise bad_value("noise", self.noise, "None, PaperNoise(...) or PhysicalNoise(...)")

    # --- derived ---------------------------------------------------------
    @property
    def shape(self) -> tuple[int, int]:
        return (self.height, self.width)

    @property
    def readout_period_s(self) -> float:
        return 1.0 / self.clock_hz

    @property
    def is_color(self) -> bool:
        return self.cfa is not None

    # --- serialisation ---------------------------------------------------
    def to_dict(self) -> dict:
        d = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        d["noise"] = None if self.noise is None else self.noise.to_dict()
        return d

    @classmethod
    def from_dict(cls, d: dict) -> Sensor:
        if not isinstance(d, dict):
            raise bad_value("sensor", d, "a dict of Sensor fields")
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise bad_value("sensor keys", unknown, f"keys among {sorted(known)}")
        d = dict(d)
        if "noise" in d:
            d["noise"] = noise_from_dict(d["noise"])
        return cls(**d)

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> Sensor:
        try:
            d = json.loads(text)
        except json.JSONDecodeError as exc:
            raise bad_value("sensor JSON", text[:60], f"valid JSON ({exc.msg})") from None
        return cls.from_dict(d)

    def replace(self, **changes) -> Sensor:
        """A copy with some fields changed (validated again)."""
        known = {f.name for f in dataclasses.fields(self)}
        unknown = sorted(set(changes) - known)
        if unknown:
            raise bad_value("sensor override", unknown, f"fields among {sorted(known)}")
        return dataclasses.replace(self, **changes)

    # --- presets ---------------------------------------------------------
    @classmethod
    def preset(cls, name: str, **overrides) -> Sensor:
        """A named sensor configuration, optionally with fields overridden.

        Examples
        --------
        >>> import spikesim as ss
        >>> sensor = ss.Sensor.preset("color-1000x1000-20k", height=256, width=256)
        >>> sensor.cfa, sensor.height, sensor.clock_hz
        ('RGGB', 256, 20000.0)
        >>> "sjdd-gn" in ss.list_presets()
        True
        """
        if name not in _PRESETS:
            raise bad_value("preset", name, f"one of {sorted(_PRESETS)}")
        return _PRESETS[name][1].replace(**overrides)


_PRESETS: dict[str, tuple[str, Sensor]] = {
    "vidar-400x250-40k": (
        "monochrome 400x250 Vidar-class spike camera at 40 kHz, ideal (as the REDS spike data)",
        Sensor(height=250, width=400, cfa=None, clock_hz=40_000.0),
    ),
    "vidar-400x250-20k": (
        "monochrome 400x250 Vidar-class spike camera at 20 kHz, ideal",
        Sensor(height=250, width=400, cfa=None, clock_hz=20_000.0),
    ),
    "color-1000x1000-20k": (
        "RGGB Bayer 1000x1000 spike camera at 20 kHz, ideal",
        Sensor(height=1000, width=1000, cfa="RGGB", clock_hz=20_000.0),
    ),
    "ideal": (
        "RGGB 256x256 at 20 kHz, no noise (quantization only)",
        Sensor(),
    ),
    "sjdd-gn": (
        "RGGB 256x256, paper-mode Gaussian noise sigma_g=10 DN (mid-range of SJDD-Net's U(0,15))",
        Sensor(noise=PaperNoise(sigma_g=10.0, sigma_p=0.0)),
    ),
    "sjdd-gpn": (
        "RGGB 256x256, paper-mode Poisson-Gaussian noise sigma_g=2.5 DN, sigma_p=2.5 "
        "(mid-range of SJDD-Net's U(0,5))",
        Sensor(noise=PaperNoise(sigma_g=2.5, sigma_p=2.5)),
    ),
    "physical": (
        "RGGB 256x256 at 20 kHz with physical noise (SCSim-derived defaults)",
        Sensor(noise=PhysicalNoise()),
    ),
}


def list_presets() -> dict[str, str]:
    """Names of the sensor presets with a one-line description each."""
    return {name: desc for name, (desc, _) in _PRESETS.items()}
