"""Training scenes with exact radiance, drawn from one random generator.

:func:`draw_scene` returns a ``spikesim`` procedural scene (exact radiance at
any time) and its description.  The distribution (issue: "training on what it
will see", and natural statistics for content it never saw):

* **content** (:data:`CONTENT_MIX`) — half crops at several scales of
  full-resolution pictures (:mod:`spikejdd.train.pictures`, training pictures
  only; scale ``2^U(-2, 0)`` of the picture, so a 32-pixel crop shows 32–128
  picture pixels), 30 % dead-leaves images (occluding shapes with power-law
  sizes and the training pictures' colours) and 20 % procedural textures
  (value noise, sine gratings, checkers, fine square-wave stripes, zone
  plates); all three through :func:`spikejdd.train.content.finish`: a colour
  mix for grey content, saturation, white balance and an exposure up to
  saturation (:mod:`spikejdd.train.content`);
* **motion** (:data:`SCENE_KINDS`) — camera paths over that content (pan,
  rotation, zoom, shake, homography; ``spikesim.scenes.paths``) or object
  motion over it: layered sprites, a fan, a textured disk
  (``spikesim.scenes.layered``);
* **speed** — :data:`SPEED_BINS`: 20 % static, 20 % slow (at most one pixel
  per 39-readout window at 20 kHz, i.e. ≤ 513 px/s), 60 % fast, log-uniform
  from 513 to 4000 px/s.
"""

from __future__ import annotations

import math

import numpy as np

from spikejdd.train.content import dead_leaves, finish, procedural_texture
from spikesim.errors import bad_value
from spikesim.scenes.analytic import ProceduralScene, SplineTexture
from spikesim.scenes.layered import RotatingDisk, Sprites
from spikesim.scenes.paths import make_path, peak_speed
from spikesim.scenes.picture import MovingPicture

__all__ = ["draw_scene", "draw_speed", "draw_content", "content_crop", "procedural_texture",
           "SPEED_BINS", "SLOW_PX_S", "CAMERA_MOTIONS", "SCENE_KINDS", "CONTENT_MIX",
           "ArrayPicture", "ArraySprites", "ArraySpinner"]

#: Readout clock (Hz) and window (readouts) of the training/evaluation sensor.
CLOCK_HZ, WINDOW = 20_000.0, 39
#: Largest speed with at most one pixel of motion per window: 20 kHz / 39 ≈ 513 px/s.
SLOW_PX_S = CLOCK_HZ / WINDOW
#: (bin, probability, (low, high) px/s).
SPEED_BINS: tuple[tuple[str, float, tuple[float, float]], ...] = (
    ("static", 0.2, (0.0, 0.0)), ("slow", 0.2, (0.0, SLOW_PX_S)),
    ("fast", 0.6, (SLOW_PX_S, 4000.0)))
CAMERA_MOTIONS = ("pan", "rotation", "zoom", "shake", "homography")
#: (content, probability) of whatever a scene shows (its picture, background, sprites, disk).
CONTENT_MIX: tuple[tuple[str, float], ...] = (
    ("picture", 0.5), ("dead-leaves", 0.3), ("texture", 0.2))
#: (kind, probability): ``camera`` moves content of :data:`CONTENT_MIX` along a camera path;
#: the others move objects over it.
SCENE_KINDS: tuple[tuple[str, float], ...] = (
    ("camera", 0.6), ("sprites", 0.2), ("fan", 0.1), ("disk", 0.1))
#: Speed given to object scenes that stand still (their classes need speed > 0), px/s.
_STILL = 1e-6


def draw_speed(rng: np.random.Generator) -> tuple[str, float]:
    """(bin, largest content speed in px/s) from :data:`SPEED_BINS`."""
    names = [b[0] for b in SPEED_BINS]
    k = int(rng.choice(len(SPEED_BINS), p=[b[1] for b in SPEED_BINS]))
    lo, hi = SPEED_BINS[k][2]
    if names[k] == "static":
        return "static", 0.0
    if names[k] == "slow":
        return "slow", float(rng.uniform(lo, hi))
    return "fast", float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def content_crop(name: str, size: tuple[int, int], rng: np.random.Generator) -> np.ndarray:
    """A random crop of picture ``name`` at scale ``2^U(-2, 0)``, resized to ``size`` (linear),
    through :func:`spikejdd.train.content.finish`."""
    import cv2

    from spikejdd.train.pictures import load_picture

    pic = load_picture(name)
    h, w = size
    ph, pw = pic.shape[:2]
    scale = 2.0 ** rng.uniform(-2.0, 0.0)  # output pixels per picture pixel, at most 1
    ch = min(ph, max(2, round(h / scale)))
    cw = min(pw, max(2, round(w / scale)))
    top, left = int(rng.integers(0, ph - ch + 1)), int(rng.integers(0, pw - cw + 1))
    crop = np.ascontiguousarray(pic[top:top + ch, left:left + cw])
    interp = cv2.INTER_AREA if (ch > h or cw > w) else cv2.INTER_CUBIC
    out = cv2.resize(crop, (w, h), interpolation=interp)
    if rng.integers(2):
        out = out[:, ::-1]
    return finish(np.clip(out, 0.0, None), rng)


