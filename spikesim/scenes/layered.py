"""Layered scenes with occlusion: sprites over a background, a rotating fan or disk.

Every layer has an analytic shape whose edge is anti-aliased by a linear
ramp one pixel wide (coverage ``clip(R + ½ − d, 0, 1)`` for a pixel centre at
distance ``d`` from a disk of radius ``R``), so the radiance is continuous in
time and exact at every instant.  Layers are composited front over back
(Porter & Duff, "Compositing digital images", SIGGRAPH 1984, the *over*
operator): a near layer hides what is behind it, and the hidden background
is revealed again when it moves on — the occlusions that optical-flow
interpolation must handle.
"""

from __future__ import annotations

import numpy as np

from spikesim._validate import check_positive
from spikesim.errors import bad_value
from spikesim.scenes.analytic import ProceduralScene, SplineTexture
from spikesim.scenes.sources import load_image

__all__ = ["Sprites", "RotatingDisk"]


def _fold(x: np.ndarray | float, lo: float, hi: float) -> np.ndarray | float:
    """Reflect ``x`` into ``[lo, hi]`` (a bouncing trajectory; triangle wave)."""
    span = hi - lo
    if span <= 0:
        return lo + 0 * x
    y = np.mod(np.asarray(x) - lo, 2 * span)
    return lo + np.where(y > span, 2 * span - y, y)


class Sprites(ProceduralScene):
    """Textured disks bouncing over a still background, nearest first.

    Sprite ``k`` moves at ``speed · (1, 0.75, 0.55, 0.4, ...)[k]`` pixels per
    second in a direction drawn from ``seed`` and bounces off the frame edges.
    Its texture is a bundled picture (``sprite_images``) cover-resized to the
    disk; the background is ``background`` (a bundled picture).
    """

    def __init__(
        self,
        size: tuple[int, int] = (256, 256),
        speed: float | None = 500.0,
        *,
        background: str = "coffee",
        n_sprites: int = 3,
        radius_frac: float = 0.16,
        sprite_images: tuple[str, ...] = ("astronaut", "chelsea", "rocket"),
        seed: int = 0,
        max_px: float = 1.0,
        exposure: float = 1.0,
    ):
        super().__init__(size, exposure=exposure, max_px=max_px)
        self.name, self.motion = "sprites", "sprites"
        if not isinstance(n_sprites, int | np.integer) or not 1 <= n_sprites <= 16:
            raise bad_value("n_sprites", n_sprites, "an integer in 1..16")
        radius_frac = check_positive("radius_frac", radius_frac)
        if radius_frac >= 0.5:
            raise bad_value("radius_frac", radius_frac, "0 < radius_frac < 0.5")
        speed = check_positive("speed", speed)
        self._set_speed(speed)
        self.background, self.seed = background, int(seed)
        self.n_sprites, self.radius_frac = int(n_sprites), radius_frac
        self.sprite_images = tuple(sprite_images)
        h, w = self.height, self.width
        self._bg = load_image(background, (h, w))
        self.radius = radius_frac * min(h, w)
        rng = np.random.default_rng(self.seed)
        r = self.radius  # (a side under 2r + 1 pixels leaves the sprites no room: they stay at r)
        self._start = np.stack(
            [rng.uniform(r, max(r, w - 1 - r), n_sprites),
             rng.uniform(r, max(r, h - 1 - r), n_sprites)], 1)
        angle = rng.uniform(0, 2 * np.pi, n_sprites)
        factors = np.array([1.0, 0.75, 0.55, 0.4] + [0.3] * 12)[:n_sprites]
        self._vel = speed * factors[:, None] * np.stack([np.cos(angle), np.sin(angle)], 1)
        side = int(np.ceil(2 * self.radius)) + 3
        self._tex = [
            SplineTexture(load_image(self.sprite_images[k % len(self.sprite_images)], (side, side)),
                          mirror=False)
            for k in range(n_sprites)
        ]
        self._side = side
        self._rows, self._cols = np.mgrid[0:h, 0:w].astype(np.float64)

    def centres(self, t: float) -> np.ndarray:
        """(n, 2) sprite centres (x=col, y=row) at ``t`` seconds."""
        pos = self._start + self._vel * t
        r = self.radius
        x = _fold(pos[:, 0], r, self.width - 1 - r)
        y = _fold(pos[:, 1], r, self.height - 1 - r)
        return np.stack([x, y], 1)

    def _render(self, t: float) -> np.ndarray:
        out = self._bg.copy()
        half = (self._side - 1) / 2.0
        for k in reversed(range(self.n_sprites)):  # back to front
            cx, cy = self.centres(t)[k]
            r0, r1 = max(0, int(cy - self.radius - 2)), min(self.height, int(cy + self.radius + 3))
            c0, c1 = max(0, int(cx - self.radius - 2)), min(self.width, int(cx + self.radius + 3))
            if r0 >= r1 or c0 >= c1:
                continue
            dy = self._rows[r0:r1, c0:c1] - cy
            dx = self._cols[r0:r1, c0:c1] - cx
            alpha = np.clip(self.radius + 0.5 - np.hypot(dx, dy), 0.0, 1.0)[..., None]
            colour = self._tex[k].sample(dy + half, dx + half)
            patch = out[r0:r1, c0:c1]
            out[r0:r1, c0:c1] = alpha * colour + (1 - alpha) * patch
        return out

    def _options(self) -> dict:
        return {"background": self.background, "n_sprites": self.n_sprites,
                "radius_frac": self.radius_frac, "sprite_images": list(self.sprite_images),
                "seed": self.seed}


