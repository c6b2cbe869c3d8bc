"""Validation on a Table-1-shaped sweep with static and slow scenes, on a source of its own.

The sweep has the benchmark's shape (``spikejdd.evaluate.SWEEP_SETS`` /
``SWEEP_LEVELS``): an object-motion set (sprites, fan, disk) and a
camera-motion set (pan, shake, zoom), at GN σ = 0/5/10/15 and random GPN, and
adds the speed axis — each scene at every speed of ``speeds`` (default 0 =
static, 150 px/s (slow: under one pixel per window), 1500 and 3000 px/s).  Its
pictures are :data:`spikejdd.train.pictures.VALIDATION_PICTURES`, from
packages (PyWavelets, glymur) that neither training nor the benchmarks read,
so the chosen checkpoint is the one that does best on content it never saw —
as users' content is — without being chosen on the held-out benchmark
(:mod:`spikejdd.heldout`) itself.

:func:`validation_frames` simulates the frames once (fixed seed 0, common
random numbers across levels as the benchmark does); :func:`validate_model`
scores a model on them (PSNR, linear light, clamped, peak 1), per speed and
per noise level; :func:`bench_row` compares that with the classical pipelines
on the same frames (sjdd minus the best classical, dB).
"""

from __future__ import annotations

import time

import numpy as np
import torch

from spikesim.errors import bad_value

__all__ = ["VAL_SCENES", "SPRITE_PICTURES", "DISK_PICTURE", "validation_pictures",
           "validation_frames", "validate_model", "classical_scores", "bench_row"]

#: set → [(scene, picture or background, motion)]
VAL_SCENES: dict[str, list[tuple[str, str, str]]] = {
    "object": [("sprites", "snowy_street", "sprites"), ("fan", "ascent", "fan"),
               ("disk", "aero", "disk")],
    "camera": [("snowy_street", "snowy_street", "pan"), ("lit_glass", "lit_glass", "shake"),
               ("ascent", "ascent", "zoom")],
}
#: The sprites' pictures and the disk's (object set).
SPRITE_PICTURES: tuple[str, ...] = ("lit_glass", "aero", "ascent")
DISK_PICTURE = "lit_glass"
_STILL = 1e-6  # px/s for object scenes that stand still


def validation_pictures() -> list[str]:
    """Every picture the validation sweep shows (backgrounds, sprites, the disk)."""
    names = [p for scenes in VAL_SCENES.values() for _, p, _ in scenes]
    return list(dict.fromkeys(names + list(SPRITE_PICTURES) + [DISK_PICTURE]))


def _scene(name: str, picture: str, motion: str, size, speed: float):
    from spikejdd.train.pictures import load_picture
    from spikejdd.train.scenes import ArrayPicture, ArraySpinner, ArraySprites
    from spikesim.scenes.sources import cover_resize

    bg = cover_resize(load_picture(picture), size)
    if motion in ("sprites", "fan", "disk"):
        move = speed if speed > 0 else _STILL
        if motion == "sprites":
            side = int(np.ceil(2 * 0.16 * min(size))) + 3
            tex = [cover_resize(load_picture(p), (side, side)) for p in SPRITE_PICTURES]
            return ArraySprites(bg, tex, move, 0.16, seed=0)
        tex = cover_resize(load_picture(DISK_PICTURE), size) if motion == "disk" else None
        return ArraySpinner(bg, motion, move, texture=tex)
    return ArrayPicture(bg, "static" if speed == 0 else motion, speed)


