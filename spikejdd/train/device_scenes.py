"""Training scenes rendered with PyTorch on the training device, exact at any time.

The distribution of :func:`spikejdd.train.scenes.draw_scene` (pictures and
textures under camera motion, or moving objects over them; static, slow and
fast speeds from :data:`~spikejdd.train.scenes.SPEED_BINS`), drawn on the host
from one ``numpy`` generator (:func:`draw_device_scene`, a small dict of
numbers) and rendered on the device (:func:`render`): radiance at any time is a
closed-form function of that time — a camera map or object positions applied
to fixed content, sampled bilinearly — so the key frames a simulation
interpolates and the ground truth at the centre readout come from the same
function, the ground truth rendered at its own instant (not interpolated).

Content: crops of the training pictures (:data:`~spikejdd.train.pictures.TRAIN_PICTURES`,
uploaded once per device at 1, ½ and ¼ resolution; a crop shows 1–4 picture
pixels per output pixel, from the level at or below that scale) or procedural
textures (value noise in octaves, gratings, checkers); grey content gets a
random colour mix, all content a random white balance and an exposure that
puts its 99.5th percentile at ``U(0.4, 1)``, clipped to [0, 1].
Motion (``speed`` = the largest content speed, output pixels per second):
camera ``pan``, ``rotation`` and ``zoom`` about the centre, ``shake``
(two-frequency jitter); objects: ``sprites`` (1–4 textured discs moving in
straight lines over a still background) and ``disk`` (a textured disk spinning
about its centre, rim speed ``speed``).
"""

from __future__ import annotations

import math
import threading

import numpy as np
import torch
import torch.nn.functional as F

__all__ = ["draw_device_scene", "render", "DEVICE_KINDS", "DEVICE_CAMERA_MOTIONS"]

#: (kind, probability): camera motion over a picture or texture, or objects.
DEVICE_KINDS: tuple[tuple[str, float], ...] = (
    ("picture", 0.45), ("texture", 0.15), ("sprites", 0.25), ("disk", 0.15))
DEVICE_CAMERA_MOTIONS = ("pan", "rotation", "zoom", "shake")
_SPRITE_SPEED = (1.0, 0.75, 0.55, 0.4)  # relative speeds of sprites 1–4


def _texture_params(rng: np.random.Generator) -> dict:
    kind = ("noise", "grating", "checker")[int(rng.integers(3))]
    if kind == "noise":  # four octaves of 2, 4, 8, 16 cells, each coloured
        return {"texture": kind, "grids": [rng.random((2 ** (o + 1) + 1,) * 2 + (3,)).tolist()
                                           for o in range(4)]}
    return {"texture": kind, "theta": float(rng.uniform(0, math.pi)),
            "period_frac": float(rng.uniform(0.05, 0.5)), "a": rng.random(3).tolist(),
            "b": rng.random(3).tolist()}


def _colour_params(rng: np.random.Generator) -> dict:
    mix = np.eye(3) * rng.uniform(0.5, 1.0, 3) + rng.uniform(0.0, 0.35, (3, 3))
    return {"mix": mix.tolist(), "balance": rng.uniform(0.7, 1.0, 3).tolist(),
            "exposure": float(rng.uniform(0.4, 1.0))}


def _content_params(rng: np.random.Generator, pictures) -> dict:
    """A picture crop (75 %) or a texture, with its colouring."""
    if rng.random() < 0.75:
        out = {"content": str(pictures[int(rng.integers(len(pictures)))]),
               "scale": float(2.0 ** rng.uniform(-2.0, 0.0)),  # output px per picture px
               "at": rng.random(2).tolist(), "flip": bool(rng.integers(2))}
    else:
        out = {"content": "texture", **_texture_params(rng)}
    out["colour"] = _colour_params(rng)
    return out


