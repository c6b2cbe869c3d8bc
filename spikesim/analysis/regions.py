"""Dark and flat regions of a capture, detected automatically.

A *region* is a boolean (H, W) mask (the user's own masks are validated by
:mod:`spikesim.analysis.masks`).  :func:`detect_regions` finds them from the
per-pixel firing-rate map when no mask is given:

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
   range test has already removed the edges); a component of at least
   ``min_pixels`` pixels is a *candidate*, dark when its median rate is at
   most ``dark_rate`` spikes per readout; a dark candidate keeps only its
   pixels at its own level (:func:`_dark_core`), and a part of it found
   brighter than ``dark_rate`` (step 6) is tested as flat;
5. a candidate is kept when the inter-quartile range of its filtered values
   is at most ``tol·median + 1/T`` (a ramp forms one wide cluster and is
   rejected; for a dark candidate, whose dark current varies a lot between
   pixels, at most ``max(tol·median + 1/T, median)``: dark pixels joined to
   dim light through the edges between them are one level no more), a
   candidate is *one level*: the variance of its raw rates exceeds the
   neighbour-referenced variance ``(8/9)·mean((x_i − x̄_nb,i)²)`` (which
   measures the fixed pattern and the counting noise alone, whatever the
   capture length) by at most :data:`LEVEL_EXCESS` plus four standard errors
   (:func:`level_excess`: a dim band joined to a brighter patch through the
   quantised rates of a short capture fails it), and, when ``halves`` are
   given, its
   pixels' count changes between the halves ``d_i`` are uncorrelated between
   neighbours: in a static region they are independent temporal noise, in
   moving content neighbours change together (moving content is neither dark
   nor flat).  The candidate is rejected when
   ``r = Σ d_i·d_j / sqrt(Σ d_i²·Σ d_j²)`` over horizontally and vertically
   adjacent pairs exceeds ``4/sqrt(pairs)`` (four standard errors of a
   correlation of independent pairs); flat candidates within 2 % of one
   spike per readout are saturated and rejected;
6. a rejected candidate may hold a static region that touches moving or
   textured content of similar rates (the clustering joins them): its
   *static pieces* (without the pixels whose change ``d_i`` is an outlier,
   :func:`_static_pieces`) and their *uniform parts*
   (the pixels of one peak of its rate histogram, :func:`_uniform_parts`,
   else of the peak's densest rate ± its density width; a ramp has no peak)
   of at least ``min_pixels`` pixels are tested again
   and kept when they pass;
7. the dark candidates kept form the dark mask, except those whose mean
   rate exceeds the darkest one's by more than ``5·tol`` of it (half at the
   default ``tol``) and four standard errors: dim light, not dark current
   (the dark current is one level across the chip), tested as flat
   candidates instead; the flat regions are ordered by rate.

:func:`find_regions` also returns the candidates left out and why
(:class:`DroppedRegion`), for the notes of the calibration report.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["detect_regions", "find_regions", "Detection", "DroppedRegion",
           "describe_region", "motion_score", "level_excess", "neighbour_mean", "LEVEL_EXCESS"]


@dataclass(frozen=True)
class DroppedRegion:
    """A candidate region :func:`find_regions` left out: ``kind`` (``"dark"``
    or ``"flat"``), ``where`` (:func:`describe_region`), ``pixels``,
    ``reason`` (a phrase saying why) and its ``mask`` over the rate map."""

    kind: str
    where: str
    pixels: int
    reason: str
    mask: np.ndarray | None = field(default=None, repr=False, compare=False)

    def describe(self) -> str:
        """The note the calibration report gives for it."""
        return f"a detected {self.kind} candidate region {self.where} was left out: {self.reason}"


def describe_region(mask: np.ndarray, rate: np.ndarray) -> str:
    """``of N pixels (rows a-b, columns c-d; median rate r spikes per readout)``:
    what notes call the region ``mask`` of the (H, W) ``rate`` map."""
    rows, cols = np.nonzero(mask)
    return (f"of {rows.size} pixels (rows {rows.min()}-{rows.max()}, columns {cols.min()}-"
            f"{cols.max()}; median rate {float(np.median(rate[mask])):.4g} spikes per readout)")


@dataclass(frozen=True)
class Detection:
    """What :func:`find_regions` found: the dark mask (or None), the flat masks
    ordered by rate and the candidates it left out (:class:`DroppedRegion`)."""

    dark: np.ndarray | None
    flats: list
    dropped: list = field(default_factory=list)


def detect_regions(rate: np.ndarray, n_readouts: int, min_pixels: int = 64, tol: float = 0.1,
                   dark_rate: float = 0.02, halves: np.ndarray | None = None
                   ) -> tuple[np.ndarray | None, list[np.ndarray]]:
    """Find dark and flat regions in an (H, W) rate map (spikes per readout); see module notes.

    ``halves``: optional (2, H, W) rates (spikes per readout) over the first and
    the second half of the capture, for the steadiness and motion tests.
    Returns ``(dark, flats)``; :func:`find_regions` also says what was left out.
    """
    found = find_regions(rate, n_readouts, min_pixels, tol, dark_rate, halves)
    return found.dark, found.flats


def find_regions(rate: np.ndarray, n_readouts: int, min_pixels: int = 64, tol: float = 0.1,
                 dark_rate: float = 0.02, halves: np.ndarray | None = None,
                 size: int = 5) -> Detection:
    """:func:`detect_regions` with the candidates left out (a :class:`Detection`).

    ``size``: the side of the median and range filters (pixels; the 5 × 5 of
    the module notes, 3 × 3 on the half-resolution planes of a colour capture),
    and twice (plus one) the erosion of dark candidates."""
    from scipy import ndimage

    rate = np.asarray(rate, dtype=np.float64)
    t = float(n_readouts)
    sm = ndimage.median_filter(rate, size=size, mode="nearest")
    change = None if halves is None else (np.asarray(halves[1], np.float64) -
                                          np.asarray(halves[0], np.float64)) * (t / 2)
    kept = _candidate_pixels(sm, t, tol, dark_rate, halves, size)
    if not kept.any():
        return Detection(None, [])
    dark_parts, flat_parts, dropped = [], [], []
    raw = (rate, neighbour_mean(rate))
    for comp, is_dark in _components(sm, kept, t, tol, dark_rate, min_pixels, size // 2):
        pieces = _dark_core(comp, sm, rate, tol, size, min_pixels) if is_dark else [comp]
        for piece in pieces:
            for part in _parts(piece, sm, t, tol, min_pixels, change, is_dark, dropped, raw):
                if is_dark and float(np.median(sm[part])) > dark_rate:  # a brighter part of a
                    flat_parts += _parts(part, sm, t, tol, min_pixels, change, False, dropped,
                                         raw)  # dark candidate: tested as flat
                else:
                    (dark_parts if is_dark else flat_parts).append(part)
    dark_parts, dim = _darkest_level(dark_parts, rate, tol)
    for comp in dim:  # brighter than the dark level: dim light, tested as flat
        flat_parts += _parts(comp, sm, t, tol, min_pixels, change, False, dropped, raw)
    flat_parts.sort(key=lambda m: float(np.median(sm[m])))
    dark = np.logical_or.reduce(dark_parts) if dark_parts else None
    return Detection(dark, flat_parts, dropped)


def _parts(comp, sm, t, tol, min_pixels, change, is_dark, dropped, raw=None) -> list:
    """The regions a candidate gives: itself when it passes the tests (module
    notes, steps 4-5), else the parts of it that do: its static pieces
    (:func:`_static_pieces`) and their uniform parts (:func:`_uniform_parts`).
    What is left out is added to ``dropped``."""
    why = _rejection(comp, sm, t, tol, is_dark, change, raw)
    if why is None:
        return [comp]
    parts = []
    for piece in _static_pieces(comp, change, min_pixels):
        if _rejection(piece, sm, t, tol, is_dark, change, raw) is None:
            parts.append(piece)
        else:
            for core in (False, True):  # each peak's range, else its mode's quantum
                got = [p for p in _uniform_parts(piece, sm, t, tol, min_pixels, core)
                       if _rejection(p, sm, t, tol, is_dark, change, raw) is None]
                if got:
                    parts += got
                    break
    kind = "dark" if is_dark else "flat"
    if parts:
        many = len(parts) > 1
        why += (f"; {len(parts)} uniform, static part{'s' if many else ''} of it "
                f"({int(np.sum([p.sum() for p in parts]))} pixels) kept as "
                f"{f'{kind} regions' if many else f'a {kind} region'}")
    dropped.append(_dropped(comp, sm, kind, why))
    return parts


def _dark_core(comp, sm, rate, tol, size, min_pixels) -> list:
    """The connected pieces (at least ``min_pixels``) of the dark candidate ``comp``
    at its own level: filtered rates at most ``median·(1 + 5·tol)`` plus four
    standard errors of a ``size × size`` median (``1.25·s/size``, ``s`` the robust
    s.d. of the raw rates), so that dim light joined to the dark through the
    pixels between them is cut off (module notes, step 4)."""
    from scipy import ndimage

    med = float(np.median(sm[comp]))
    raw = rate[comp]
    rsd = 1.4826 * float(np.median(np.abs(raw - np.median(raw))))
    core = comp & (sm <= med * (1 + 5 * tol) + 4 * 1.25 * rsd / size)
    if core.sum() == comp.sum():
        return [comp]
    lab, n = ndimage.label(core)
    return [lab == k for k in range(1, n + 1) if np.count_nonzero(lab == k) >= min_pixels]


def _static_pieces(comp, change, min_pixels):
    """Yield the connected pieces (at least ``min_pixels`` pixels) of ``comp``
    without the pixels whose count change between the halves (spikes) is an
    outlier: more than 4 robust standard deviations (at least one spike) from
    the median change; pixels enclosed by a piece stay in it (hot pixels).
    Moving content next to a static region changes by many spikes, the static
    region by its counting noise."""
    from scipy import ndimage

    if change is None:
        yield comp
        return
    d = change[comp]
    med = float(np.median(d))
    sd = max(1.4826 * float(np.median(np.abs(d - med))), 1.0)
    lab, n = ndimage.label(comp & (np.abs(change - med) <= 4 * sd))
    for k in range(1, n + 1):
        piece = ndimage.binary_fill_holes(lab == k) & comp  # keep enclosed hot pixels
        if piece.sum() >= min_pixels:
            yield piece


def _uniform_parts(comp, sm, t, tol, min_pixels, core: bool = False):
    """Yield the candidate's pieces of one rate level: for each peak of its rate
    histogram (:func:`_peak_ranges`), its connected pixels in the peak's rate
    range, of at least ``min_pixels`` pixels and not tilted (:func:`_tilted`).
    A static band that touches moving or textured content of similar rates
    forms one candidate with it; this finds the band again (a ramp has no peak).
    ``core``: the range is only the peak's densest rate ± its density width (a
    short capture's quantised rates can make the band's peak and the moving
    content around it one wide peak)."""
    from scipy import ndimage

    rows, cols = np.nonzero(comp)
    box = (slice(rows.min(), rows.max() + 1), slice(cols.min(), cols.max() + 1))
    inside, values = comp[box], sm[box]
    for lo, hi in _peak_ranges(values[inside], t, tol, min_pixels, core):
        lab, n = ndimage.label(inside & (values >= lo) & (values <= hi))
        for k in range(1, n + 1):
            if np.count_nonzero(lab == k) >= min_pixels:
                piece = np.zeros(comp.shape, bool)
                piece[box] = lab == k
                if not _tilted(piece, sm, t, tol):
                    yield piece


def _peak_ranges(values, t, tol, min_pixels, core: bool = False) -> list[tuple[float, float]]:
    """The rate ranges (spikes per readout) of the peaks of ``values``.

    The density at rate ``u`` is the number of values within ``w`` of it,
    ``w = max((tol·u + 1/T)/4, 1/T)`` (a quarter of the flatness tolerance,
    at least one count over the capture: rates are multiples of ``1/T``); from
    the densest rate down, a peak of at least ``min_pixels`` extends on both
    sides while the density stays at least half its own (a rate range
    overlapping an earlier peak's is no peak).  A ramp's density is flat: one
    range covering it all."""
    v = np.sort(np.asarray(values, np.float64))
    u = np.unique(v)
    w = np.maximum((tol * u + 1.0 / t) / 4, 1.0 / t)
    dens = _count(v, u - w, u + w)
    taken = np.zeros(u.size, bool)
    ranges = []
    for i in np.argsort(-dens, kind="stable"):
        if dens[i] < min_pixels:
            break
        lo, hi = i, i
        while lo > 0 and 2 * dens[lo - 1] >= dens[i]:
            lo -= 1
        while hi < u.size - 1 and 2 * dens[hi + 1] >= dens[i]:
            hi += 1
        if not taken[lo: hi + 1].any():
            taken[lo: hi + 1] = True
            ranges.append((float(u[i] - w[i]), float(u[i] + w[i])) if core else
                          (float(u[lo] - w[lo]), float(u[hi] + w[hi])))
    return ranges


def _count(v, lo, hi):
    """How many of the sorted ``v`` lie in each ``[lo, hi]``."""
    return np.searchsorted(v, hi, side="right") - np.searchsorted(v, lo, side="left")


def _tilted(piece, sm, t, tol) -> bool:
    """Whether the least-squares plane through the filtered rates of ``piece``
    varies over it by more than half the flatness tolerance (a slice of a ramp,
    not a uniform part)."""
    rows, cols = np.nonzero(piece)
    x = np.stack([np.ones(rows.size), rows, cols], axis=1).astype(np.float64)
    coef, *_ = np.linalg.lstsq(x, sm[piece], rcond=None)
    fit = x @ coef
    return float(fit.max() - fit.min()) > (tol * float(np.median(sm[piece])) + 1.0 / t) / 2


def _darkest_level(parts, rate, tol):
    """Split the dark candidates into ``(dark, dim)`` (module notes, step 7):
    dark are those whose mean rate (spikes per readout) exceeds the darkest
    candidate's by at most ``5·tol`` of it plus four standard errors of the
    difference; a brighter one is dim light (a flat candidate)."""
    if len(parts) < 2:
        return parts, []
    stats = [(float(rate[p].mean()), float(rate[p].var()) / max(int(p.sum()) - 1, 1))
             for p in parts]
    b0, v0 = min(stats)
    dark, dim = [], []
    for p, (b, v) in zip(parts, stats, strict=True):
        (dark if b - b0 <= 5 * tol * b0 + 4 * np.sqrt(v + v0) else dim).append(p)
    return dark, dim


def _candidate_pixels(sm, t, tol, dark_rate, halves, size: int = 5) -> np.ndarray:
    """(H, W) bool: the locally flat and steady pixels (module notes, step 2)."""
    from scipy import ndimage

    spread = ndimage.maximum_filter(sm, size=size, mode="nearest") - \
        ndimage.minimum_filter(sm, size=size, mode="nearest")
    kept = (spread <= 2 * tol * sm + 2.0 / t) | (sm <= dark_rate)
    if halves is not None:
        h1, h2 = (ndimage.median_filter(np.asarray(x, np.float64), size=size, mode="nearest")
                  for x in halves)
        steady = ndimage.maximum_filter(np.abs(h1 - h2), size=size, mode="nearest")
        kept &= steady <= tol * sm + 2.0 / (t / 2)
    return kept


def _components(sm, kept, t, tol, dark_rate, min_pixels, dark_erosion: int = 2):
    """Yield ``(mask, is_dark)`` per eroded connected component of each rate
    cluster with at least ``min_pixels`` pixels (module notes, steps 3-4)."""
    from scipy import ndimage

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
            comp = ndimage.binary_erosion(region, iterations=dark_erosion if is_dark else 1)
            if comp.sum() >= min_pixels:
                yield comp, bool(float(np.median(sm[comp])) <= dark_rate)


def _rejection(comp, sm, t, tol, is_dark, change, raw=None) -> str | None:
    """Why the candidate ``comp`` is not a region (module notes, steps 4-5), or None.

    ``raw``: ``(rate, neighbour mean)`` maps for the one-level test of flat
    candidates (:func:`level_excess`)."""
    vals = sm[comp]
    med = float(np.median(vals))
    q1, q3 = np.percentile(vals, [25, 75])
    if not is_dark and q3 - q1 > tol * med + 1.0 / t:
        return (f"not uniform (inter-quartile range of its rates {q3 - q1:.3g} > "
                f"{tol * med + 1.0 / t:.3g} spikes per readout: a ramp or texture)")
    if raw is not None:
        ratio, limit = level_excess(comp, *raw)
        if ratio > limit:
            return (f"not one level (its rates vary {ratio:.3g}x more across it than between "
                    f"neighbours, more than {limit:.3g}x: a step or a gradient)")
    if is_dark and q3 - q1 > max(tol * med + 1.0 / t, med):
        return (f"not one dark level (inter-quartile range of its rates {q3 - q1:.3g} > "
                f"{max(tol * med + 1.0 / t, med):.3g} spikes per readout: dark and dim light "
                "joined)")
    if change is not None:
        r, limit = motion_score(comp, change)
        if r > limit:
            return ("not static (its pixels' count changes between the capture's halves are "
                    f"correlated between neighbours, r = {r:.3g} > {limit:.3g}: moving "
                    f"content{' is not dark' if is_dark else ''})")
    if not is_dark and med >= 0.98:
        return "saturated (within 2 % of one spike per readout: no gain information)"
    return None


def _dropped(comp, sm, kind, reason) -> DroppedRegion:
    return DroppedRegion(kind, describe_region(comp, sm), int(comp.sum()), reason, comp)


#: Variance excess over the neighbour-referenced variance that a flat region may show
#: (a gradient of this size biases its response spread by about half as much).
LEVEL_EXCESS = 0.1


def neighbour_mean(rate: np.ndarray) -> np.ndarray:
    """(H, W) mean of each pixel's 8 neighbours (the pixel left out; mirrored at the border)."""
    from scipy import ndimage

    x = np.asarray(rate, np.float64)
    return (ndimage.uniform_filter(x, 3, mode="reflect") * 9 - x) / 8


def level_excess(comp: np.ndarray, rate: np.ndarray, nb: np.ndarray) -> tuple[float, float]:
    """``(ratio, limit)``: the variance of the rates over the region ``comp``
    against ``(8/9)·mean((rate − nb)²)`` over its inner pixels (``nb``
    :func:`neighbour_mean`).  Both measure the fixed pattern and the counting
    noise of one level; a step or gradient inside the region adds to the first
    only.  ``limit`` is ``1 +`` :data:`LEVEL_EXCESS` plus four standard
    errors of the ratio; ``(1, inf)`` for regions of fewer than 16 inner pixels."""
    from scipy import ndimage

    inner = ndimage.binary_erosion(comp, structure=np.ones((3, 3), bool))
    n_in, n = int(inner.sum()), int(comp.sum())
    if n_in < 16:
        return 1.0, float("inf")
    local = float(np.mean((rate[inner] - nb[inner]) ** 2)) * 8 / 9
    if local <= 0:
        return 1.0, float("inf")
    ratio = float(np.var(rate[comp])) / local
    return ratio, 1 + LEVEL_EXCESS + 4 * float(np.sqrt(2 / n + 2 / n_in))


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
