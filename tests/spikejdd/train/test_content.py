"""Training content: dead leaves, textures and exposure (spikejdd.train.content)."""

from __future__ import annotations

import numpy as np
import pytest

from spikejdd.train.content import (
    BRIGHT_FRACTION,
    DESATURATED,
    GREY_KEPT,
    TEXTURE_KINDS,
    _colour_pool,
    _mean_square_radius,
    _rasterise,
    dead_leaves,
    finish,
    percentile,
    powerlaw_radii,
    procedural_texture,
)
from spikejdd.train.scenes import CONTENT_MIX, draw_content, draw_scene
from spikesim.errors import SpikeSimValueError


def test_radii_follow_the_inverse_cube_law():
    rng = np.random.default_rng(0)
    r_min, r_max, n = 1.0, 64.0, 200_000
    r = powerlaw_radii(n, r_min, r_max, rng)
    assert r.min() >= r_min and r.max() <= r_max
    # survival function of p(r) ∝ r^-3 on [r_min, r_max]: (x^-2 − r_max^-2) / (r_min^-2 − r_max^-2)
    for x in (1.5, 2.0, 4.0, 8.0, 16.0):
        want = (x**-2 - r_max**-2) / (r_min**-2 - r_max**-2)
        got = np.mean(r > x)
        # binomial standard error ≤ 0.0012 at n = 200k: 5 sigma
        assert abs(got - want) < 0.006, (x, got, want)
    # log-log slope of the density between 2 and 16 px: −3
    edges = np.geomspace(2.0, 16.0, 9)
    counts, _ = np.histogram(r, edges)
    density = counts / np.diff(edges)
    slope = np.polyfit(np.log(np.sqrt(edges[1:] * edges[:-1])), np.log(density), 1)[0]
    assert slope == pytest.approx(-3.0, abs=0.1)
    assert np.mean(r**2) == pytest.approx(_mean_square_radius(r_min, r_max), rel=0.03)
    assert _mean_square_radius(1.0, 8.0, alpha=4.0) == pytest.approx(
        np.mean(powerlaw_radii(400_000, 1.0, 8.0, rng, alpha=4.0) ** 2), rel=0.02)
    with pytest.raises(SpikeSimValueError, match="r_min"):
        powerlaw_radii(3, 2.0, 1.0, rng)
    with pytest.raises(SpikeSimValueError, match="alpha"):
        powerlaw_radii(3, 1.0, 2.0, rng, alpha=1.0)


def test_dead_leaves_have_the_power_spectrum_of_natural_images():
    # scale invariance (Lee, Mumford & Huang 2001): power ∝ 1/f^γ with γ near 2
    slopes = []
    for i in range(6):
        img = dead_leaves((128, 128), np.random.default_rng([1, i]), r_min=1.0,
                          texture=False, blur=False).mean(axis=2)
        spec = np.abs(np.fft.fft2(img - img.mean())) ** 2
        fy, fx = np.meshgrid(np.fft.fftfreq(128) * 128, np.fft.fftfreq(128) * 128,
                             indexing="ij")
        f = np.hypot(fx, fy)
        bands = np.geomspace(3, 40, 8)
        power = [spec[(f >= a) & (f < b)].mean() for a, b in zip(bands[:-1], bands[1:],
                                                                 strict=True)]
        mid = np.sqrt(bands[1:] * bands[:-1])
        slopes.append(np.polyfit(np.log(mid), np.log(power), 1)[0])
    assert -2.8 < np.median(slopes) < -1.6, slopes


def test_dead_leaves_are_reproducible_and_in_range():
    a = dead_leaves((40, 56), np.random.default_rng([3, 1]))
    b = dead_leaves((40, 56), np.random.default_rng([3, 1]))
    c = dead_leaves((40, 56), np.random.default_rng([3, 2]))
    assert a.shape == (40, 56, 3) and a.dtype == np.float32
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    assert np.isfinite(a).all() and a.min() >= 0
    # the leaves' colours are pixels of the training pictures: in [0, 1] before texture
    flat = dead_leaves((40, 56), np.random.default_rng(4), texture=False, blur=False)
    assert flat.max() <= 1.0 + 1e-6
    pool = _colour_pool()
    assert pool.min() >= 0 and pool.max() <= 1 and len(pool) > 10_000