def draw_device_scene(rng: np.random.Generator, size: tuple[int, int],
                      pictures: tuple[str, ...] | None = None) -> dict:
    """The parameters of one training scene of ``size`` (H, W): plain numbers
    (:func:`render` draws it); keys ``kind``, ``motion``, ``speed_bin``,
    ``speed_px_s``, ``content`` and the kind's own."""
    from spikejdd.train.pictures import TRAIN_PICTURES
    from spikejdd.train.scenes import draw_speed

    pictures = TRAIN_PICTURES if pictures is None else tuple(pictures)
    kinds = [k for k, _ in DEVICE_KINDS]
    kind = kinds[int(rng.choice(len(kinds), p=[p for _, p in DEVICE_KINDS]))]
    speed_bin, speed = draw_speed(rng)
    h, w = size
    p = {"kind": kind, "speed_bin": speed_bin, "speed_px_s": float(speed)}
    if kind in ("picture", "texture"):
        p["background"] = (_content_params(rng, pictures) if kind == "picture"
                           else {"content": "texture", **_texture_params(rng),
                                 "colour": _colour_params(rng)})
        p["motion"] = ("static" if speed == 0
                       else DEVICE_CAMERA_MOTIONS[int(rng.integers(len(DEVICE_CAMERA_MOTIONS)))])
        p["direction"] = float(rng.uniform(0.0, 2 * math.pi))
        p["sign"] = float(rng.choice([-1.0, 1.0]))
        p["shake_hz"] = float(rng.uniform(8.0, 30.0))
        p["shake_phase"] = rng.uniform(0.0, 2 * math.pi, 2).tolist()
        return p
    p["motion"] = kind
    p["background"] = _content_params(rng, pictures)
    if kind == "sprites":
        n = int(rng.integers(1, 5))
        p["radius"] = float(rng.uniform(0.12, 0.3) * min(h, w))
        p["sprites"] = [{"start": [float(rng.uniform(0, w)), float(rng.uniform(0, h))],
                         "angle": float(rng.uniform(0, 2 * math.pi)),
                         "look": {"content": "texture", **_texture_params(rng),
                                  "colour": _colour_params(rng)}} for _ in range(n)]
    else:
        p["radius"] = float(rng.uniform(0.3, 0.45) * min(h, w))
        p["centre"] = [float(w * rng.uniform(0.35, 0.65)), float(h * rng.uniform(0.35, 0.65))]
        p["sign"] = float(rng.choice([-1.0, 1.0]))
        p["look"] = _content_params(rng, pictures)
    return p


# --- content on the device ----------------------------------------------------------
_PICTURES: dict = {}
_PICTURES_LOCK = threading.Lock()


def _picture_levels(name: str, device) -> tuple[list[torch.Tensor], bool]:
    """Picture ``name`` as (3, h, w) float32 tensors at full, ½ and ¼ resolution on
    ``device`` (box-filtered), and whether it is grey; uploaded once per device."""
    key = (name, str(device))
    with _PICTURES_LOCK:
        if key in _PICTURES:
            return _PICTURES[key]
    from spikejdd.train.pictures import load_picture

    pic = load_picture(name)
    grey = float(np.ptp(pic - pic.mean(axis=2, keepdims=True))) < 1e-3
    x = torch.from_numpy(np.ascontiguousarray(pic.transpose(2, 0, 1))).to(device)
    levels = [x]
    for _ in range(2):
        prev = levels[-1]
        if min(prev.shape[1:]) < 4:
            break
        levels.append(F.avg_pool2d(prev[None], 2)[0])
    with _PICTURES_LOCK:
        _PICTURES[key] = (levels, grey)
    return levels, grey


def _texture(p: dict, hc: int, wc: int, device) -> torch.Tensor:
    """(3, hc, wc) procedural texture in [0, 1] (before colouring)."""
    if p["texture"] == "noise":
        out = torch.zeros((1, 3, hc, wc), dtype=torch.float32, device=device)
        for octave, grid in enumerate(p["grids"]):
            g = torch.tensor(grid, dtype=torch.float32, device=device).permute(2, 0, 1)[None]
            out += F.interpolate(g, size=(hc, wc), mode="bicubic", align_corners=True) \
                * 0.5**octave
        out = out[0]
    else:
        rows = torch.arange(hc, dtype=torch.float32, device=device)[:, None]
        cols = torch.arange(wc, dtype=torch.float32, device=device)[None, :]
        th = p["theta"]
        u = cols * math.cos(th) + rows * math.sin(th)
        v = -cols * math.sin(th) + rows * math.cos(th)
        period = max(3.0, p["period_frac"] * min(hc, wc))
        if p["texture"] == "grating":
            t = 0.5 + 0.5 * torch.sin(2 * math.pi * u / period)
        else:
            t = torch.remainder(torch.floor(u / period) + torch.floor(v / period), 2.0)
        a = torch.tensor(p["a"], dtype=torch.float32, device=device).view(3, 1, 1)
        b = torch.tensor(p["b"], dtype=torch.float32, device=device).view(3, 1, 1)
        out = t * a + (1 - t) * b
    out = out - out.min()
    return out / out.max().clamp_min(1e-6)


