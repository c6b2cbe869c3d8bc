"""The regions a calibration fits: the user's masks or detected ones, plane by plane.

:func:`gather_regions` returns the dark mask and the flat regions of a
capture (:class:`Regions`), each flat region within one colour plane
(:mod:`spikesim.analysis.planes`; a monochrome capture is one plane):

* **masks given** — the dark mask as given (the dark current has no colour);
  each flat mask split into its colour planes (a patch is uniform within a
  plane, not across them), named ``flat_masks[i] (R plane)``; given flat
  masks that fail the motion test of :mod:`spikesim.analysis.regions` get a
  note;
* **detected** — :func:`spikesim.analysis.regions.find_regions` on each
  plane's half-resolution rate map (the whole map when monochrome; on a
  plane 3 × 3 filters, and regions of ``min_pixels/4`` pixels, at least
  :data:`PLANE_MIN_PIXELS`, so that a region counts its pixels over the four
  planes): the dark
  regions of all planes form the dark mask; a note names each candidate left
  out (up to :data:`MAX_DROPPED_NOTES`, then one for the rest) and each flat
  region too dim for the fit (fewer than ``MIN_FLAT_SPIKES`` spikes per
  pixel); flat regions of fewer than :data:`MIN_DETECTED_TOTAL` pixels in all,
  and a dark region that small, are left out (with a note);
* **a dark mask alone** — the flat regions are detected outside it.

When detection finds no flat region, ``Regions.flats`` is empty and
``Regions.left_out`` says why; the calibration then takes the path for
captures without one (:mod:`spikesim.analysis.natural_fit`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from spikesim.analysis.calibrate_fit import MIN_FLAT_SPIKES
from spikesim.analysis.capture import pixel_counts
from spikesim.analysis.masks import check_regions, flat_names
from spikesim.analysis.regions import DroppedRegion, describe_region, find_regions, motion_score
from spikesim.errors import bad_value

__all__ = ["Regions", "gather_regions", "MAX_DROPPED_NOTES"]

#: Most left-out candidate regions the notes name one by one (the largest first).
MAX_DROPPED_NOTES = 10
#: Fewest pixels the detected flat regions need together, and the detected dark region
#: (all planes): smaller ones are left out, as the one-level and motion tests have too
#: little power to tell a small patch from moving content.
MIN_DETECTED_TOTAL = 256
#: Fewest pixels of one colour plane a detected region needs (``min_pixels``/4 otherwise).
PLANE_MIN_PIXELS = 32


@dataclass
class Regions:
    """The regions of a calibration.

    ``flats`` are (H, W) masks, each within one colour plane (``planes[i]``
    its name), named ``names[i]`` in errors and notes; ``source[i]`` is the
    index of the user's flat mask it comes from (None when detected), for
    ``flat_levels``; ``detected`` is ``True`` (all detected), ``False`` (from
    masks) or ``"flat regions"`` (dark mask given, flat regions detected);
    ``halves`` the (2, H, W) rates over the capture's two halves and
    ``left_out`` what detection dropped (:class:`DroppedRegion`).
    """

    dark: np.ndarray | None
    flats: list
    planes: list
    names: list
    source: list
    detected: object
    halves: np.ndarray
    left_out: list = field(default_factory=list)

    def levels(self, flat_levels, name: str = "flat_levels"):
        """The radiance of each flat region (scene units, 1 = full scale) from
        ``flat_levels``, one per given flat mask (each of its planes gets it), or
        None; errors call the parameter ``name``."""
        if flat_levels is None:
            return None
        n_given = len({s for s in self.source if s is not None}) if self.detected is False \
            else len(self.flats)
        lv = np.asarray(flat_levels, dtype=np.float64).ravel()
        if lv.size != n_given or np.any(~np.isfinite(lv)) or np.any(lv <= 0):
            raise bad_value(name, lv.tolist(),
                            f"{n_given} finite radiances > 0, one per flat region")
        if self.detected is False:
            return np.array([lv[s] for s in self.source])
        return lv


def gather_regions(cap, rate, n, dark_mask, flat_masks, cfg, planes, progress=False,
                   notes=None) -> Regions:
    """The dark and flat regions of the capture's first ``n`` readouts (module notes).

    ``rate``: (H, W) spikes per readout over them; ``planes``:
    :func:`spikesim.analysis.planes.planes_of` the capture's colour filter;
    ``notes``: a list the notes are appended to.
    """
    notes = [] if notes is None else notes
    shape = (cap.height, cap.width)
    dark, given = check_regions(dark_mask, flat_masks, shape)
    if (dark is None and not given) and not cfg.detect:
        raise bad_value("dark_mask/flat_masks", None, "masks, or detect=True")
    first = pixel_counts(cap, 0, n // 2, progress=progress) / (n // 2)
    second = (rate * n - first * (n // 2)) / (n - n // 2)
    halves = np.stack([first, second])
    if given:
        _motion_notes(given, flat_masks, halves, n, notes)
        flats, names, source, pl = _split(given, flat_names(flat_masks, len(given)), planes)
        return Regions(dark, flats, pl, names, source, False, halves)
    if dark is not None and not cfg.detect:
        raise bad_value("flat_masks", None, "flat masks (a dark_mask alone needs detect=True "
                        "to find the flat regions)")
    found_dark, found, dropped = _detect(rate, n, cfg, halves, planes, notes)
    kept = []
    for f, p in found:
        if dark is not None:
            f = f & ~dark
            if f.sum() < cfg.min_pixels:
                continue
        kept.append((f, p))
    kept = _bright_enough(kept, rate, n, notes)
    if kept and sum(int(f.sum()) for f, _ in kept) < MIN_DETECTED_TOTAL:
        notes.append(f"detected flat regions of {[int(f.sum()) for f, _ in kept]} pixels left "
                     f"out: fewer than {MIN_DETECTED_TOTAL} pixels in all, too few for the "
                     "tests to tell them from moving content")
        kept = []
    if found_dark is not None and found_dark.sum() < MIN_DETECTED_TOTAL:
        notes.append(f"a detected dark region of {int(found_dark.sum())} pixels left out: fewer "
                     f"than {MIN_DETECTED_TOTAL}, too few for the tests to tell it from dim "
                     "moving content")
        found_dark = None
    flats = [f for f, _ in kept]
    pl = [p for _, p in kept]
    names = [f"detected flat region {i}" + ("" if p == "mono" else f" ({p} plane)")
             for i, p in enumerate(pl)]
    return Regions(found_dark if dark is None else dark, flats, pl, names, [None] * len(flats),
                   True if dark is None else "flat regions", halves, dropped)


def _motion_notes(given, flat_masks, halves, n, notes) -> None:
    """A note for each given flat mask whose pixels' count changes between the
    halves are correlated between neighbours (moving content)."""
    change = (halves[1] - halves[0]) * (n / 2)
    for name, f in zip(flat_names(flat_masks, len(given)), given, strict=True):
        r, limit = motion_score(f, change)
        if r > limit:
            notes.append(f"{name} does not look static: its pixels' count changes "
                         f"between the capture's halves are correlated between neighbours "
                         f"(r = {r:.3g} > {limit:.3g}); its intervals inflate the fitted "
                         "temporal noise")


def _split(given, names, planes):
    """Each given flat mask split into its colour planes (one piece when mono)."""
    flats, out_names, source, pl = [], [], [], []
    shape = given[0].shape
    for i, (f, name) in enumerate(zip(given, names, strict=True)):
        for p in planes:
            part = f & p.mask(shape)
            if part.any():
                flats.append(part)
                out_names.append(name if p.name == "mono" else f"{name} ({p.name} plane)")
                source.append(i)
                pl.append(p.name)
    return flats, out_names, source, pl


def _detect(rate, n, cfg, halves, planes, notes):
    """:func:`find_regions` on each plane; ``(dark, [(flat, plane name)], dropped)``
    with full-resolution masks, and the notes on what was left out."""
    shape = rate.shape
    darks, flats, dropped = [], [], []
    mono = len(planes) == 1
    # a plane has a quarter of the pixels at half the resolution: smaller filters and regions
    min_px = cfg.min_pixels if mono else max(-(-cfg.min_pixels // 4), PLANE_MIN_PIXELS)
    for p in planes:
        found = find_regions(p.sub(rate), n, min_pixels=min_px, halves=p.sub(halves),
                             size=5 if mono else 3)
        if found.dark is not None:
            darks += [(m, p.name) for m in _pieces(p.full(found.dark, shape))]
        flats += [(p.full(f, shape), p.name) for f in found.flats]
        for d in found.dropped:
            if p.name != "mono":
                full = p.full(d.mask, shape)
                d = DroppedRegion(d.kind, f"in the {p.name} plane " + describe_region(full, rate),
                                  d.pixels, d.reason, full)
            dropped.append(d)
    if not mono:
        darks = _seen_in_two_planes(darks, "dark", rate, dropped)
        flats = _seen_in_two_planes(flats, "flat", rate, dropped)
    darks = [m for m, _ in darks]
    if len(planes) > 1:
        flats.sort(key=lambda fp: float(np.median(rate[fp[0]])))
    dropped.sort(key=lambda d: -d.pixels)
    notes.extend(d.describe() for d in dropped[:MAX_DROPPED_NOTES])
    rest = dropped[MAX_DROPPED_NOTES:]
    if rest:
        notes.append(f"{len(rest)} smaller detected candidate regions "
                     f"({sum(d.pixels for d in rest)} pixels) were left out too: "
                     f"{reason_counts(rest)}")
    dark = np.logical_or.reduce(darks) if darks else None
    return dark, flats, dropped


def _pieces(mask):
    """The connected pieces of a full-resolution mask of one plane (8-connected on
    the plane's grid: 2 pixels apart at full resolution)."""
    from scipy import ndimage

    lab, n = ndimage.label(ndimage.binary_dilation(mask, np.ones((3, 3), bool)))
    return [mask & (lab == k) for k in range(1, n + 1)]


def _footprint(mask):
    from scipy import ndimage

    return ndimage.binary_dilation(mask, np.ones((3, 3), bool))


def _seen_in_two_planes(regions, kind, rate, dropped):
    """The ``(mask, plane)`` regions of a colour capture whose footprint (dilated by
    one pixel) is at least half covered by regions of the same kind in planes of
    another colour: a uniform patch is uniform in every plane, a dark area dark
    in every plane; a region found in one colour only (the two greens see the
    same light, so they agree on texture too) is chance, texture or motion the
    tests of one plane could not see, and is left out with a note."""
    feet = [(_footprint(m), p) for m, p in regions]
    kept = []
    for (m, p), (foot, _) in zip(regions, feet, strict=True):
        others = [f for f, q in feet if q[0] != p[0]]
        cover = np.logical_or.reduce(others) if others else np.zeros_like(foot)
        if np.count_nonzero(foot & cover) >= 0.5 * np.count_nonzero(foot):
            kept.append((m, p))
        else:
            dropped.append(DroppedRegion(
                kind, f"in the {p} plane " + describe_region(m, rate), int(m.sum()),
                "found in this colour only (a uniform or dark patch is so in every colour: "
                "texture or motion)", m))
    return kept


def reason_counts(dropped) -> str:
    """``2 not static, 1 not uniform``: how many of ``dropped`` were left out for each reason."""
    kinds: dict[str, int] = {}
    for d in dropped:
        key = d.reason.split(" (")[0]
        kinds[key] = kinds.get(key, 0) + 1
    return ", ".join(f"{v} {k}" for v, k in sorted(((v, k) for k, v in kinds.items()),
                                                    reverse=True))


def _bright_enough(flats, rate, n, notes):
    """The detected ``(flat, plane)`` pairs with at least ``MIN_FLAT_SPIKES``
    spikes per pixel (the fit needs them); each one dropped gets a note."""
    kept = []
    for f, p in flats:
        spikes = min(float(np.mean(rate[f])), float(np.median(rate[f]))) * n
        if spikes >= MIN_FLAT_SPIKES:
            kept.append((f, p))
        else:
            where = "" if p == "mono" else f"in the {p} plane "
            notes.append(f"a detected flat region {where}{describe_region(f, rate)} was left "
                         f"out: too dim, {spikes:.3g} spikes per pixel, fewer than the fit's "
                         f"{MIN_FLAT_SPIKES} (a longer capture would keep it)")
    return kept
