"""Viewable images of a spike stream: TFP/TFI estimate, demosaiced, sRGB-encoded.

The estimate is linear light in scene units (``spikesim.estimate``); a Bayer
stream is demosaiced with Malvar, He & Cutler (2004) through
colour-demosaicing; the result is clipped to [0, 1], sRGB-encoded
(IEC 61966-2-1) for viewing and quantised to 8 bits.  A monochrome stream
gives a grey image.
"""

from __future__ import annotations

import numpy as np

from spikesim import estimate
from spikesim.errors import bad_value
from spikesim.srgb import linear_to_srgb8

__all__ = ["METHODS", "estimate_image", "render", "render_frames", "save_image"]

METHODS = ("tfp", "tfi")


def _rate_of(source) -> float:
    sensor = (getattr(source, "meta", None) or {}).get("sensor") or {}
    rate = sensor.get("full_scale_rate") if isinstance(sensor, dict) else None
    return float(rate) if rate else 0.6


def estimate_image(source, readout: int, method: str = "tfp", window: int = 41,
                   rate: float | None = None) -> np.ndarray:
    """(H, W, 3) linear-light image at ``readout`` from a Sequence or DatFile.

    Only the readouts the estimator needs are read.  ``rate`` defaults to the
    sensor's ``full_scale_rate`` recorded in the file (0.6 for a ``.dat``).
    """
    if method not in METHODS:
        raise bad_value("method", method, f"one of {METHODS}")
    n = source.n_readouts
    if isinstance(readout, bool) or not isinstance(readout, (int, np.integer)) \
            or not 0 <= readout < n:
        raise bad_value("readout", readout, f"a readout index in [0, {n - 1}]")
    rate = _rate_of(source) if rate is None else rate
    start, stop = estimate.window_bounds(n, int(readout), min(int(window), n))
    spikes = source.read_window(start, stop - start)
    center = int(readout) - start
    if method == "tfp":
        img = estimate.tfp(spikes, center, window=stop - start, rate=rate)
    else:
        img = estimate.tfi(spikes, center, rate=rate)
    cfa = getattr(source, "cfa", None)
    if cfa is None:
        return np.repeat(img[..., None], 3, axis=2)
    if min(img.shape) < 2:
        raise bad_value("height/width", img.shape, "at least 2x2 pixels to demosaic")
    from colour_demosaicing import demosaicing_CFA_Bayer_Malvar2004

    return np.asarray(demosaicing_CFA_Bayer_Malvar2004(img, cfa), np.float64)


def render(source, readout: int, method: str = "tfp", window: int = 41,
           rate: float | None = None) -> np.ndarray:
    """(H, W, 3) uint8 sRGB-encoded preview at ``readout``."""
    lin = estimate_image(source, readout, method, window, rate)
    return linear_to_srgb8(lin)


def render_frames(source, readouts, method: str = "tfp", window: int = 41,
                  rate: float | None = None, progress: bool = False) -> list[np.ndarray]:
    """Previews at each of ``readouts`` (for an animation), with a progress bar."""
    from tqdm.auto import tqdm

    readouts = list(readouts)
    return [render(source, int(r), method, window, rate)
            for r in tqdm(readouts, disable=not progress, desc="preview", unit="frame")]


def save_image(path, frames: list[np.ndarray], fps: float = 10.0) -> None:
    """Write one frame as PNG, or several as an animated GIF (by the file suffix)."""
    from PIL import Image

    from spikesim.io.atomic import atomic_path

    suffix = str(path).lower().rsplit(".", 1)[-1]
    if suffix not in ("png", "gif"):
        raise bad_value("out", str(path), "a file name ending in .png or .gif")
    if not frames:
        raise bad_value("frames", 0, "at least one frame")
    images = [Image.fromarray(f) for f in frames]
    with atomic_path(path) as tmp:
        if suffix == "png":
            images[0].save(tmp, format="PNG")
        else:
            images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:],
                           duration=max(1, round(1000 / fps)), loop=0)