class ArrayPicture(MovingPicture):
    """:class:`spikesim.scenes.picture.MovingPicture` over an in-memory linear image."""

    def __init__(self, image: np.ndarray, motion: str, speed: float, direction_deg: float = 0.0):
        h, w = image.shape[:2]
        ProceduralScene.__init__(self, (h, w), exposure=1.0, max_px=1.0)
        self.name, self.motion, self.direction_deg = "array", motion, float(direction_deg)
        self._path, _ = make_path(motion, h, w, self.direction_deg)
        self._picture = np.asarray(image, np.float32)
        # (a still picture is its own radiance: no spline to prefilter)
        self._texture = None if motion == "static" else SplineTexture(self._picture)
        if motion == "static":
            self.rate = 0.0
            self._set_speed(None)
        else:
            self.rate = speed / peak_speed(motion, h, w, self.direction_deg)
            self._set_speed(speed)
        r, c = np.mgrid[0:h, 0:w].astype(np.float64)
        self._grid = np.stack([c.ravel(), r.ravel(), np.ones(r.size)])


class ArraySprites(Sprites):
    """:class:`spikesim.scenes.layered.Sprites` with in-memory background and sprite images."""

    def __init__(self, background: np.ndarray, sprites: list[np.ndarray], speed: float,
                 radius_frac: float, seed: int):
        h, w = background.shape[:2]
        ProceduralScene.__init__(self, (h, w), exposure=1.0, max_px=1.0)
        self.name = self.motion = "sprites"
        self._set_speed(speed)
        self.background, self.seed, self.n_sprites = "array", int(seed), len(sprites)
        self.radius_frac, self.sprite_images = radius_frac, ("array",) * len(sprites)
        self._bg = np.asarray(background, np.float32)
        self.radius = radius_frac * min(h, w)
        rng = np.random.default_rng(self.seed)
        n = len(sprites)
        self._start = np.stack([rng.uniform(self.radius, w - 1 - self.radius, n),
                                rng.uniform(self.radius, h - 1 - self.radius, n)], 1)
        angle = rng.uniform(0, 2 * np.pi, n)
        factors = np.array([1.0, 0.75, 0.55, 0.4] + [0.3] * 12)[:n]
        self._vel = speed * factors[:, None] * np.stack([np.cos(angle), np.sin(angle)], 1)
        self._side = int(np.ceil(2 * self.radius)) + 3
        self._tex = [SplineTexture(s, mirror=False) for s in sprites]
        self._rows, self._cols = np.mgrid[0:h, 0:w].astype(np.float64)


class ArraySpinner(RotatingDisk):
    """:class:`spikesim.scenes.layered.RotatingDisk` (fan or disk) over an in-memory background."""

    def __init__(self, background: np.ndarray, pattern: str, speed: float, blades: int = 4,
                 texture: np.ndarray | None = None, blade_rgb=(0.85, 0.8, 0.7)):
        h, w = background.shape[:2]
        ProceduralScene.__init__(self, (h, w), exposure=1.0, max_px=1.0)
        if pattern not in ("fan", "disk"):
            raise bad_value("pattern", pattern, "'fan' or 'disk'")
        self.name = self.motion = self.pattern = pattern
        self.blades, self.background, self.texture = int(blades), "array", "array"
        self._build(speed, background, texture, blade_rgb)


def draw_content(rng: np.random.Generator, size: tuple[int, int],
                 pictures: tuple[str, ...]) -> tuple[np.ndarray, str]:
    """(H, W, 3) linear content of :data:`CONTENT_MIX` and its name (a picture's name,
    ``"dead-leaves"`` or ``"texture"``)."""
    kinds = [k for k, _ in CONTENT_MIX]
    kind = kinds[int(rng.choice(len(kinds), p=[p for _, p in CONTENT_MIX]))]
    if kind == "picture":
        name = str(pictures[int(rng.integers(len(pictures)))])
        return content_crop(name, size, rng), name
    if kind == "dead-leaves":
        return finish(dead_leaves(size, rng), rng), kind
    return procedural_texture(size, rng), kind


def draw_scene(rng: np.random.Generator, size: tuple[int, int],
               pictures: tuple[str, ...] | None = None) -> tuple[ProceduralScene, dict]:
    """A training scene of ``size`` (H, W) and its description (kind, content, motion, speed)."""
    from spikejdd.train.pictures import TRAIN_PICTURES

    pictures = TRAIN_PICTURES if pictures is None else tuple(pictures)
    kinds = [k for k, _ in SCENE_KINDS]
    kind = kinds[int(rng.choice(len(kinds), p=[p for _, p in SCENE_KINDS]))]
    speed_bin, speed = draw_speed(rng)
    if kind == "camera":
        img, name = draw_content(rng, size, pictures)
        motion = "static" if speed == 0 else str(rng.choice(CAMERA_MOTIONS))
        direction = float(rng.uniform(0.0, 360.0))
        scene = ArrayPicture(img, motion, speed, direction)
        content = [name]
    else:
        bg, bg_name = draw_content(rng, size, pictures)
        move = speed if speed > 0 else _STILL
        if kind == "sprites":
            n = int(rng.integers(1, 5))
            radius_frac = float(rng.uniform(0.12, 0.3))
            side = int(np.ceil(2 * radius_frac * min(size))) + 3
            tex = [draw_content(rng, (side, side), pictures) for _ in range(n)]
            scene = ArraySprites(bg, [t[0] for t in tex], move, radius_frac,
                                 int(rng.integers(2**31)))
            content = [bg_name] + [t[1] for t in tex]
        else:
            tex, tex_name = draw_content(rng, size, pictures) if kind == "disk" else (None, None)
            scene = ArraySpinner(bg, kind, move, blades=int(rng.integers(2, 7)), texture=tex,
                                 blade_rgb=tuple(rng.uniform(0.2, 1.0, 3)))
            content = [bg_name] + ([tex_name] if tex_name else [])
        motion = kind
    return scene, {"kind": kind, "content": content, "motion": motion,
                   "speed_bin": speed_bin, "speed_px_s": speed}
