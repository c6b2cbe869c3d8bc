"""Training pictures: every suitable picture that installed packages ship, minus the test ones.

Sources (read from the packages' own folders, no downloads):

* scikit-image ``skimage/data`` — every colour or grey photograph and
  micrograph it installs (binary masks, tiny face crops, multi-page stacks and
  GIFs are left out as unsuitable);
* matplotlib ``mpl-data/sample_data`` — its photographs.

Kept out of training (:data:`TEST_PICTURES`): every picture the benchmark
scores on — the evaluation sweep's camera set (astronaut, coffee, chelsea,
``spikejdd.evaluate.SWEEP_SETS``) and the pictures inside its object set
(``spikesim.scenes.layered``: sprites over coffee with astronaut, chelsea and
rocket sprites; fan/disk over astronaut with a rocket disk).  Three more
(:data:`VALIDATION_PICTURES`) are held out for validation, so the checkpoint is
chosen on pictures the model never trained on.

Pictures are decoded from sRGB to linear light (``spikesim`` photometry) at
full resolution and cached once per process.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from spikesim.errors import bad_value

__all__ = ["PICTURES", "TEST_PICTURES", "VALIDATION_PICTURES", "TRAIN_PICTURES",
           "picture_path", "load_picture"]

#: name → (package, path inside the package).
PICTURES: dict[str, tuple[str, str]] = {
    **{name: ("skimage", f"data/{file}") for name, file in (
        ("astronaut", "astronaut.png"), ("coffee", "coffee.png"), ("chelsea", "chelsea.png"),
        ("rocket", "rocket.jpg"), ("camera", "camera.png"), ("clock", "clock_motion.png"),
        ("colorwheel", "color.png"), ("gravel", "gravel.png"), ("brick", "brick.png"),
        ("text", "text.png"), ("hubble_deep_field", "hubble_deep_field.jpg"),
        ("page", "page.png"), ("moon", "moon.png"), ("grass", "grass.png"),
        ("retina", "retina.jpg"), ("immunohistochemistry", "ihc.png"), ("cell", "cell.png"),
        ("microaneurysms", "microaneurysms.png"), ("coins", "coins.png"),
        ("chessboard", "chessboard_RGB.png"), ("logo", "logo.png"),
        ("motorcycle_left", "motorcycle_left.png"), ("motorcycle_right", "motorcycle_right.png"))},
    "grace_hopper": ("matplotlib", "mpl-data/sample_data/grace_hopper.jpg"),
    "present_pack": ("matplotlib", "mpl-data/sample_data/Minduka_Present_Blue_Pack.png"),
}
#: Pictures the benchmark scores on (sweep camera set and object-set textures).
TEST_PICTURES: tuple[str, ...] = ("astronaut", "coffee", "chelsea", "rocket")
#: Held out for validation (never trained on, never tested on).
VALIDATION_PICTURES: tuple[str, ...] = ("motorcycle_left", "motorcycle_right", "grace_hopper")
#: Everything else.
TRAIN_PICTURES: tuple[str, ...] = tuple(
    n for n in PICTURES if n not in TEST_PICTURES and n not in VALIDATION_PICTURES)


def picture_path(name: str) -> Path:
    """The installed file of picture ``name``."""
    import importlib

    if name not in PICTURES:
        raise bad_value("picture", name, f"one of {sorted(PICTURES)}")
    package, rel = PICTURES[name]
    root = Path(importlib.import_module(package).__file__).parent
    return root / rel


@lru_cache(maxsize=64)
def load_picture(name: str) -> np.ndarray:
    """Picture ``name`` at full resolution, (H, W, 3) float32 linear light in [0, 1] (read-only)."""
    import imageio.v3 as iio

    from spikesim.scenes.photometry import decode_frame

    img = np.asarray(iio.imread(picture_path(name)))
    if img.ndim == 3 and img.shape[2] == 4:
        img = img[..., :3]
    out = decode_frame(img, linear=False, name=name)
    out.setflags(write=False)
    return out
