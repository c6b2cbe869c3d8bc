"""Evaluation harness and CLI on a tiny simulated dataset."""

from __future__ import annotations

import json

import numpy as np
import pytest

import spikesim as ss
from spikejdd import evaluate
from spikejdd.cli import main
from spikesim.errors import SpikeSimValueError
from spikesim.io import write_h5


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("evalset")
    yy, xx = np.mgrid[0:20, 0:24] / 24.0
    for i, cfa in enumerate(("RGGB", "GBRG")):
        img = np.stack([0.2 + 0.6 * xx, 0.3 + 0.5 * yy, 0.7 - 0.4 * xx * yy], -1)  # smooth
        sensor = ss.Sensor(height=20, width=24, cfa=cfa)
        stream = ss.simulate(ss.scenes.Static(img), sensor, n_readouts=50, seed=0,
                             gt_readouts=[25])
        write_h5(d / f"seq{i}.h5", stream)
    return d


def test_run_scores_and_times(data_dir):
    frames = evaluate.frames_from_dataset(data_dir, context=41)
    assert len(frames) == 2 and frames[0].spikes.shape == (41, 20, 24)
    res = evaluate.run(frames, ["tfp+bilinear", "tfp21+menon2007"], repeats=2, progress=False)
    assert len(res["rows"]) == 4
    s = res["summary"]["tfp21+menon2007"]["all"]
    assert s["frames"] == 2 and s["ms_per_frame"] > 0
    assert 15 < s["PSNR[linear]"] < 60 and 0 < s["SSIM-gauss11[srgb]"] <= 1
    with pytest.raises(SpikeSimValueError, match="method"):
        evaluate.run(frames, ["nope"], progress=False)
    with pytest.raises(SpikeSimValueError, match="repeats"):
        evaluate.run(frames, ["tfp+bilinear"], repeats=0, progress=False)


def test_cli_writes_json_md_png(data_dir, tmp_path, capsys):
    out = tmp_path / "r"
    rc = main(["evaluate", "--data", str(data_dir), "--methods", "tfp+bilinear,tfi+bilinear",
               "--repeats", "1", "--out", str(out), "--quiet"])
    assert rc == 0
    res = json.loads(out.with_suffix(".json").read_text())
    assert set(res["summary"]) == {"tfp+bilinear", "tfi+bilinear"}
    assert "PSNR[linear] per sequence" in out.with_suffix(".md").read_text()
    assert out.with_suffix(".png").read_bytes()[:4] == b"\x89PNG"
    assert main(["evaluate", "--data", str(data_dir), "--methods", "bogus", "--out",
                 str(out), "--quiet"]) == 1
    assert "bogus" in capsys.readouterr().err
    assert main(["methods"]) == 0


def test_group_columns_sort_numbers_by_value():
    from spikejdd.evaluate import _natural

    assert sorted(["GN0", "GN10", "GN15", "GN5", "GPN-rand"], key=_natural) == [
        "GN0", "GN5", "GN10", "GN15", "GPN-rand"]