def validation_frames(size=(48, 64), speeds=(0.0, 150.0, 1500.0, 3000.0), levels=None,
                      context: int = 41, backend: str = "numba", device=None) -> list:
    """``spikejdd.evaluate.Frame`` objects of the validation sweep (see the module doc),
    simulated by ``backend`` on ``device`` (``spikesim.simulate``: the same bits)."""
    import spikesim as ss
    from spikejdd.evaluate import GPN_RANGE, SWEEP_LEVELS, frames_from_simulation

    known = [lv[0] for lv in SWEEP_LEVELS]
    levels = known if levels is None else list(levels)
    bad = sorted(set(levels) - set(known))
    if bad or not levels:
        raise bad_value("val_levels", levels, f"labels among {known}")
    size = tuple(int(v) for v in size)
    rng = np.random.default_rng(0)
    frames = []
    for label, sg, sp in SWEEP_LEVELS:
        gpn = (float(rng.uniform(*GPN_RANGE["sigma_g"])), float(rng.uniform(*GPN_RANGE["sigma_p"])))
        if label not in levels:
            continue
        if sg is None:
            sg, sp = gpn
        noise = ss.noise.PaperNoise(sigma_g=sg, sigma_p=sp) if (sg or sp) else None
        sensor = ss.Sensor(height=size[0], width=size[1], cfa="RGGB", clock_hz=20_000.0,
                           full_scale_rate=0.6, noise=noise)
        for set_name, scenes in VAL_SCENES.items():
            for name, picture, motion in scenes:
                for speed in speeds:
                    scene = _scene(name, picture, motion, size, float(speed))
                    frames += frames_from_simulation(
                        scene, sensor, f"{name}-{motion}", [context // 2], context, seed=0,
                        backend=backend, device=device,
                        group={"set": set_name, "noise": label, "scene": f"{name}-{motion}",
                               "speed_px_s": float(speed), "sigma_g": sg, "sigma_p": sp})
    return frames


def _means(rows: list[dict], key: str) -> dict:
    out: dict = {}
    for r in rows:
        out.setdefault(str(r[key]), []).append(r["psnr"])
    return {k: float(np.mean(v)) for k, v in out.items()}


@torch.no_grad()
def validate_model(model, frames: list, device) -> dict:
    """Mean PSNR (dB, linear) of ``model`` on ``frames``, overall, per speed and per noise."""
    from spikejdd.metrics import psnr
    from spikejdd.models.adapter import model_inputs

    was_training = model.training
    model.eval()
    rows, t0 = [], time.perf_counter()
    for f in frames:
        x, m = model_inputs(f.spikes, f.cfa, f.center, model.config.n_readouts)
        out, _ = model(x.to(device), m.to(device))
        img = out[0].float().clamp(0, 1).permute(1, 2, 0).cpu().numpy()
        rows.append(dict(f.group, psnr=psnr(img, f.gt)))
    ms = 1000 * (time.perf_counter() - t0) / max(1, len(frames))
    if was_training:
        model.train()
    return {"psnr_linear": float(np.mean([r["psnr"] for r in rows])), "frames": len(rows),
            "by_speed": _means(rows, "speed_px_s"), "by_noise": _means(rows, "noise"),
            "rows": rows, "ms_per_frame": ms}


def classical_scores(frames: list, methods: list[str]) -> dict:
    """method → the summary of :func:`validate_model` (PSNR per frame by ``evaluate.run``)."""
    from spikejdd import evaluate

    res = evaluate.run(frames, list(methods), repeats=1, progress=False)
    out = {}
    for m in methods:
        rows = [dict(r, psnr=r["PSNR[linear]"]) for r in res["rows"] if r["method"] == m]
        out[m] = {"psnr_linear": float(np.mean([r["psnr"] for r in rows])),
                  "by_speed": _means(rows, "speed_px_s"), "by_noise": _means(rows, "noise"),
                  "rows": rows}
    return out


def bench_row(step: int, sjdd: dict, classical: dict) -> dict:
    """One benchmark row: sjdd minus the best classical pipeline (dB), overall, per speed and
    per noise level (the best pipeline chosen per cell)."""
    best = max(classical, key=lambda m: classical[m]["psnr_linear"])
    row = {"step": step, "sjdd_psnr": sjdd["psnr_linear"], "best_classical": best,
           "classical_psnr": classical[best]["psnr_linear"],
           "delta_db": sjdd["psnr_linear"] - classical[best]["psnr_linear"],
           "sjdd_ms_per_frame": sjdd.get("ms_per_frame")}
    for axis in ("by_speed", "by_noise"):
        row[f"delta_{axis}"] = {
            k: v - max(c[axis][k] for c in classical.values()) for k, v in sjdd[axis].items()}
    return row
