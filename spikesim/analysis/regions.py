"""Dark and flat regions of a capture: validation of user masks and automatic detection.

A *region* is a boolean (H, W) mask.  Users pass a dark mask and flat masks
(a list of boolean masks, or one integer label image with 0 = no region and
k = flat region k); :func:`check_regions` validates shapes, emptiness and
overlap.  :func:`detect_regions` finds them from the per-pixel firing-rate
map when no mask is given:

1. the rate map is median filtered (5 × 5), which removes the fixed pattern
   and hot pixels but keeps region edges;
2. *locally flat* pixels are kept: the range (max − min) of the filtered
   map over the pixel's 5 × 5 neighbourhood is at most
   ``2·tol·value + 2/T`` (two counts over the capture: short captures
   quantise rates coarsely).  This separates uniform areas from textured or
   moving content whose rates fill the gaps between them; pixels at most
   ``dark_rate`` are always kept (the dark current varies a lot between
   pixels);
3. the filtered values of the kept pixels are clustered in one dimension:
   sorted, a new cluster starts wherever consecutive values differ by more
   than ``tol·value + 3/T`` (three counts over the capture);
4. each cluster is split into connected components, eroded (dark: two
   pixels, the filter radius, as edges mix two levels; flat: one pixel, the
   range test has already removed the edges) and kept when it holds at
   least ``min_pixels`` pixels and, unless dark, the inter-quartile range of
   its filtered values is at most ``tol·median + 1/T`` (a ramp forms one wide
   cluster and is rejected) and, when ``halves`` are given, its pixels'
   count changes between the halves ``d_i`` are uncorrelated between
   neighbours: in a static region they are independent temporal noise, in
   moving content neighbours change together.  The component is rejected
   when ``r = Σ d_i·d_j / sqrt(Σ d_i²·Σ d_j²)`` over horizontally and
   vertically adjacent pairs exceeds ``4/sqrt(pairs)`` (four standard errors
   of a correlation of independent pairs);
5. components whose median rate is at most ``dark_rate`` spikes per readout
   form the dark mask; the others are flat regions, ordered by rate; regions
   within 2 % of one spike per readout are saturated and dropped.
"""

from __future__ import annotations

import numpy as np

from spikesim.errors import SpikeSimTypeError, bad_value

__all__ = ["check_regions", "detect_regions", "as_mask", "motion_score"]


#: What the flat masks may be, for the errors that name it.
FLAT_FORMS = "an (H, W) integer label image (0 = none) or boolean (H, W) or (K, H, W) masks"


def as_mask(mask, shape: tuple[int, int], name: str,
            forms: str = "a boolean (H, W) mask") -> np.ndarray:
    """Validate one (H, W) mask (bool, or integers 0/1) and return it as bool;
    ``forms`` says what was expected in the errors."""
    arr = np.asarray(mask)
    if arr.dtype != np.bool_ and arr.dtype.kind not in "iu":
        raise SpikeSimTypeError(f"{name} must be {forms}, got dtype {arr.dtype}")
    if arr.shape != tuple(shape):
        raise bad_value(f"{name}.shape", arr.shape, f"the capture's (H, W) = {tuple(shape)}")
    if arr.dtype != np.bool_ and arr.size and (arr.min() < 0 or arr.max() > 1):
        raise bad_value(name, f"integers from {arr.min()} to {arr.max()}",
                        f"{forms}, with integers 0 and 1 at most")
    return arr.astype(bool)


def _is_label_image(arr) -> bool:
    return arr is not None and arr.ndim == 2 and arr.dtype.kind in "iu"


def flat_names(flat_masks, count: int) -> list[str]:
    """The names errors and notes give the ``count`` flat regions: ``flat_masks
    label k`` for an integer label image (labels in increasing order, the
    order of ``flat_levels``), ``flat_masks[i]`` for masks, ``detected flat
    region i`` where ``flat_masks`` is None (the regions were detected)."""
    if flat_masks is None:
        return [f"detected flat region {i}" for i in range(count)]
    arr = np.asarray(flat_masks) if not isinstance(flat_masks, (list, tuple)) else None
    if _is_label_image(arr):
        return [f"flat_masks label {k}" for k in sorted(set(np.unique(arr).tolist()) - {0})]
    if arr is not None and arr.ndim == 2:
        return ["flat_masks"]
    return [f"flat_masks[{i}]" for i in range(count)]