def _colour(img: torch.Tensor, p: dict, grey: bool,
            window: tuple[slice, slice] | None = None) -> torch.Tensor:
    """Colour mix (grey content), white balance, and the exposure that puts the
    99.5th percentile of ``img[:, window]`` (all of it by default) at
    ``p["exposure"]``; clipped to [0, 1]."""
    dev = img.device
    mix = torch.tensor(p["mix"], dtype=torch.float32, device=dev)
    balance = torch.tensor(p["balance"], dtype=torch.float32, device=dev).view(3, 1, 1)

    def tone(x):
        return (torch.einsum("ij,j...->i...", mix, x) if grey else x) * balance

    flat = tone(img if window is None else img[:, window[0], window[1]]).flatten()
    if flat.numel() > 1 << 20:
        flat = flat[:: flat.numel() // (1 << 20) + 1]
    top = float(torch.quantile(flat, 0.995).clamp_min(1e-6))
    return (tone(img) * (p["exposure"] / top)).clamp(0.0, 1.0)


def _content(p: dict, size: tuple[int, int], device):
    """``(image (3, hc, wc), centre (u, v) in its pixels, its pixels per output pixel)``."""
    h, w = size
    if p["content"] == "texture":
        margin = int(0.5 * max(h, w)) + 8
        hc, wc = h + 2 * margin, w + 2 * margin
        img = _colour(_texture(p, hc, wc, device), p["colour"], grey=False)
        return img, (wc / 2.0, hc / 2.0), 1.0
    levels, grey = _picture_levels(p["content"], device)
    per_px = 1.0 / p["scale"]  # picture pixels per output pixel, 1…4
    level = min(len(levels) - 1, int(math.floor(math.log2(per_px) + 1e-9)))
    img = levels[level]
    per_px /= 2.0**level
    ph, pw = img.shape[1:]
    half_w, half_h = min(pw, w * per_px) / 2, min(ph, h * per_px) / 2
    cu = half_w + p["at"][0] * (pw - 2 * half_w)
    cv = half_h + p["at"][1] * (ph - 2 * half_h)
    if p["flip"]:
        img = img.flip(-1)
    top, left = max(0, int(cv - half_h)), max(0, int(cu - half_w))
    window = (slice(top, top + int(2 * half_h) + 1), slice(left, left + int(2 * half_w) + 1))
    return _colour(img, p["colour"], grey, window), (cu, cv), per_px


def _sample(img: torch.Tensor, u: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """``img`` (3, hc, wc) at continuous pixel coordinates ``u``, ``v`` (…, H, W),
    bilinear, mirrored at the borders: (…, 3, H, W)."""
    hc, wc = img.shape[1:]
    grid = torch.stack([2.0 * u / wc - 1.0, 2.0 * v / hc - 1.0], dim=-1).to(torch.float32)
    lead = grid.shape[:-3]
    g = grid.reshape(1, -1, grid.shape[-2], 2)
    out = F.grid_sample(img[None], g, mode="bilinear", padding_mode="reflection",
                        align_corners=False)  # (1, 3, n·H, W)
    return out[0].reshape(3, *lead, *grid.shape[-3:-1]).movedim(0, -3)


def _pixel_offsets(size, device):
    """(H, W) float64 x and y of each output pixel centre from the frame centre."""
    h, w = size
    y = torch.arange(h, dtype=torch.float64, device=device)[:, None] + 0.5 - h / 2.0
    x = torch.arange(w, dtype=torch.float64, device=device)[None, :] + 0.5 - w / 2.0
    return x.expand(h, w), y.expand(h, w)


def _camera(p: dict, size, t: torch.Tensor, device):
    """Content coordinates (K, H, W) of every output pixel at times ``t`` (K,) s,
    relative to the content centre, in output pixels."""
    h, w = size
    dx, dy = _pixel_offsets(size, device)
    tt = t.view(-1, 1, 1)
    speed, motion = p["speed_px_s"], p["motion"]
    r = math.hypot(h, w) / 2.0  # centre-to-corner distance
    if motion == "pan":
        d = p["direction"]
        return dx + speed * tt * math.cos(d), dy + speed * tt * math.sin(d)
    if motion == "rotation":
        a = p["sign"] * speed / r * tt
        return (torch.cos(a) * dx - torch.sin(a) * dy, torch.sin(a) * dx + torch.cos(a) * dy)
    if motion == "zoom":
        s = torch.exp(p["sign"] * speed / r * tt)
        return s * dx, s * dy
    if motion == "shake":
        f1 = p["shake_hz"]
        f2 = 1.37 * f1
        amp = speed / (2 * math.pi * math.hypot(f1, f2))
        p1, p2 = p["shake_phase"]
        ox = amp * (torch.sin(2 * math.pi * f1 * tt + p1) - math.sin(p1))
        oy = amp * (torch.sin(2 * math.pi * f2 * tt + p2) - math.sin(p2))
        return dx + ox, dy + oy
    return dx.expand(len(t), h, w), dy.expand(len(t), h, w)


def _background(p: dict, size, t, device):
    img, (cu, cv), per_px = _content(p["background"], size, device)
    x, y = _camera(p, size, t, device) if p["kind"] in ("picture", "texture") else \
        [c.expand(len(t), *size) for c in _pixel_offsets(size, device)]
    return _sample(img, cu + per_px * x, cv + per_px * y)


def _disc_alpha(dist: torch.Tensor, radius: float) -> torch.Tensor:
    """Coverage of a disc of ``radius`` with a one-pixel soft rim, (…, H, W) → (…, 1, H, W)."""
    return (radius - dist + 0.5).clamp(0.0, 1.0).unsqueeze(-3).to(torch.float32)


def render(p: dict, times_s, size: tuple[int, int], device) -> torch.Tensor:
    """Radiance of scene ``p`` (:func:`draw_device_scene`) at ``times_s`` (K,)
    seconds: (K, 3, H, W) float32 linear light on ``device``."""
    h, w = size
    t = torch.as_tensor(np.asarray(times_s, np.float64), device=device)
    img = _background(p, size, t, device)
    if p["kind"] in ("picture", "texture"):
        return img.contiguous()
    dx, dy = _pixel_offsets(size, device)
    x, y = dx + w / 2.0, dy + h / 2.0  # pixel centres, output pixels
    radius, speed = p["radius"], p["speed_px_s"]
    tt = t.view(-1, 1, 1)
    if p["kind"] == "sprites":
        side = 2.0 * radius + 3.0
        for k, s in enumerate(p["sprites"]):
            look, _, _ = _content(s["look"], (int(math.ceil(side)),) * 2, device)
            v = speed * _SPRITE_SPEED[k]
            cx = s["start"][0] + v * math.cos(s["angle"]) * tt
            cy = s["start"][1] + v * math.sin(s["angle"]) * tt
            lx, ly = x - cx, y - cy  # (K, H, W)
            hc, wc = look.shape[1:]
            tex = _sample(look, wc / 2.0 + lx * (wc / side), hc / 2.0 + ly * (hc / side))
            a = _disc_alpha(torch.sqrt(lx * lx + ly * ly), radius)
            img = img * (1 - a) + tex * a
        return img.contiguous()
    cx, cy = p["centre"]
    look, (cu, cv), per_px = _content(p["look"], (int(math.ceil(2 * radius + 3)),) * 2, device)
    ang = -p["sign"] * speed / radius * tt  # rim speed = speed
    lx, ly = (x - cx).expand_as(ang * x), (y - cy).expand_as(ang * x)
    ru = torch.cos(ang) * lx - torch.sin(ang) * ly
    rv = torch.sin(ang) * lx + torch.cos(ang) * ly
    tex = _sample(look, cu + per_px * ru, cv + per_px * rv)
    a = _disc_alpha(torch.sqrt(lx * lx + ly * ly), radius)
    return (img * (1 - a) + tex * a).contiguous()
