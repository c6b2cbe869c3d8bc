"""The held-out benchmark's pictures: a source disjoint from training and validation."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from spikejdd.heldout import (
    CATEGORIES,
    CLASSICAL,
    HELD_OUT,
    held_out_frames,
    held_out_packages,
    held_out_picture,
    held_out_tables,
    rendered_text,
)
from spikejdd.train.pictures import (
    PICTURES,
    TEST_PICTURES,
    TRAIN_PICTURES,
    VALIDATION_PICTURES,
    package_folder,
)
from spikejdd.train.validation import validation_pictures
from spikesim.errors import SpikeSimFileError, SpikeSimValueError

_MISSING = sorted(p for p in held_out_packages() if importlib.util.find_spec(p) is None)
needs_pictures = pytest.mark.skipif(
    bool(_MISSING), reason=f"held-out pictures not installed ({', '.join(_MISSING)}): "
    "pip install --no-deps scikit-learn mahotas plenoptic")


def test_the_three_sources_share_no_package():
    train = {PICTURES[n][0] for n in TRAIN_PICTURES + TEST_PICTURES}
    val = {PICTURES[n][0] for n in VALIDATION_PICTURES}
    held = held_out_packages()
    assert train == {"skimage", "matplotlib", "colour"}
    assert val == {"pywt", "glymur"}
    assert held == {"sklearn", "mahotas", "plenoptic"}
    assert not train & val and not train & held and not val & held
    assert set(validation_pictures()) == set(VALIDATION_PICTURES)
    assert not set(TRAIN_PICTURES) & set(VALIDATION_PICTURES)


def test_twelve_pictures_cover_every_category():
    assert len(HELD_OUT) >= 12
    for cat in CATEGORIES:
        assert any(cat in p.categories for p in HELD_OUT.values()), cat
    for p in HELD_OUT.values():
        assert set(p.categories) <= set(CATEGORIES) and 0 < p.scale <= 1


def test_the_rendered_page_is_text_on_paper():
    page = rendered_text()
    assert page.shape == (256, 384, 3) and page.dtype == np.float32
    assert page.max() == pytest.approx(0.85, abs=1e-3) and page.min() < 0.1
    assert 0.05 < np.mean(page < 0.4) < 0.4  # ink covers a part of the page
    np.testing.assert_array_equal(held_out_picture("text-page", (20, 30)),
                                  held_out_picture("text-page", (20, 30)))


@needs_pictures
def test_every_picture_crops_to_the_frame_in_linear_light():
    for name in HELD_OUT:
        img = held_out_picture(name, (48, 64))
        assert img.shape == (48, 64, 3) and img.dtype == np.float32, name
        assert img.min() >= 0 and img.max() <= 1 and img.std() > 0.02, name
    # a crop larger than a picture is enlarged, never out of bounds
    assert held_out_picture("curie", (300, 400)).shape == (300, 400, 3)
    with pytest.raises(SpikeSimValueError, match="picture"):
        held_out_picture("lena", (8, 8))


def test_a_missing_package_is_named_with_its_install_command():
    with pytest.raises(SpikeSimFileError, match="pip install --no-deps no-such-pkg"):
        package_folder("no-such-pkg")


@needs_pictures
def test_frames_cover_pictures_speeds_and_levels():
    frames = held_out_frames(size=(12, 16), speeds=(0.0, 3000.0), levels=["GN10", "GPN-rand"],
                             pictures=["text-page", "dahlia"], context=9)
    assert len(frames) == 2 * 2 * 2
    g = [f.group for f in frames]
    assert {x["picture"] for x in g} == {"text-page", "dahlia"}
    assert {x["noise"] for x in g} == {"GN10", "GPN-rand"}
    assert {x["motion"] for x in g} == {"static", "pan", "zoom"}
    assert frames[0].spikes.shape == (9, 12, 16) and frames[0].gt.shape == (12, 16, 3)
    with pytest.raises(SpikeSimValueError, match="levels"):
        held_out_frames(levels=["GN7"])
    with pytest.raises(SpikeSimValueError, match="pictures"):
        held_out_frames(pictures=["nope"])


def test_tables_take_the_best_classical_pipeline_per_cell():
    rows = []
    for pic in ("dahlia", "text-page"):
        for speed in (0.0, 150.0):
            for noise in ("GN0", "GN10"):
                for k, m in enumerate(CLASSICAL):
                    rows.append({"method": m, "picture": pic, "speed_px_s": speed,
                                 "noise": noise, "PSNR[linear]": 30.0 + k * 0.1})
                # sjdd: +1 dB over the best (30.5) on the dahlia, −0.5 dB on the text
                rows.append({"method": "sjdd", "picture": pic, "speed_px_s": speed,
                             "noise": noise,
                             "PSNR[linear]": 31.5 if pic == "dahlia" else 30.0})
    t = held_out_tables(rows, "sjdd")
    assert t["by_picture"]["dahlia"]["0.0"]["delta_db_gn10"] == pytest.approx(1.0)
    assert t["by_picture"]["text-page"]["150.0"]["delta_db"] == pytest.approx(-0.5)
    assert t["by_category"]["flat"]["0.0"]["delta_db"] == pytest.approx(1.0)
    assert t["by_category"]["text"]["pictures"] == ["text-page"]
    assert t["by_category"]["edges"]["150.0"]["delta_db_gn10"] == pytest.approx(-0.5)
    assert t["summary"]["mean_delta_db"] == pytest.approx(0.25)
    assert t["summary"]["min_delta_db_gn10_static_slow"] == pytest.approx(-0.5)
    assert t["summary"]["pictures_at_least_equal_gn10_static_slow"] == ["dahlia"]
    assert t["wins"] == {CLASSICAL[-1]: 8}
    with pytest.raises(SpikeSimValueError, match="rows"):
        held_out_tables([r for r in rows if r["method"] != CLASSICAL[0]], "sjdd")
