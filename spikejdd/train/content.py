"""Training content with natural statistics: dead leaves, sharp textures, exposure and colour.

* :func:`dead_leaves` — the dead-leaves model (Matheron's random sets; as an
  image model, Lee, Mumford & Huang, "Occlusion models for natural images",
  IJCV 41, 2001): opaque shapes dropped one over another until they cover the
  frame, radii with the power-law density ``p(r) ∝ r⁻³`` on ``[r_min,
  r_max]`` — the scale-invariant case, whose images have the ``1/f²`` power
  spectrum of natural photographs.  Achddou, Gousseau & Ladjal, "Synthetic
  images as a regularity prior for image restoration neural networks" (SSVM
  2021) trained denoisers on such images, with colours drawn from natural
  photographs, nearly as well as on the photographs themselves.  Here the
  shapes are ellipses (discs among them) and rotated rectangles, the colours
  are pixels of the training pictures (:func:`natural_colours`), half the
  images carry a sinusoidal texture inside some leaves (periods down to 2
  pixels) and a quarter a slight blur (depth of field);
* :func:`procedural_texture` — value noise, sine gratings, checkers,
  square-wave stripes of 2–16-pixel period and zone plates (every frequency
  up to Nyquist), the sharp ones rendered at twice the resolution and
  area-averaged;
* :func:`finish` — colour transforms (a colour mix for two thirds of the grey
  content, the rest kept grey; a saturation change ×U(0.6, 1.4), or to
  U(0, 0.3) for 15 % of the colour content; a white balance) and an
  exposure that sets the 99.5th
  percentile at ``U(0.4, 1)`` of full scale, or, for one image in five, at
  ``U(1, 2.5)``: clipped at 1, those have saturated and near-saturated regions.

Every function draws from the ``numpy`` generator it is given and from
nothing else (the colour pool is a fixed function of the installed training
pictures), so content is reproducible from the seed.
"""

from __future__ import annotations

import math
from functools import lru_cache

import cv2
import numpy as np

from spikesim.errors import bad_value

__all__ = ["dead_leaves", "procedural_texture", "finish", "natural_colours", "powerlaw_radii",
           "percentile", "TEXTURE_KINDS", "BRIGHT_FRACTION", "GREY_KEPT", "DESATURATED",
           "SUPERSAMPLE"]

#: Rendering resolution of sharp content, times the output's (area-averaged down).
SUPERSAMPLE = 2
#: Share of images exposed past full scale (saturated and near-saturated regions).
BRIGHT_FRACTION = 0.2
#: Share of grey content kept grey (only the white balance tints it), and of colour
#: content desaturated to 0–30 %: black-and-white pictures and near-grey scenes exist (the
#: held-out benchmark's largest losses of the shipped models are on grey pictures).
GREY_KEPT, DESATURATED = 1 / 3, 0.15
#: Kinds of :func:`procedural_texture`.
TEXTURE_KINDS = ("value-noise", "sine-grating", "checker", "stripes", "zone-plate")
_POOL_PER_PICTURE = 4096
_MAX_LEAVES = 3000


def percentile(x: np.ndarray, q: float) -> float:
    """``numpy.percentile(x, q)`` (linear interpolation) from a partial sort: the same value."""
    a = np.asarray(x).ravel()
    pos = q / 100.0 * (a.size - 1)
    lo = int(math.floor(pos))
    hi = min(lo + 1, a.size - 1)
    part = np.partition(a, (lo, hi))
    return float(part[lo] + (pos - lo) * (part[hi] - part[lo]))


@lru_cache(maxsize=1)
def _colour_pool() -> np.ndarray:
    """(K, 3) float32 linear colours: pixels of the colour training pictures (fixed draw)."""
    from spikejdd.train.pictures import TRAIN_PICTURES, load_picture

    rng = np.random.default_rng(20210)
    pool = []
    for name in TRAIN_PICTURES:
        pic = load_picture(name).reshape(-1, 3)
        if np.ptp(pic - pic.mean(axis=1, keepdims=True)) < 1e-3:  # grey: no colour statistics
            continue
        pool.append(pic[rng.integers(0, len(pic), _POOL_PER_PICTURE)])
    out = np.concatenate(pool).astype(np.float32)
    out.setflags(write=False)
    return out


def natural_colours(n: int, rng: np.random.Generator) -> np.ndarray:
    """(n, 3) float32 linear colours drawn from pixels of the colour training pictures."""
    pool = _colour_pool()
    return pool[rng.integers(0, len(pool), int(n))]