def test_dead_leaves_occlude_front_to_back_like_a_painter():
    # leaf 0 in front: the label of each pixel is the smallest index covering it,
    # whichever rasteriser (stamp or OpenCV fill) drew the leaf
    rng = np.random.default_rng(2)
    n = 60
    cx, cy = rng.uniform(0, 40, n), rng.uniform(0, 30, n)
    a = np.concatenate([rng.uniform(0.5, 3.0, 40), rng.uniform(5, 12, 20)])
    b = a * rng.uniform(0.4, 1.0, n)
    angle = rng.uniform(0, np.pi, n)
    rect = rng.random(n) < 0.3
    reach = a * np.where(rect, np.sqrt(1 + (b / a) ** 2), 1.0)
    label = _rasterise(30, 40, cx, cy, a, b, angle, rect, reach)
    rows, cols = np.indices((30, 40))
    want = np.full((30, 40), n)
    for k in range(n - 1, -1, -1):  # the painter, from the back, with exact inside tests
        dx, dy = cols - cx[k], rows - cy[k]
        u = (dx * np.cos(angle[k]) + dy * np.sin(angle[k])) / a[k]
        v = (-dx * np.sin(angle[k]) + dy * np.cos(angle[k])) / b[k]
        inside = (np.maximum(abs(u), abs(v)) <= 1) if rect[k] else (u * u + v * v <= 1)
        want[inside] = k
    # OpenCV's fill rounds edges to 1/16 pixel and its own polygon of the ellipse: a few
    # pixels on the large leaves' borders may differ, nothing else, and without a bias
    assert np.mean(label == want) > 0.97
    cover_got, cover_want = np.mean(label < n), np.mean(want < n)
    assert abs(cover_got - cover_want) < 0.01
    small = reach <= 6
    assert small.sum() == 40
    assert set(np.unique(label)) <= set(range(n + 1))


@pytest.mark.parametrize("seed", range(12))
def test_textures_and_exposure_stay_in_range(seed):
    rng = np.random.default_rng([9, seed])
    t = procedural_texture((24, 40), rng)
    assert t.shape == (24, 40, 3) and t.dtype == np.float32
    assert t.min() >= 0 and t.max() <= 1 and np.isfinite(t).all()
    img, name = draw_content(rng, (16, 20), ("camera", "coins"))
    assert name in {"camera", "coins", "dead-leaves", "texture"}
    assert img.shape == (16, 20, 3) and img.min() >= 0 and img.max() <= 1


def test_every_texture_kind_is_drawn_and_reproducible():
    kinds = set()
    for i in range(60):
        rng = np.random.default_rng([4, i])
        kinds.add(TEXTURE_KINDS[int(np.random.default_rng([4, i]).integers(len(TEXTURE_KINDS)))])
        a = procedural_texture((12, 12), rng)
        np.testing.assert_array_equal(a, procedural_texture((12, 12),
                                                            np.random.default_rng([4, i])))
    assert kinds == set(TEXTURE_KINDS)


def test_exposure_reaches_saturation_in_a_fifth_of_the_images():
    base = np.random.default_rng(0).random((32, 32, 3)).astype(np.float32)
    sat = [np.mean(finish(base, np.random.default_rng([6, i])) >= 1.0) > 0.005
           for i in range(1000)]
    # a binomial(1000, 0.2) share: 5 sigma = 0.063
    assert abs(np.mean(sat) - BRIGHT_FRACTION) < 0.065
    grey = np.repeat(base[..., :1], 3, axis=2)

    def chroma(x):  # spread of the channels about their mean, normalised
        return np.abs(x - x.mean(axis=2, keepdims=True)).mean() / max(x.mean(), 1e-6)

    # grey content: a third stays grey, tinted by the white balance alone (channel gains
    # within [0.7, 1]); the rest gets a colour mix, whose gains reach outside that
    ratios, kept = [], []
    for i in range(600):
        out = finish(grey, np.random.default_rng([7, i]))
        gains = (out / np.maximum(grey, 1e-6)).reshape(-1, 3)[grey.reshape(-1, 3)[:, 0] > 0.05]
        gains = np.median(gains, axis=0)
        ratios.append(gains.max() / gains.min())
        kept.append(np.random.default_rng([7, i]).random() < GREY_KEPT)
    ratios, kept = np.array(ratios), np.array(kept)
    assert abs(kept.mean() - GREY_KEPT) < 0.1
    assert ratios[kept].max() <= 1 / 0.7 + 1e-3
    assert np.mean(ratios[~kept] > 1 / 0.7) > 0.3
    # colour content: 15 % desaturated to at most 30 % of its chroma
    before = chroma(base)
    dull = [chroma(finish(base, np.random.default_rng([8, i]))) < 0.45 * before
            for i in range(600)]
    assert abs(np.mean(dull) - DESATURATED) < 0.08


def test_percentile_is_numpys():
    x = np.random.default_rng(3).random(1001).astype(np.float32)
    for q in (0.0, 50.0, 99.5, 100.0):
        assert percentile(x, q) == pytest.approx(float(np.percentile(x, q)), rel=1e-6)


def test_the_content_mix_is_drawn_as_documented():
    names = []
    for i in range(300):
        _, desc = draw_scene(np.random.default_rng([8, i]), (8, 8))
        names += desc["content"]
    share = {k: np.mean([n == k for n in names]) for k in ("dead-leaves", "texture")}
    want = dict(CONTENT_MIX)
    assert abs(share["dead-leaves"] - want["dead-leaves"]) < 0.08
    assert abs(share["texture"] - want["texture"]) < 0.08