def check_regions(dark_mask, flat_masks, shape) -> tuple[np.ndarray | None, list[np.ndarray]]:
    """Validate the user's masks: right shape, non-empty, no overlap."""
    dark = None if dark_mask is None else as_mask(dark_mask, shape, "dark_mask")
    if dark is not None and not dark.any():
        raise bad_value("dark_mask", "an all-False mask", "a mask selecting at least one pixel")
    flats: list[np.ndarray] = []
    if flat_masks is not None:
        arr = np.asarray(flat_masks) if not isinstance(flat_masks, (list, tuple)) else None
        if _is_label_image(arr):
            if arr.shape != tuple(shape):
                raise bad_value("flat_masks.shape", arr.shape,
                                f"the capture's (H, W) = {tuple(shape)}")
            labels = arr
            flats = [labels == k for k in sorted(set(np.unique(labels).tolist()) - {0})]
            if not flats:
                raise bad_value("flat_masks", "a label image without labels > 0",
                                "labels 1..K marking the flat regions (0 = none)")
        elif arr is not None and arr.ndim == 2:  # one boolean mask
            flats = [as_mask(arr, shape, "flat_masks", FLAT_FORMS)]
        else:
            seq = list(flat_masks) if arr is None else list(arr)
            flats = [as_mask(m, shape, f"flat_masks[{i}]", FLAT_FORMS) for i, m in enumerate(seq)]
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
                   dark_rate: float = 0.02, halves: np.ndarray | None = None
                   ) -> tuple[np.ndarray | None, list[np.ndarray]]:
    """Find dark and flat regions in an (H, W) rate map (spikes per readout); see module notes.

    ``halves``: optional (2, H, W) rates (spikes per readout) over the first and
    the second half of the capture, for the steadiness test.
    """
    from scipy import ndimage

    rate = np.asarray(rate, dtype=np.float64)
    t = float(n_readouts)
    sm = ndimage.median_filter(rate, size=5, mode="nearest")
    spread = ndimage.maximum_filter(sm, size=5, mode="nearest") - \
        ndimage.minimum_filter(sm, size=5, mode="nearest")
    kept = (spread <= 2 * tol * sm + 2.0 / t) | (sm <= dark_rate)
    if halves is not None:
        h1, h2 = (ndimage.median_filter(np.asarray(x, np.float64), size=5, mode="nearest")
                  for x in halves)
        change = ndimage.maximum_filter(np.abs(h1 - h2), size=5, mode="nearest")
        kept &= change <= tol * sm + 2.0 / (t / 2)
    dark = np.zeros(rate.shape, bool)
    flats = []
    if not kept.any():
        return None, []
    v = np.sort(sm[kept])
    gap = tol * v[1:] + 3.0 / t
    cuts = np.flatnonzero(np.diff(v) > gap)
    edges = np.concatenate([[v[0] - 1], v[cuts], [v[-1] + 1]])
    cluster = np.where(kept, np.searchsorted(edges, sm, side="left") - 1, -1)
    for c in np.unique(cluster[kept]):
        lab, n = ndimage.label(cluster == c)
        for k in range(1, n + 1):
            region = lab == k
            is_dark = float(np.median(sm[region])) <= dark_rate
            comp = ndimage.binary_erosion(region, iterations=2 if is_dark else 1)
            if comp.sum() < min_pixels:
                continue
            vals = sm[comp]
            med = float(np.median(vals))
            q1, q3 = np.percentile(vals, [25, 75])
            if med <= dark_rate:  # dark current varies a lot between pixels: no flatness test
                dark |= comp
            elif q3 - q1 > tol * med + 1.0 / t:
                continue
            elif halves is not None and _moving(comp, (halves[1] - halves[0]) * (t / 2)):
                continue
            elif med < 0.98:
                flats.append((med, comp))
    flats.sort(key=lambda item: item[0])
    return (dark if dark.any() else None), [m for _, m in flats]


def _moving(comp: np.ndarray, change: np.ndarray) -> bool:
    """Neighbour correlation test of the count changes ``change`` over ``comp`` (notes)."""
    r, limit = motion_score(comp, change)
    return r > limit


def motion_score(comp: np.ndarray, change: np.ndarray) -> tuple[float, float]:
    """``(r, 4/sqrt(pairs))``: the neighbour correlation of the count changes
    ``change`` (second half − first half, spikes) over the region ``comp`` and
    the limit above which it is moving (module notes); ``(0, inf)`` when the
    region has fewer than 16 adjacent pairs or no change at all."""
    a, b = [], []
    for sl0, sl1 in (((slice(None), slice(None, -1)), (slice(None), slice(1, None))),
                     ((slice(None, -1), slice(None)), (slice(1, None), slice(None)))):
        both = comp[sl0] & comp[sl1]
        a.append(change[sl0][both])
        b.append(change[sl1][both])
    x, y = np.concatenate(a), np.concatenate(b)
    x, y = x - x.mean(), y - y.mean()
    den = float(np.sqrt(np.sum(x * x) * np.sum(y * y)))
    if x.size < 16 or den == 0:
        return 0.0, float("inf")
    return float(np.sum(x * y)) / den, 4.0 / float(np.sqrt(x.size))
