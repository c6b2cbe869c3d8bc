"""Colour planes of a Bayer capture, and the test that a capture called mono is colour.

A Bayer sensor samples one colour per pixel (:mod:`spikesim.cfa`); its four
2 × 2 phases ``R, G1, G2, B`` (G1 the green on the red row) are four
half-resolution images of different colours.  Calibration works plane by
plane: a flat patch of a colour scene is uniform within each plane, not
across them, so the spread of a region's rates across planes is the scene's
colour, not the chip's fixed pattern.  A monochrome capture is one plane.

:func:`colour_evidence` tests whether a capture whose colour filter is not
known looks like a colour capture.  Its statistic is the period-2 structure
that a colour filter leaves: at each pixel the error of predicting it from its
two neighbours one pixel away (the other colour on a Bayer sensor) is compared
with the error of predicting it from its two neighbours two pixels away (the
same colour), horizontally and vertically::

    a = x − (x[−1] + x[+1])/2,    b = x − (x[−2] + x[+2])/2,    d = a² − b²

On a monochrome sensor ``E[d] ≤ 0`` (pixel-independent noise gives equal
variances, ``1.5·σ²`` each; smooth scenes make the nearer neighbours the
better predictors); behind a colour filter ``a`` also holds the colour
difference between neighbours, of either sign, so ``E[d] > 0`` wherever the
scene is coloured.  The capture is called colour when the mean of ``d`` is
more than :data:`COLOUR_Z` standard errors above 0 (standard error from 8 × 8
tiles, so neighbouring pixels' shared noise is counted) *and* the mean
``a²`` exceeds the mean ``b²`` by :data:`COLOUR_EXCESS` (a large capture
makes a tiny period-2 effect significant; it must also be large).  A colour
sensor viewing a grey scene passes as monochrome: all its planes then see the
same radiance, and the monochrome calibration of it is right.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from spikesim.cfa import mask_planes, normalize_cfa
from spikesim.errors import SpikeSimValueError

__all__ = ["Plane", "planes_of", "colour_evidence", "refuse_colour_as_mono", "PLANE_NAMES",
           "COLOUR_Z", "COLOUR_EXCESS"]

#: Plane names of a Bayer capture, in SJDD-Net's mask order.
PLANE_NAMES = ("R", "G1", "G2", "B")
#: Least significance (standard errors) of the period-2 structure for a colour verdict.
COLOUR_Z = 6.0
#: Least relative excess of the nearer-neighbour error for a colour verdict (20 %).
COLOUR_EXCESS = 0.2
#: Tile side (pixels) of the standard error of the period-2 statistic.
_TILE = 8


@dataclass(frozen=True)
class Plane:
    """One colour plane: ``name`` and the row/column slices of its pixels."""

    name: str
    rows: slice
    cols: slice

    def sub(self, a: np.ndarray) -> np.ndarray:
        """The plane's pixels of an ``(..., H, W)`` array, as ``(..., h, w)``."""
        return a[..., self.rows, self.cols]

    def full(self, sub_mask: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
        """An (H, W) bool mask from a mask over the plane's pixels."""
        m = np.zeros(shape, bool)
        m[self.rows, self.cols] = sub_mask
        return m

    def mask(self, shape: tuple[int, int]) -> np.ndarray:
        """(H, W) bool: the plane's pixels."""
        m = np.zeros(shape, bool)
        m[self.rows, self.cols] = True
        return m


def planes_of(cfa: str | None, height: int, width: int) -> list[Plane]:
    """The colour planes of a sensor: one ``mono`` plane, or ``R, G1, G2, B``."""
    cfa = normalize_cfa(cfa)
    if cfa is None:
        return [Plane("mono", slice(None), slice(None))]
    tile = mask_planes(cfa, 2, 2)
    out = []
    for k, name in enumerate(PLANE_NAMES):
        r, c = (int(v[0]) for v in np.nonzero(tile[k]))
        out.append(Plane(name, slice(r, height, 2), slice(c, width, 2)))
    return out


def _mean_se(d: np.ndarray) -> tuple[float, float]:
    """Mean of the (h, w) map ``d`` and its standard error from tile means."""
    h, w = d.shape
    th, tw = h // _TILE, w // _TILE
    if th * tw < 4:
        return float(d.mean()), float(d.std() / np.sqrt(max(d.size, 1)) * 4)
    tiles = d[: th * _TILE, : tw * _TILE].reshape(th, _TILE, tw, _TILE).mean(axis=(1, 3))
    return float(d.mean()), float(tiles.std(ddof=1) / np.sqrt(tiles.size))


def colour_evidence(rate: np.ndarray) -> dict:
    """The period-2 statistic of an (H, W) rate map (spikes per readout; module notes).

    Returns ``z`` (mean of ``d`` over its standard error), ``excess`` (mean
    ``a²`` over mean ``b²``, minus 1), ``phase_means`` (mean rate of the
    2 × 2 phases, row by row) and ``colour`` (the verdict).
    """
    x = np.asarray(rate, np.float64)
    h, w = x.shape
    phases = [float(x[r::2, c::2].mean()) for r in (0, 1) for c in (0, 1)] if h >= 2 and w >= 2 \
        else [float(x.mean())] * 4
    out = {"z": 0.0, "excess": 0.0, "phase_means": phases, "colour": False}
    if h < 5 or w < 5:
        return out
    ah = x[:, 2:-2] - (x[:, 1:-3] + x[:, 3:-1]) / 2
    bh = x[:, 2:-2] - (x[:, :-4] + x[:, 4:]) / 2
    av = x[2:-2, :] - (x[1:-3, :] + x[3:-1, :]) / 2
    bv = x[2:-2, :] - (x[:-4, :] + x[4:, :]) / 2
    a2 = (ah[2:-2, :] ** 2 + av[:, 2:-2] ** 2) / 2
    b2 = (bh[2:-2, :] ** 2 + bv[:, 2:-2] ** 2) / 2
    mean, se = _mean_se(a2 - b2)
    mb = float(b2.mean())
    z = mean / se if se > 0 else (np.inf if mean > 0 else 0.0)
    excess = float(a2.mean()) / mb - 1 if mb > 0 else (np.inf if a2.mean() > 0 else 0.0)
    out.update(z=float(z), excess=float(excess),
               colour=bool(z > COLOUR_Z and excess > COLOUR_EXCESS))
    return out


def refuse_colour_as_mono(rate: np.ndarray, cfa_option: str = "cfa") -> dict:
    """Raise when a capture of unknown colour filter looks like colour (module
    notes); errors name the option ``cfa_option``.  Returns the evidence."""
    ev = colour_evidence(rate)
    if ev["colour"]:
        phases = ", ".join(f"{v:.3g}" for v in ev["phase_means"])
        raise SpikeSimValueError(
            "the capture looks like a colour (Bayer) capture: neighbouring pixels differ "
            f"{1 + ev['excess']:.3g}x more (mean square) than pixels two apart ({ev['z']:.3g} "
            f"standard errors), its 2x2 phases average {phases} spikes per readout; calibrated "
            "as monochrome, the colour filter would be read as PRNU: pass its pattern, "
            f"{cfa_option}=RGGB, BGGR, GRBG or GBRG (or {cfa_option}=mono if it is monochrome)")
    return ev
