"""Synthetic natural captures: a bundled photograph panning, with or without a flat sky band.

Public real spike captures are natural scenes of a few hundred readouts, dim
(about 0.03 spikes per readout on average) or bright, with moving content and
at best a patch of sky.  :func:`natural_capture` simulates such a capture
from a chip whose parameters are known, so that calibration can be checked
against the truth: a bundled picture (:func:`spikesim.scenes.procedural`)
panning sideways, exposed so that the capture's mean rate is ``mean_rate``
spikes per readout, optionally under a static band of sky across its top
quarter (radiance ``sky_level`` of the picture's mean, blue-grey on a colour
sensor): uniform (a flat region) or falling to half from top to bottom, as
real skies do (smooth and static, but no flat region).  :data:`NATURAL_CHIPS`
holds chips away from the package defaults.
"""

from __future__ import annotations

import numpy as np

import spikesim as ss
from spikesim._validate import is_int, is_real
from spikesim.errors import bad_value
from spikesim.scenes.base import Scene

__all__ = ["natural_capture", "NaturalScene", "NATURAL_CHIPS", "SKY_RGB", "SKIES"]

#: Chips away from the package defaults: name -> PhysicalNoise keywords.
NATURAL_CHIPS = {
    "prnu 8 %, E = 400, dark 1.5 %": dict(
        prnu=0.08, threshold_mismatch=0.045, electrons_per_threshold=400.0,
        dark_current_rel=0.015, dark_current_spread=0.3, fpn_seed=5),
    "prnu 3 %, E = 3000": dict(
        prnu=0.03, threshold_mismatch=0.02, electrons_per_threshold=3000.0,
        dark_current_rel=0.002, fpn_seed=8),
}
#: Colour of the sky band (linear RGB, relative; grey on a monochrome sensor).
SKY_RGB = (0.62, 0.8, 1.0)


class NaturalScene(Scene):
    """``picture`` (a :class:`~spikesim.scenes.procedural` picture scene) with its
    radiance scaled by ``gain`` and, when ``sky_rows`` > 0, its top rows replaced
    by a static band of radiance ``sky`` (an RGB triple) times ``1 − fall·y``,
    ``y`` going from 0 at the top row to 1 at the band's last row (``fall = 0``:
    uniform)."""

    def __init__(self, picture, gain: float, sky_rows: int = 0, sky=(0.0, 0.0, 0.0),
                 fall: float = 0.0):
        self.picture = picture
        self.height, self.width = picture.height, picture.width
        self.key_interval_s = picture.key_interval_s
        self.gain = float(gain)
        self.sky_rows = int(sky_rows)
        self.fall = float(fall)
        y = np.linspace(0.0, 1.0, max(self.sky_rows, 1))[:, None, None]
        self.sky = (np.asarray(sky, np.float32) * (1 - self.fall * y)).astype(np.float32)

    def key_times(self, start_s: float, stop_s: float) -> np.ndarray:
        return self.picture.key_times(start_s, stop_s)

    def radiance(self, t: float) -> np.ndarray:
        img = np.asarray(self.picture.radiance(t), np.float32) * np.float32(self.gain)
        if self.sky_rows:
            img[: self.sky_rows] = self.sky
        return img

    def describe(self) -> dict:
        return {"kind": "natural", "picture": self.picture.describe(), "gain": self.gain,
                "sky_rows": self.sky_rows, "sky": self.sky[0, 0].tolist(), "fall": self.fall}


#: Sky kinds of :func:`natural_capture`: how much the band's radiance falls from top
#: to bottom (``None``: no sky).
SKIES = {"flat": 0.0, "gradient": 0.5, None: None}


def natural_capture(noise_kw: dict, *, cfa: str | None = None, mean_rate: float = 0.03,
                    n_readouts: int = 200, size=(96, 96), sky: str | None = "flat",
                    picture: str = "coffee", shift_px: float = 16.0,
                    full_scale_rate: float = 0.6, sky_level: float = 1.5, seed: int = 0):
    """Simulate a natural capture of a chip of known parameters (module notes).

    Parameters
    ----------
    noise_kw : dict
        :class:`spikesim.noise.PhysicalNoise` keywords of the chip.
    cfa : str or None
        Bayer pattern, or None for monochrome.
    mean_rate : float
        Mean firing rate of the capture, spikes per readout (e.g. 0.03 dim, 0.2
        bright), dark current included (at least twice the chip's dark rate).
    n_readouts : int
    size : (H, W)
    sky : {"flat", "gradient", None}
        A static sky band over the top quarter of the frame, uniform (a flat
        region) or falling to half its radiance from top to bottom (smooth and
        static, but no flat region), or none.
    picture : str
        A bundled picture (:func:`spikesim.scenes.procedural.list_scenes`).
    shift_px : float
        How far the picture pans over the capture, pixels.
    sky_level : float
        The sky's radiance relative to the picture's mean (its brightest channel).

    Returns ``(stream, sky_mask, truth)``: the stream, the (H, W) bool mask of
    the sky band (all False without one) and the true :class:`spikesim.Sensor`.
    """
    if sky not in SKIES:
        raise bad_value("sky", sky, f"one of {list(SKIES)}")
    h, w = size
    if not (is_int(h) and is_int(w)) or h < 16 or w < 16:
        raise bad_value("size", size, "at least 16 × 16 pixels")
    if not (is_real(mean_rate) and 0 < mean_rate < 0.9):
        raise bad_value("mean_rate", mean_rate, "a rate in (0, 0.9) spikes per readout")
    sensor = ss.Sensor(height=h, width=w, cfa=cfa, full_scale_rate=full_scale_rate,
                       noise=ss.noise.PhysicalNoise(**noise_kw))
    speed = shift_px * sensor.clock_hz / n_readouts
    pic = ss.scenes.procedural(picture, motion="pan", size=(h, w), speed=speed)
    first = np.asarray(pic.radiance(0.0), np.float64)
    sky_rows = h // 4 if sky else 0
    fall = SKIES[sky] or 0.0
    sky_rgb = np.asarray(SKY_RGB) * sky_level * float(first.mean())
    scene = NaturalScene(pic, 1.0, sky_rows, sky_rgb, fall)
    seen = ss.cfa.mosaic(np.asarray(scene.radiance(0.0), np.float32), sensor.cfa)
    noise = sensor.noise
    dark = full_scale_rate * (1 + noise.threshold_mismatch**2) * (
        noise.dark_current_rel + noise.hot_pixel_fraction * noise.hot_pixel_dark_rel)
    if mean_rate <= 2 * dark:
        raise bad_value("mean_rate", mean_rate, f"more than twice the chip's dark rate "
                        f"{dark:.3g} spikes per readout")
    gain = (mean_rate - dark) / (full_scale_rate * (1 + noise.threshold_mismatch**2)
                                 * float(np.mean(seen)))
    scene = NaturalScene(pic, gain, sky_rows, sky_rgb * gain, fall)
    stream = ss.simulate(scene, sensor, n_readouts, seed=seed)
    mask = np.zeros((h, w), bool)
    mask[:sky_rows] = True
    return stream, mask, sensor