def powerlaw_radii(n: int, r_min: float, r_max: float, rng: np.random.Generator,
                   alpha: float = 3.0) -> np.ndarray:
    """``n`` radii with density ``∝ r^-alpha`` on ``[r_min, r_max]`` (inverse CDF; alpha > 1)."""
    if not 0 < r_min < r_max:
        raise bad_value("r_min, r_max", (r_min, r_max), "0 < r_min < r_max")
    if not alpha > 1:
        raise bad_value("alpha", alpha, "an exponent > 1")
    k = 1.0 - alpha
    u = rng.random(int(n))
    return (r_min**k + u * (r_max**k - r_min**k)) ** (1.0 / k)


def _mean_square_radius(r_min: float, r_max: float, alpha: float = 3.0) -> float:
    """E[r²] under :func:`powerlaw_radii`; for alpha = 3,
    ``2 r_min² ln(r_max / r_min) / (1 − (r_min / r_max)²)``."""
    if alpha == 3.0:
        return 2 * r_min**2 * math.log(r_max / r_min) / (1 - (r_min / r_max) ** 2)
    k = 1 - alpha
    return (k / (k + 2)) * (r_max ** (k + 2) - r_min ** (k + 2)) / (r_max**k - r_min**k)


def _sharp_to_output(img: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    h, w = size
    return cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA)


_STAMP = 6  # leaves reaching at most this many canvas pixels are stamped, not drawn


def _rasterise(h: int, w: int, cx, cy, a, b, angle, rect, reach) -> np.ndarray:
    """(h, w) int64 label of the front leaf at each pixel centre (index ``k``: leaf 0 in
    front; ``n``: none) for ellipses (semi-axes ``a``, ``b``) and rectangles (half-sides
    ``a``, ``b``) centred at ``cx``, ``cy`` (pixel centres at integers) rotated by ``angle``
    radians.  Small leaves (most of them, under r⁻³) are stamped all at once — a
    ``numpy.minimum.at`` of their indices over the pixels inside them; larger ones are
    filled by OpenCV from the back, so the smallest index covering a pixel stays on top."""
    n = len(cx)
    small = reach <= _STAMP
    label = np.full(h * w, n, np.int64)
    k = np.flatnonzero(small)
    if len(k):
        off = np.arange(-_STAMP, _STAMP + 1)
        px = np.rint(cx[k])[:, None, None] + off[None, None, :]
        py = np.rint(cy[k])[:, None, None] + off[None, :, None]
        dx, dy = px - cx[k, None, None], py - cy[k, None, None]
        c, s = np.cos(angle[k])[:, None, None], np.sin(angle[k])[:, None, None]
        u = (dx * c + dy * s) / a[k, None, None]
        v = (-dx * s + dy * c) / b[k, None, None]
        inside = np.where(rect[k, None, None], np.maximum(np.abs(u), np.abs(v)) <= 1.0,
                          u * u + v * v <= 1.0)
        inside &= (px >= 0) & (px < w) & (py >= 0) & (py < h)
        idx = (py * w + px)[inside].astype(np.int64)
        np.minimum.at(label, idx, np.broadcast_to(k[:, None, None], inside.shape)[inside])
    big = np.flatnonzero(~small)
    if len(big):
        shift = 4  # OpenCV's sub-pixel precision: 1/16 pixel
        one = 1 << shift
        canvas = np.full((h, w), float(n), np.float32)
        # OpenCV fills every pixel its outline touches, about half a pixel beyond the
        # shape: shapes half a pixel smaller cover the pixel centres inside the true one
        # (to 2 % of the area, unbiased, as measured against the exact inside test)
        ab, bb_ = np.maximum(a[big] - 0.5, 0.25), np.maximum(b[big] - 0.5, 0.25)
        xs = np.rint(cx[big] * one).astype(np.int64).tolist()
        ys = np.rint(cy[big] * one).astype(np.int64).tolist()
        aa = np.maximum(np.rint(ab * one), 1).astype(np.int64).tolist()
        bb = np.maximum(np.rint(bb_ * one), 1).astype(np.int64).tolist()
        deg = np.degrees(angle[big]).tolist()
        t = angle[big][:, None]
        u = np.array([1.0, -1.0, -1.0, 1.0]) * ab[:, None]
        v = np.array([1.0, 1.0, -1.0, -1.0]) * bb_[:, None]
        corners = np.rint(np.stack([cx[big][:, None] + u * np.cos(t) - v * np.sin(t),
                                    cy[big][:, None] + u * np.sin(t) + v * np.cos(t)], -1)
                          * one).astype(np.int32)
        is_rect = rect[big].tolist()
        for j in range(len(big) - 1, -1, -1):  # back to front
            if is_rect[j]:
                cv2.fillConvexPoly(canvas, corners[j], float(big[j]), cv2.LINE_8, shift)
            else:
                cv2.ellipse(canvas, (xs[j], ys[j]), (aa[j], bb[j]), deg[j], 0, 360,
                            float(big[j]), -1, cv2.LINE_8, shift)
        np.minimum(label, canvas.ravel().astype(np.int64), out=label)
    return label.reshape(h, w)