class RotatingDisk(ProceduralScene):
    """A fan (``pattern="fan"``) or textured disk (``"disk"``) spinning over a still background.

    The disk has radius ``0.4 · min(H, W)`` about the frame centre; ``speed`` is
    the rim speed in pixels per second (angular speed ``speed / R`` rad/s), the
    largest content speed in the scene.  The fan has ``blades`` opaque blades of
    angular half-width ``π / (2·blades)`` and a hub of radius ``0.18 R``; the
    background shows between the blades.
    """

    def __init__(
        self,
        size: tuple[int, int] = (256, 256),
        speed: float | None = 500.0,
        *,
        pattern: str = "fan",
        blades: int = 4,
        background: str = "astronaut",
        texture: str = "rocket",
        max_px: float = 1.0,
        exposure: float = 1.0,
    ):
        super().__init__(size, exposure=exposure, max_px=max_px)
        if pattern not in ("fan", "disk"):
            raise bad_value("pattern", pattern, "'fan' or 'disk'")
        if not isinstance(blades, int | np.integer) or not 1 <= blades <= 64:
            raise bad_value("blades", blades, "an integer in 1..64")
        self.name = self.motion = pattern
        self.pattern, self.blades = pattern, int(blades)
        self.background, self.texture = background, texture
        h, w = self.height, self.width
        self._build(check_positive("speed", speed), load_image(background, (h, w)),
                    load_image(texture, (h, w)) if pattern == "disk" else None)

    def _build(self, speed: float, background: np.ndarray, texture: np.ndarray | None,
               blade_rgb=(0.85, 0.8, 0.7)) -> None:
        """The disk's geometry over ``background`` (H, W, 3) linear radiance; ``texture``
        (same shape) is what a ``disk`` carries; ``speed`` is the rim speed in px/s."""
        self._set_speed(speed)
        h, w = self.height, self.width
        self.radius = 0.4 * min(h, w)
        self.omega = speed / self.radius
        self._bg = np.asarray(background, np.float32)
        rows, cols = np.mgrid[0:h, 0:w].astype(np.float64)
        self._cx, self._cy = (w - 1) / 2.0, (h - 1) / 2.0
        self._dx, self._dy = cols - self._cx, rows - self._cy
        self._r = np.hypot(self._dx, self._dy)
        self._phi = np.arctan2(self._dy, self._dx)
        self._rim = np.clip(self.radius + 0.5 - self._r, 0.0, 1.0)
        if self.pattern == "disk":
            self._tex = SplineTexture(np.asarray(texture, np.float32))
        self._blade_rgb = np.asarray(blade_rgb, np.float32)
        self._hub = np.clip(0.18 * self.radius + 0.5 - self._r, 0.0, 1.0)

    def _render(self, t: float) -> np.ndarray:
        theta = self.omega * t
        if self.pattern == "disk":
            c, s = np.cos(theta), np.sin(theta)
            # output pixel shows the texture point rotated back by theta about the centre
            cols = self._cx + c * self._dx + s * self._dy
            rows = self._cy - s * self._dx + c * self._dy
            fg = self._tex.sample(rows, cols)
            alpha = self._rim[..., None]
        else:
            period = 2 * np.pi / self.blades
            rel = np.mod(self._phi - theta + period / 2, period) - period / 2
            half_width = period / 4
            # distance in pixels from the blade edge, measured along the arc
            cover = np.clip((half_width - np.abs(rel)) * self._r + 0.5, 0.0, 1.0)
            alpha = (np.maximum(cover, self._hub) * self._rim)[..., None]
            fg = self._blade_rgb
        return (alpha * fg + (1 - alpha) * self._bg).astype(np.float32)

    def _options(self) -> dict:
        return {"pattern": self.pattern, "blades": self.blades, "background": self.background,
                "texture": self.texture, "omega_rad_s": self.omega}
