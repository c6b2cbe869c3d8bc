"""The held-out benchmark: pictures from a source that training and validation never read.

Generalisation is what a learned reconstructor is judged on, so this set is
split from the training content *by package*: its photographs ship with
scikit-learn, mahotas and plenoptic, while training reads scikit-image,
matplotlib and colour-science and validation reads PyWavelets and glymur
(:mod:`spikejdd.train.pictures`); a test checks that no package serves two
of the three.  The one picture no installed package ships, a page of text, is
rendered here (OpenCV's Hershey fonts, at 4× and area-averaged): training
renders no text.  The pictures are read from the packages' folders without
importing them, so ``pip install --no-deps scikit-learn mahotas plenoptic``
is enough.

Each picture is cropped where its category shows (:data:`HELD_OUT`: centre
and scale, output pixels per picture pixel), decoded to linear light at its
own exposure, and moved along a camera path (:mod:`spikesim.scenes.paths`)
at the benchmark's speeds: static, 150 px/s (under one pixel per 39-readout
window at 20 kHz), 1500 and 3000 px/s.  :func:`held_out_frames` simulates it
on the evaluation sweep's sensor (RGGB, 20 kHz, full_scale_rate 0.6, modulo
reset) at GN σ = 0/5/10/15 and random GPN (``spikejdd.evaluate``), one frame
per cell, seed 0 for every cell (common random numbers); the benchmark
``benchmarks/bench_sjdd.py --held-out`` scores the methods on them.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from spikesim.errors import bad_value

__all__ = ["HeldOutPicture", "HELD_OUT", "CATEGORIES", "SPEEDS", "CLASSICAL",
           "held_out_picture", "held_out_frames", "held_out_packages", "held_out_tables",
           "rendered_text"]


@dataclass(frozen=True)
class HeldOutPicture:
    """One picture of the held-out set: where it is, what it shows and where to crop it."""

    package: str  # importable package that ships it ("" for the rendered text)
    path: str  # inside the package
    description: str
    categories: tuple[str, ...]
    centre: tuple[float, float]  # crop centre, (row, column) as fractions of the picture
    scale: float  # output pixels per picture pixel (≤ 1: picture pixels are averaged)
    motion: str  # camera path of the moving cells


#: Category → what it tests.
CATEGORIES: dict[str, str] = {
    "fine-texture": "detail at the pixel scale: a crowd drawing, tweed, reptile skin",
    "edges": "sharp high-contrast edges: architecture, stripes, petals, letters",
    "bright": "bright and near-saturated regions: sky, a white page, lit nuclei",
    "foliage": "leaves and branches",
    "faces": "human and animal faces",
    "text": "printed letters",
    "flat": "flat or smooth areas: bokeh, a dark field, a white ground",
}
#: Speeds of the table, px/s (0 = static; 150 px/s is under one pixel per window).
SPEEDS: tuple[float, ...] = (0.0, 150.0, 1500.0, 3000.0)

#: name → picture (12, every category at least once).
HELD_OUT: dict[str, HeldOutPicture] = {
    "summer-palace": HeldOutPicture(
        "sklearn", "datasets/images/china.jpg", "a pagoda against a bright sky, trees "
        "(colour)", ("edges", "bright", "foliage"), (0.3, 0.28), 0.3, "pan"),
    "dahlia": HeldOutPicture(
        "sklearn", "datasets/images/flower.jpg", "a dahlia before a smooth dark-green "
        "background (colour)", ("flat",), (0.45, 0.45), 0.2, "zoom"),
    "crowd-drawing": HeldOutPicture(
        "mahotas", "demos/data/DepartmentStore.jpg", "a crowd drawn in fine detail "
        "(colour)", ("fine-texture", "edges"), (0.5, 0.5), 0.35, "shake"),
    "portrait": HeldOutPicture(
        "mahotas", "demos/data/luispedro.jpg", "a man's face against glass (colour)",
        ("faces",), (0.45, 0.5), 0.3, "rotation"),
    "nuclei": HeldOutPicture(
        "mahotas", "demos/data/nuclear.png", "fluorescent nuclei on a dark field, a few "
        "near saturation (colour)", ("flat", "bright"), (0.2, 0.72), 0.25, "pan"),
    "curie": HeldOutPicture(
        "plenoptic", "data/curie.pgm", "a portrait of Marie Curie (grey)", ("faces",),
        (0.5, 0.5), 0.35, "homography"),
    "einstein": HeldOutPicture(
        "plenoptic", "data/einstein.pgm", "a portrait of Albert Einstein in tweed (grey)",
        ("faces", "fine-texture"), (0.45, 0.5), 0.4, "shake"),
    "macaque": HeldOutPicture(
        "plenoptic", "data/macaca_nigra_self-portrait.jpg", "a macaque's face before "
        "foliage (colour)", ("faces", "foliage"), (0.38, 0.5), 0.08, "zoom"),
    "parrot": HeldOutPicture(
        "plenoptic", "data/parrot.png", "a parrot's striped face (grey)", ("edges",),
        (0.45, 0.35), 0.5, "rotation"),
    "reptile-skin": HeldOutPicture(
        "plenoptic", "data/reptile_skin.pgm", "reptile scales (grey)", ("fine-texture",),
        (0.5, 0.5), 0.6, "pan"),
    "colour-wheel": HeldOutPicture(
        "plenoptic", "data/color_wheel.jpg", "overlapping coloured petals on white "
        "(colour)", ("edges", "bright", "flat"), (0.2, 0.25), 0.15, "homography"),
    "text-page": HeldOutPicture(
        "", "", "a rendered page of text, dark ink on white paper (grey)", ("text", "edges"),
        (0.35, 0.3), 0.5, "pan"),
}

_TEXT_LINES = (
    "THE QUICK BROWN FOX JUMPS OVER THE LAZY DOG",
    "Pack my box with five dozen liquor jugs 0123456789",
    "Sphinx of black quartz, judge my vow. (1500 px/s)",
    "How vexingly quick daft zebras jump! 39 readouts",
    "Spike cameras fire when the charge reaches threshold.",
    "Bayer RGGB: red, green, green, blue - 20 kHz clock",
)


@lru_cache(maxsize=1)
def rendered_text() -> np.ndarray:
    """(256, 384, 3) float32 linear page of text: ink 0.02 on paper 0.85, four Hershey
    fonts at several sizes, drawn at 4× and area-averaged (anti-aliased)."""
    import cv2

    k = 4
    page = np.full((256 * k, 384 * k), 255, np.uint8)
    fonts = (cv2.FONT_HERSHEY_SIMPLEX, cv2.FONT_HERSHEY_COMPLEX, cv2.FONT_HERSHEY_DUPLEX,
             cv2.FONT_HERSHEY_TRIPLEX)
    y = 10 * k
    for i, line in enumerate(_TEXT_LINES * 3):
        size = (0.28, 0.36, 0.45, 0.6)[i % 4]
        y += int((24 * size + 9) * k)
        if y > 250 * k:
            break
        cv2.putText(page, line, (6 * k, y), fonts[i % 4], size * k, 0, max(1, k // 2 + i % 2),
                    cv2.LINE_AA)
    small = cv2.resize(page, (384, 256), interpolation=cv2.INTER_AREA).astype(np.float32) / 255
    out = (0.02 + 0.83 * small)[..., None].repeat(3, axis=2)
    out.setflags(write=False)
    return out


def held_out_packages() -> set[str]:
    """The packages the held-out pictures come from."""
    return {p.package for p in HELD_OUT.values() if p.package}


@lru_cache(maxsize=16)
def _full(name: str) -> np.ndarray:
    from spikejdd.train.pictures import package_folder, read_picture

    pic = HELD_OUT[name]
    if not pic.package:
        return rendered_text()
    out = read_picture(package_folder(pic.package) / pic.path, name)
    out.setflags(write=False)
    return out


def held_out_picture(name: str, size: tuple[int, int]) -> np.ndarray:
    """Held-out picture ``name`` cropped to ``size`` = (H, W) around its centre at its scale
    (area-averaged; enlarged instead where the picture is smaller than the crop), float32
    linear light."""
    import cv2

    if name not in HELD_OUT:
        raise bad_value("picture", name, f"one of {sorted(HELD_OUT)}")
    pic, full = HELD_OUT[name], _full(name)
    h, w = (int(v) for v in size)
    ph, pw = full.shape[:2]
    scale = max(pic.scale, h / ph, w / pw)  # the crop fits inside the picture
    ch, cw = min(ph, round(h / scale)), min(pw, round(w / scale))
    top = int(np.clip(round(pic.centre[0] * ph - ch / 2), 0, ph - ch))
    left = int(np.clip(round(pic.centre[1] * pw - cw / 2), 0, pw - cw))
    crop = np.ascontiguousarray(full[top:top + ch, left:left + cw])
    interp = cv2.INTER_AREA if (ch > h or cw > w) else cv2.INTER_CUBIC
    out = cv2.resize(crop, (w, h), interpolation=interp)
    return np.clip(out, 0.0, 1.0).astype(np.float32)


def held_out_frames(size=(48, 64), speeds=SPEEDS, levels=None, pictures=None,
                    context: int = 41, progress: bool = False) -> list:
    """``spikejdd.evaluate.Frame`` objects: every picture × speed × noise level, one frame
    each (GT at the window's centre), groups ``picture``, ``categories``, ``speed_px_s``,
    ``noise``, ``sigma_g``, ``sigma_p``."""
    from tqdm import tqdm

    import spikesim as ss
    from spikejdd.evaluate import GPN_RANGE, SWEEP_LEVELS, frames_from_simulation
    from spikejdd.train.scenes import ArrayPicture

    known = [lv[0] for lv in SWEEP_LEVELS]
    levels = known if levels is None else list(levels)
    if not levels or set(levels) - set(known):
        raise bad_value("levels", levels, f"labels among {known}")
    pictures = list(HELD_OUT) if pictures is None else list(pictures)
    if not pictures or set(pictures) - set(HELD_OUT):
        raise bad_value("pictures", pictures, f"names among {sorted(HELD_OUT)}")
    size = tuple(int(v) for v in size)
    rng = np.random.default_rng(0)
    gpn = {name: (float(rng.uniform(*GPN_RANGE["sigma_g"])),
                  float(rng.uniform(*GPN_RANGE["sigma_p"]))) for name in HELD_OUT}
    frames = []
    jobs = [(lv, name, speed) for lv in SWEEP_LEVELS if lv[0] in levels
            for name in pictures for speed in speeds]
    for (label, sg, sp), name, speed in tqdm(jobs, desc="held-out", disable=not progress):
        if sg is None:
            sg, sp = gpn[name]
        noise = ss.noise.PaperNoise(sigma_g=sg, sigma_p=sp) if (sg or sp) else None
        sensor = ss.Sensor(height=size[0], width=size[1], cfa="RGGB", clock_hz=20_000.0,
                           full_scale_rate=0.6, noise=noise)
        pic = HELD_OUT[name]
        motion = "static" if speed == 0 else pic.motion
        direction = 30.0 * list(HELD_OUT).index(name)
        scene = ArrayPicture(held_out_picture(name, size), motion, float(speed), direction)
        frames += frames_from_simulation(
            scene, sensor, f"{name}-{motion}", [context // 2], context, seed=0,
            group={"picture": name, "categories": list(pic.categories), "motion": motion,
                   "speed_px_s": float(speed), "noise": label, "sigma_g": sg, "sigma_p": sp})
    return frames


#: The classical pipelines the benchmark compares against (the best one per cell).
CLASSICAL: tuple[str, ...] = ("tfp+malvar2004", "tfp+menon2007", "tfp+menon2007+bilateral",
                              "tfp+menon2007+nlm", "tfp39+menon2007+nlm", "tfi+menon2007+nlm")


def held_out_tables(rows: list[dict], method: str, classical=CLASSICAL) -> dict:
    """Tables of ``method`` against the best of ``classical`` from ``spikejdd.evaluate.run``
    rows of :func:`held_out_frames` (PSNR linear, dB).

    A *cell* is one picture × speed × noise level; its delta is ``method`` minus the
    best classical pipeline of that cell.  Returns ``cells`` (every cell: both PSNRs,
    the winning pipeline, the delta), ``by_picture`` (picture → speed → mean delta and
    PSNR over the noise levels given, and at GN10 alone), ``by_category`` (category →
    speed → mean delta over its pictures), ``by_noise`` (level → mean delta and PSNRs
    over every picture and speed), ``wins`` (pipeline → cells it was best in) and
    ``summary`` (overall mean delta, mean at GN10, the smallest GN10 delta on static and
    slow cells and where)."""
    psnr: dict = {}
    for r in rows:
        key = (r["picture"], float(r["speed_px_s"]), r["noise"])
        psnr.setdefault(key, {})[r["method"]] = float(r["PSNR[linear]"])
    cells = []
    for (pic, speed, noise), by in psnr.items():
        if method not in by or not all(m in by for m in classical):
            raise bad_value("rows", f"{pic}/{speed}/{noise}",
                            f"rows of {method} and every one of {list(classical)}")
        best = max(classical, key=lambda m: by[m])
        cells.append({"picture": pic, "categories": list(HELD_OUT[pic].categories),
                      "speed_px_s": speed, "noise": noise, "psnr": by[method],
                      "best_classical": best, "classical_psnr": by[best],
                      "delta_db": by[method] - by[best]})

    def mean(sel, key="delta_db"):
        return float(np.mean([c[key] for c in sel])) if sel else float("nan")

    speeds = sorted({c["speed_px_s"] for c in cells})
    pictures = list(dict.fromkeys(c["picture"] for c in cells))
    gn10 = [c for c in cells if c["noise"] == "GN10"]
    by_picture = {}
    for p in pictures:
        row = {}
        for s in speeds:
            sel = [c for c in cells if c["picture"] == p and c["speed_px_s"] == s]
            sel10 = [c for c in sel if c["noise"] == "GN10"]
            row[str(s)] = {"delta_db": mean(sel), "psnr": mean(sel, "psnr"),
                           "classical_psnr": mean(sel, "classical_psnr"),
                           "delta_db_gn10": mean(sel10), "psnr_gn10": mean(sel10, "psnr"),
                           "classical_psnr_gn10": mean(sel10, "classical_psnr")}
        by_picture[p] = row
    by_category = {}
    for cat in CATEGORIES:
        members = [p for p in pictures if cat in HELD_OUT[p].categories]
        if members:
            by_category[cat] = {"pictures": members, **{
                str(s): {"delta_db": mean([c for c in cells if c["picture"] in members
                                           and c["speed_px_s"] == s]),
                         "delta_db_gn10": mean([c for c in gn10 if c["picture"] in members
                                                and c["speed_px_s"] == s])}
                for s in speeds}}
    by_noise = {n: {"delta_db": mean(sel), "psnr": mean(sel, "psnr"),
                    "classical_psnr": mean(sel, "classical_psnr")}
                for n in dict.fromkeys(c["noise"] for c in cells)
                for sel in [[c for c in cells if c["noise"] == n]]}
    wins: dict = {}
    for c in cells:
        wins[c["best_classical"]] = wins.get(c["best_classical"], 0) + 1
    still = [c for c in gn10 if c["speed_px_s"] <= 150.0]
    worst = min(still, key=lambda c: c["delta_db"]) if still else None
    summary = {"mean_delta_db": mean(cells), "mean_delta_db_gn10": mean(gn10),
               "min_delta_db_gn10_static_slow": worst["delta_db"] if worst else None,
               "worst_gn10_static_slow": ({k: worst[k] for k in ("picture", "speed_px_s")}
                                          if worst else None),
               "pictures_at_least_equal_gn10_static_slow": sorted(
                   {c["picture"] for c in still} - {c["picture"] for c in still
                                                     if c["delta_db"] < 0})}
    return {"method": method, "classical": list(classical), "speeds_px_s": speeds,
            "cells": cells, "by_picture": by_picture, "by_category": by_category,
            "by_noise": by_noise, "wins": wins, "summary": summary}