def dead_leaves(size: tuple[int, int], rng: np.random.Generator, r_min: float | None = None,
                r_max: float | None = None, uncovered: float = 0.03,
                texture: bool | None = None, blur: bool | None = None) -> np.ndarray:
    """(H, W, 3) float32 linear dead-leaves image (see the module doc), before :func:`finish`.

    Parameters
    ----------
    size : (H, W)
        Output pixels.
    r_min, r_max : float, optional
        Radius range, output pixels (default ``2^U(0, 1.5)`` and ``max(H, W)``).
    uncovered : float
        Expected fraction of the frame no leaf covers (it shows the background
        colour): sets the number of leaves, ``ln(1/uncovered) · H·W / E[leaf area]``
        (at most 3000).
    texture, blur : bool, optional
        Sinusoidal texture in some leaves / a Gaussian blur of σ ∈ U(0.3, 1.2) px;
        default: drawn (½ and ¼ of the images).
    """
    h, w = (int(v) for v in size)
    s = SUPERSAMPLE
    r_min = float(2.0 ** rng.uniform(0.0, 1.5)) if r_min is None else float(r_min)
    r_max = float(max(h, w)) if r_max is None else float(r_max)
    r_max = max(r_max, r_min * 1.01)
    texture = bool(rng.random() < 0.5) if texture is None else texture
    blur = bool(rng.random() < 0.25) if blur is None else blur
    # mean leaf area: ellipses π r² q and rectangles 4 r² q (q the aspect, E[q] = 0.7)
    mean_area = (0.7 * math.pi + 0.3 * 4.0) * 0.7 * _mean_square_radius(r_min, r_max)
    n = int(min(_MAX_LEAVES, math.ceil(math.log(1.0 / uncovered) * h * w / mean_area)))
    r = powerlaw_radii(n, r_min, r_max, rng)
    q = rng.uniform(0.4, 1.0, n)
    rect = rng.random(n) < 0.3
    reach = r * np.where(rect, np.sqrt(1 + q * q), 1.0)  # farthest point from the centre
    # centres over the frame grown by each leaf's reach (up to 10 % of the side): a leaf
    # centred outside still covers the border
    grow = np.minimum(reach, 0.1 * max(h, w))
    cx = -grow + rng.random(n) * (w + 2 * grow)
    cy = -grow + rng.random(n) * (h + 2 * grow)
    angle = rng.uniform(0.0, np.pi, n)
    colours = natural_colours(n + 1, rng)  # [n] the background behind every leaf
    label = _rasterise(h * s, w * s, cx * s + (s - 1) / 2, cy * s + (s - 1) / 2, r * s,
                       r * q * s, angle, rect, reach * s)
    img = colours[label]
    if texture:
        textured = rng.random(n + 1) < 0.5
        amp = np.where(textured, rng.uniform(0.1, 0.6, n + 1), 0.0).astype(np.float32)
        period = 2.0 ** rng.uniform(1.0, 4.0, n + 1) * s  # 2–16 output pixels
        theta = rng.uniform(0.0, np.pi, n + 1)
        kx = (2 * np.pi * np.cos(theta) / period).astype(np.float32)
        ky = (2 * np.pi * np.sin(theta) / period).astype(np.float32)
        phase = rng.uniform(0.0, 2 * np.pi, n + 1).astype(np.float32)
        rows, cols = np.indices(label.shape, dtype=np.float32)
        mod = 1.0 + amp[label] * np.sin(kx[label] * cols + ky[label] * rows + phase[label])
        img = img * mod[..., None]
    out = _sharp_to_output(np.ascontiguousarray(img, dtype=np.float32), (h, w))
    if blur:
        sigma = float(rng.uniform(0.3, 1.2))
        out = cv2.GaussianBlur(out, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
    return np.clip(out, 0.0, None)


def procedural_texture(size: tuple[int, int], rng: np.random.Generator) -> np.ndarray:
    """(H, W, 3) linear texture of one of :data:`TEXTURE_KINDS`, through :func:`finish`."""
    h, w = (int(v) for v in size)
    kind = TEXTURE_KINDS[int(rng.integers(len(TEXTURE_KINDS)))]
    if kind == "value-noise":  # 4 octaves, coloured per octave
        out = np.zeros((h, w, 3), np.float32)
        for octave in range(4):
            cells = 2 ** (octave + 1)
            grid = rng.random((cells + 1, cells + 1, 3)).astype(np.float32)
            out += cv2.resize(grid, (w, h), interpolation=cv2.INTER_CUBIC) * 0.5**octave
        out = out - out.min()
        return finish(out / max(float(out.max()), 1e-6), rng)
    s = 1 if kind == "sine-grating" else SUPERSAMPLE
    rows, cols = np.indices((h * s, w * s), dtype=np.float32)
    rows, cols = (rows - (s - 1) / 2) / s, (cols - (s - 1) / 2) / s  # output-pixel units
    theta = rng.uniform(0, np.pi)
    u = cols * np.cos(theta) + rows * np.sin(theta)
    v = -cols * np.sin(theta) + rows * np.cos(theta)
    if kind == "sine-grating":
        period = rng.uniform(3.0, max(4.0, min(h, w) / 2))
        t = 0.5 + 0.5 * np.sin(2 * np.pi * u / period)
    elif kind == "checker":
        period = rng.uniform(2.0, max(3.0, min(h, w) / 2))
        t = ((np.floor(u / period) + np.floor(v / period)) % 2).astype(np.float32)
    elif kind == "stripes":  # square wave, fine and high contrast
        period = float(2.0 ** rng.uniform(1.0, 4.0))
        duty = rng.uniform(0.3, 0.7)
        t = (np.mod(u / period + rng.random(), 1.0) < duty).astype(np.float32)
    else:  # zone plate cos(π k r²): local frequency k·r cycles/px, f_max at the farthest pixel
        cx, cy = rng.uniform(0, w), rng.uniform(0, h)
        r2 = (cols - cx) ** 2 + (rows - cy) ** 2
        k = rng.uniform(0.25, 0.5) / max(float(r2.max()), 1.0) ** 0.5  # f_max ≤ Nyquist
        t = 0.5 + 0.5 * np.cos(np.pi * k * r2)
    a, b = natural_colours(2, rng)
    if rng.random() < 0.5:  # high contrast: one side dark, the other bright
        a, b = a * 0.1, b / max(float(b.max()), 1e-3)
    out = t[..., None] * a + (1 - t[..., None]) * b
    if s > 1:
        out = _sharp_to_output(np.ascontiguousarray(out, dtype=np.float32), (h, w))
    return finish(out, rng)


def finish(img: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Colour transforms and exposure (see the module doc): (H, W, 3) float32 in [0, 1]."""
    img = np.asarray(img, np.float32)
    if np.ptp(img - img.mean(axis=2, keepdims=True)) < 1e-3:  # grey
        if rng.random() >= GREY_KEPT:  # give it colour
            mix = np.eye(3) * rng.uniform(0.5, 1.0, 3) + rng.uniform(0.0, 0.35, (3, 3))
            img = img @ mix.T.astype(np.float32)
    else:
        lum = img @ np.array([0.2126, 0.7152, 0.0722], np.float32)  # Rec. 709 luminance
        grey = rng.random() < DESATURATED
        sat = np.float32(rng.uniform(0.0, 0.3) if grey else rng.uniform(0.6, 1.4))
        img = np.clip(lum[..., None] + sat * (img - lum[..., None]), 0.0, None)
    img = img * rng.uniform(0.7, 1.0, 3).astype(np.float32)
    bright = rng.random() < BRIGHT_FRACTION
    level = rng.uniform(1.0, 2.5) if bright else rng.uniform(0.4, 1.0)
    img = img / max(percentile(img, 99.5), 1e-6) * np.float32(level)
    return np.clip(img, 0.0, 1.0).astype(np.float32)
