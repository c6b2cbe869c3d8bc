"""Dark and flat regions of a capture: validation of user masks and automatic detection.

A *region* is a boolean (H, W) mask.  Users pass a dark mask and flat masks
(a list of boolean masks, or one integer label image with 0 = no region and
k = flat region k); :func:`check_regions` validates shapes, emptiness and
overlap.  :func:`detect_regions` finds them from the per-pixel firing-rate
map when no mask is given:

1. the rate map is median filtered (5 × 5), which removes the fixed pattern
   and hot pixels but keeps region edges;
2. the filtered values are clustered in one dimension: sorted, a new cluster
   starts wherever consecutive values differ by more than
   ``tol·value + 3/T`` (three counts over the capture);
3. each cluster is split into connected components, eroded by two pixels
   (the filter radius: edges mix two levels), and kept when it holds at least ``min_pixels``
   pixels and, unless dark, its filtered values spread by at most ``tol``
   (relative inter-quartile range; a ramp forms one wide cluster and is
   rejected);
4. components whose median rate is at most ``dark_rate`` spikes per readout
   form the dark mask; the others are flat regions, ordered by rate; regions
   within 2 % of one spike per readout are saturated and dropped.
"""

from __future__ import annotations

import numpy as np

from spikesim.errors import SpikeSimTypeError, bad_value

__all__ = ["check_regions", "detect_regions", "as_mask"]


def as_mask(mask, shape: tuple[int, int], name: str) -> np.ndarray:
    """Validate one (H, W) mask (bool or 0/1) and return it as bool."""
    arr = np.asarray(mask)
    if arr.dtype != np.bool_ and arr.dtype.kind not in "iu":
        raise SpikeSimTypeError(f"{name} must be a boolean (H, W) mask, got dtype {arr.dtype}")
    if arr.shape != tuple(shape):
        raise bad_value(f"{name}.shape", arr.shape, f"the capture's (H, W) = {tuple(shape)}")
    return arr.astype(bool)


def check_regions(dark_mask, flat_masks, shape) -> tuple[np.ndarray | None, list[np.ndarray]]:
    """Validate the user's masks: right shape, non-empty, no overlap."""
    dark = None if dark_mask is None else as_mask(dark_mask, shape, "dark_mask")
    if dark is not None and not dark.any():
        raise bad_value("dark_mask", "an all-False mask", "a mask selecting at least one pixel")
    flats: list[np.ndarray] = []
    if flat_masks is not None:
        arr = np.asarray(flat_masks) if not isinstance(flat_masks, (list, tuple)) else None
        if arr is not None and arr.ndim == 2 and arr.dtype.kind in "iu":
            if arr.shape != tuple(shape):
                raise bad_value("flat_masks.shape", arr.shape,
                                f"the capture's (H, W) = {tuple(shape)}")
            labels = arr
            flats = [labels == k for k in sorted(set(np.unique(labels).tolist()) - {0})]
            if not flats:
                raise bad_value("flat_masks", "a label image without labels > 0",
                                "labels 1..K marking the flat regions (0 = none)")
        elif arr is not None and arr.ndim == 2:  # one boolean mask
            flats = [as_mask(arr, shape, "flat_masks")]
        else:
            seq = list(flat_masks) if arr is None else list(arr)
            flats = [as_mask(m, shape, f"flat_masks[{i}]") for i, m in enumerate(seq)]
        if not flats:
            raise bad_value("flat_masks", "an empty list", "one or more masks, or None")
        for i, m in enumerate(flats):
            if not m.any():
                raise bad_value(f"flat_masks[{i}]", "an empty region",
                                "a mask selecting at least one pixel")
    masks = ([dark] if dark is not None else []) + flats
    if masks:
        overlap = np.sum(masks, axis=0) > 1
        if overlap.any():
            raise bad_value("masks", f"{int(overlap.sum())} pixels in two regions",
                            "disjoint dark and flat regions")
    return dark, flats


def detect_regions(rate: np.ndarray, n_readouts: int, min_pixels: int = 64, tol: float = 0.1,
                   dark_rate: float = 0.02) -> tuple[np.ndarray | None, list[np.ndarray]]:
    """Find dark and flat regions in an (H, W) rate map (spikes per readout); see module notes."""
    from scipy import ndimage

    rate = np.asarray(rate, dtype=np.float64)
    sm = ndimage.median_filter(rate, size=5, mode="nearest")
    v = np.sort(sm.ravel())
    gap = tol * v[1:] + 3.0 / n_readouts
    cuts = np.flatnonzero(np.diff(v) > gap)
    edges = np.concatenate([[v[0] - 1], v[cuts], [v[-1] + 1]])
    cluster = np.searchsorted(edges, sm, side="left") - 1
    dark = np.zeros(rate.shape, bool)
    flats = []
    for c in np.unique(cluster):
        lab, n = ndimage.label(cluster == c)
        for k in range(1, n + 1):
            comp = ndimage.binary_erosion(lab == k, iterations=2)
            if comp.sum() < min_pixels:
                continue
            vals = sm[comp]
            med = float(np.median(vals))
            q1, q3 = np.percentile(vals, [25, 75])
            if med <= dark_rate:  # dark current varies a lot between pixels: no flatness test
                dark |= comp
            elif (q3 - q1) / med > tol:
                continue
            elif med < 0.98:
                flats.append((med, comp))
    flats.sort(key=lambda t: t[0])
    return (dark if dark.any() else None), [m for _, m in flats]
