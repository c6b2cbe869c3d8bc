"""Pictures that installed packages ship, split by package into training, validation and test.

No downloads: every picture is read from the folder of the package that
ships it (found with ``importlib.util.find_spec``, so the package is never
imported and its own dependencies need not be installed).  The split is by
package, so no picture, and no photographer's or collection's style, crosses
from one use to another:

* **training** (:data:`TRAIN_PICTURES`) — scikit-image ``skimage/data``
  (every colour or grey photograph, micrograph and test chart it installs;
  binary masks, tiny face crops, multi-page stacks and GIFs are left out as
  unsuitable), matplotlib ``mpl-data/sample_data`` (its photographs) and
  colour-science's Ishihara plate (coloured discs);
* **kept out of training** (:data:`TEST_PICTURES`) — the scikit-image
  pictures the Table-1 sweep scores on (``spikejdd.evaluate.SWEEP_SETS``:
  astronaut, coffee, chelsea; the sprites, fan and disk of
  ``spikesim.scenes.layered`` carry rocket as well);
* **validation** (:data:`VALIDATION_PICTURES`, ``spikejdd.train.validation``)
  — PyWavelets ``pywt/data`` (an aerial photograph, people on stairs) and
  glymur ``glymur/data`` (a snowy street, a glass on a lit coaster): a source
  that neither training nor any benchmark uses, so the checkpoint kept is the
  best on content the model has not seen and is not chosen on the benchmark;
* the **held-out benchmark** (:mod:`spikejdd.heldout`) reads scikit-learn,
  mahotas and plenoptic pictures, none of them here.

Pictures are decoded from sRGB to linear light (``spikesim`` photometry) at
full resolution and cached once per process.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from spikesim.errors import SpikeSimFileError, bad_value

__all__ = ["PICTURES", "TEST_PICTURES", "VALIDATION_PICTURES", "TRAIN_PICTURES",
           "PIP_NAMES", "package_folder", "picture_path", "load_picture", "read_picture"]

#: name → (importable package, path inside the package).
PICTURES: dict[str, tuple[str, str]] = {
    **{name: ("skimage", f"data/{file}") for name, file in (
        ("astronaut", "astronaut.png"), ("coffee", "coffee.png"), ("chelsea", "chelsea.png"),
        ("rocket", "rocket.jpg"), ("camera", "camera.png"), ("clock", "clock_motion.png"),
        ("colorwheel", "color.png"), ("gravel", "gravel.png"), ("brick", "brick.png"),
        ("text", "text.png"), ("hubble_deep_field", "hubble_deep_field.jpg"),
        ("page", "page.png"), ("moon", "moon.png"), ("grass", "grass.png"),
        ("retina", "retina.jpg"), ("immunohistochemistry", "ihc.png"), ("cell", "cell.png"),
        ("microaneurysms", "microaneurysms.png"), ("coins", "coins.png"),
        ("chessboard", "chessboard_RGB.png"), ("logo", "logo.png"), ("phantom", "phantom.png"),
        ("motorcycle_left", "motorcycle_left.png"), ("motorcycle_right", "motorcycle_right.png"))},
    "grace_hopper": ("matplotlib", "mpl-data/sample_data/grace_hopper.jpg"),
    "present_pack": ("matplotlib", "mpl-data/sample_data/Minduka_Present_Blue_Pack.png"),
    "ishihara": ("colour",
                 "examples/plotting/resources/Ishihara_Colour_Blindness_Test_Plate_3.png"),
    "aero": ("pywt", "data/aero.npz"),
    "ascent": ("pywt", "data/ascent.npz"),
    "snowy_street": ("glymur", "data/nemo.jp2"),
    "lit_glass": ("glymur", "data/goodstuff.j2k"),
}
#: Importable package → the name pip installs it by.
PIP_NAMES: dict[str, str] = {"skimage": "scikit-image", "matplotlib": "matplotlib",
                             "colour": "colour-science", "pywt": "pywavelets",
                             "glymur": "glymur", "sklearn": "scikit-learn",
                             "mahotas": "mahotas", "plenoptic": "plenoptic"}
#: Pictures the Table-1 sweep scores on (camera set and object-set textures).
TEST_PICTURES: tuple[str, ...] = ("astronaut", "coffee", "chelsea", "rocket")
#: The validation source (its own packages: PyWavelets and glymur).
VALIDATION_PICTURES: tuple[str, ...] = ("aero", "ascent", "snowy_street", "lit_glass")
#: Every other picture (scikit-image, matplotlib, colour-science).
TRAIN_PICTURES: tuple[str, ...] = tuple(
    n for n in PICTURES if n not in TEST_PICTURES and n not in VALIDATION_PICTURES)


def package_folder(package: str) -> Path:
    """The installed folder of ``package``, found without importing it."""
    import importlib.util

    try:
        spec = importlib.util.find_spec(package)
    except (ImportError, ValueError):
        spec = None
    if spec is None or not spec.submodule_search_locations:
        pip = PIP_NAMES.get(package, package)
        raise SpikeSimFileError(f"package {package!r} is not installed; its pictures are read "
                                f"from its folder: pip install --no-deps {pip}")
    return Path(next(iter(spec.submodule_search_locations)))


def picture_path(name: str) -> Path:
    """The installed file of picture ``name``."""
    if name not in PICTURES:
        raise bad_value("picture", name, f"one of {sorted(PICTURES)}")
    package, rel = PICTURES[name]
    return package_folder(package) / rel


def read_picture(path: Path, name: str) -> np.ndarray:
    """The picture file ``path`` (PNG, JPEG, PGM, JPEG 2000, or a NumPy ``.npz`` of one 8-bit
    array) as (H, W, 3) float32 linear light in [0, 1] (an alpha channel is dropped)."""
    import imageio.v3 as iio

    from spikesim.scenes.photometry import decode_frame

    if not path.is_file():
        raise SpikeSimFileError(f"picture {name!r}: {path} is missing (reinstall its package)")
    if path.suffix == ".npz":
        with np.load(path) as blob:
            img = np.asarray(blob[blob.files[0]])
    else:
        img = np.asarray(iio.imread(path))
    if img.ndim == 3 and img.shape[2] == 4:
        img = img[..., :3]
    return decode_frame(img, linear=False, name=name)


@lru_cache(maxsize=64)
def load_picture(name: str) -> np.ndarray:
    """Picture ``name`` at full resolution, (H, W, 3) float32 linear light in [0, 1] (read-only)."""
    out = read_picture(picture_path(name), name)
    out.setflags(write=False)
    return out
