"""Geometric self-ensemble of torch methods: every view keeps the Bayer pattern
and maps back to the right pixels; one view is the plain model, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
import torch

import spikejdd as sj
import spikesim as ss
from spikejdd.models import TorchMethod, run_ensemble, sjdd_method
from spikejdd.models.adapter import model_inputs
from spikejdd.models.pretrained import DEFAULT_WEIGHTS, cached_model
from spikesim.cfa import channel_index, mask_planes
from spikesim.errors import SpikeSimValueError

PATTERNS = ("RGGB", "BGGR", "GRBG", "GBRG")


class Probe(torch.nn.Module):
    """Channel 0: each pixel's spike count (differs from pixel to pixel, so a
    view mapped back to the wrong pixels shows); channels 1, 2: the red and
    blue mask planes it was given (a view that changed the pattern shows)."""

    def forward(self, spikes, mask):
        return torch.cat([spikes.sum(1, keepdim=True), mask[:, :1], mask[:, 3:]], 1)


def _spikes(h, w, t=5, seed=0):
    return np.random.default_rng(seed).integers(0, 2, (t, h, w), dtype=np.uint8)


@pytest.mark.parametrize("cfa", PATTERNS)
@pytest.mark.parametrize("shape", [(6, 8), (7, 9), (5, 4), (2, 3)])
@pytest.mark.parametrize("ensemble", [2, 4])
def test_views_keep_pattern_and_pixels(cfa, shape, ensemble):
    spikes = _spikes(*shape)
    x = torch.from_numpy(spikes.astype(np.float32))[None]
    out = run_ensemble(Probe(), x, cfa, ensemble).numpy()
    np.testing.assert_array_equal(out[0], spikes.sum(0))
    colours = channel_index(cfa, *shape)
    np.testing.assert_array_equal(out[1], colours == 0)
    np.testing.assert_array_equal(out[2], colours == 2)


class Rows(torch.nn.Module):
    """Outputs each pixel's row index in the view it is given."""

    def forward(self, spikes, mask):
        h, w = spikes.shape[-2:]
        r = torch.arange(h, dtype=torch.float32)[:, None].expand(h, w)
        return torch.stack([r, r, r])[None]


def test_views_are_averaged():
    """The mean over views of where each pixel sat in them, which only a
    correct mapping and count give."""
    x = torch.zeros(1, 3, 6, 8)
    rows = np.arange(6.0)[:, None] * np.ones((1, 8))
    cols = np.ones((6, 1)) * np.arange(8.0)[None]
    inner = (slice(1, -1), slice(1, -1))
    border = np.ones((6, 8), bool)
    border[inner] = False
    # RGGB: the transposed view needs no crop (its row is the input's column);
    # the 180° rotations are BGGR, so they drop the border: rows 4 − row and
    # 6 − column of the interior
    np.testing.assert_allclose(run_ensemble(Rows(), x, "RGGB", 2).numpy()[0], (rows + cols) / 2)
    four = run_ensemble(Rows(), x, "RGGB", 4).numpy()[0]
    np.testing.assert_allclose(four[inner], 2.5)  # (r + c + (4 − r) + (6 − c)) / 4
    np.testing.assert_allclose(four[border], (rows + cols)[border] / 2)
    # GRBG: the transposed view drops its first and last row and column (the
    # input's border), so its row is the input's column − 1 and the border has
    # the identity view alone
    out = run_ensemble(Rows(), x, "GRBG", 2).numpy()[0]
    inner = (slice(1, -1), slice(1, -1))
    np.testing.assert_allclose(out[inner], (rows[inner] + cols[inner] - 1) / 2)
    border = np.ones((6, 8), bool)
    border[inner] = False
    np.testing.assert_allclose(out[border], rows[border])


def test_one_view_is_the_model_bit_for_bit():
    sensor = ss.Sensor(height=18, width=22, cfa="GRBG",
                       noise=ss.noise.PaperNoise(sigma_g=5.0, sigma_p=0.0))
    stream = ss.simulate(ss.scenes.procedural("fan", size=(18, 22), speed=300.0), sensor, 41,
                         seed=2, gt_readouts=[])
    spikes = stream.unpack()
    model = cached_model(DEFAULT_WEIGHTS, "cpu")
    x, m = model_inputs(spikes, "GRBG", 20, model.config.n_readouts)
    with torch.inference_mode():
        plain = model(x, m)[0][0].clamp(0, 1).permute(1, 2, 0).numpy()
    np.testing.assert_array_equal(sjdd_method(spikes, "GRBG", 20, ensemble=1), plain)
    two = sj.reconstruct(spikes, "GRBG", method="sjdd", center=20)  # the default
    np.testing.assert_array_equal(two, sjdd_method(spikes, "GRBG", 20, ensemble=2))
    assert not np.array_equal(two, plain)


def test_torch_method_option_and_default():
    spikes = _spikes(6, 8, t=3)
    probe = TorchMethod(Probe(), window=3, ensemble=4)
    np.testing.assert_array_equal(probe(spikes, "BGGR", 1)[..., 0], spikes.sum(0).clip(0, 1))
    rows = TorchMethod(Rows(), window=3)  # default: one view
    np.testing.assert_array_equal(rows(spikes, "RGGB", 1)[..., 0],
                                  (np.arange(6.0)[:, None] * np.ones((1, 8))).clip(0, 1))
    two = rows(spikes, "RGGB", 1, ensemble=2)[..., 0]
    np.testing.assert_allclose(two, ((np.arange(6.0)[:, None] + np.arange(8.0)) / 2).clip(0, 1))


@pytest.mark.parametrize("bad", [0, 3, 8, True, "2", 2.0, 2.5, [2]])
def test_bad_ensemble(bad):
    """One message wherever the value arrives, the classical pipelines (which
    ignore the option) included."""
    spikes = _spikes(8, 8, t=39)
    with pytest.raises(SpikeSimValueError, match="ensemble"):
        sjdd_method(spikes, "RGGB", 19, ensemble=bad)
    with pytest.raises(SpikeSimValueError, match="ensemble"):
        TorchMethod(Probe(), window=3, ensemble=bad)
    with pytest.raises(SpikeSimValueError, match="ensemble"):
        run_ensemble(Probe(), torch.zeros(1, 3, 6, 8), "RGGB", bad)
    for method in ("sjdd@sjdd-lite", "tfp+bilinear"):
        with pytest.raises(SpikeSimValueError, match="ensemble"):
            sj.reconstruct(spikes, "RGGB", method=method, center=19, ensemble=bad)


def test_none_is_the_default():
    spikes = _spikes(8, 10, t=39)
    np.testing.assert_array_equal(sjdd_method(spikes, "RGGB", 19, ensemble=None),
                                  sjdd_method(spikes, "RGGB", 19, ensemble=2))
    rows = TorchMethod(Rows(), window=3, ensemble=None)
    assert rows.ensemble == 1
    four = TorchMethod(Rows(), window=3, ensemble=4)
    np.testing.assert_array_equal(four(spikes[:3], "RGGB", 1, ensemble=None),
                                  four(spikes[:3], "RGGB", 1))
    sj.reconstruct(spikes, "RGGB", method="tfp+bilinear", center=19, ensemble=None)


@pytest.mark.parametrize("shape, passes", [((1, 8), (1, 2, 4)), ((8, 1), (1, 2, 4)),
                                           ((1, 1), (1, 2, 4)), ((2, 2), (1, 2, 2)),
                                           ((2, 3), (1, 2, 2))])
def test_thin_images_keep_the_views_that_fit(shape, passes):
    """RGGB keeps its pattern when transposed, so a 1-pixel-thin image still
    gets its transposed view; a 180° rotation of one row needs only its first
    and last column dropped, while a 2×2 image's rotations (BGGR) would need
    both rows dropped and are skipped (so would a 2×3 image's)."""

    class Count(Probe):
        calls = 0

        def forward(self, spikes, mask):
            Count.calls += 1
            return super().forward(spikes, mask)

    spikes = _spikes(*shape)
    x = torch.from_numpy(spikes.astype(np.float32))[None]
    for k, n in zip((1, 2, 4), passes, strict=True):
        Count.calls = 0
        out = run_ensemble(Count(), x, "RGGB", k).numpy()
        assert Count.calls == n
        np.testing.assert_array_equal(out[0], spikes.sum(0))
        np.testing.assert_array_equal(out[1], channel_index("RGGB", *shape) == 0)


def test_mask_planes_of_a_view_match_its_crop():
    """The premise of the crops: a transposed GRBG mosaic is GBRG, and dropping
    its first row and column gives GRBG again."""
    c = channel_index("GRBG", 6, 8)
    np.testing.assert_array_equal(c.T, channel_index("GBRG", 8, 6))
    np.testing.assert_array_equal(c.T[1:-1, 1:-1], channel_index("GRBG", 6, 4))
    assert mask_planes("GRBG", 6, 4).shape == (4, 6, 4)


@pytest.fixture(scope="module")
def small_h5(tmp_path_factory):
    from spikesim.io import write_h5

    path = tmp_path_factory.mktemp("ens") / "pan.h5"
    sensor = ss.Sensor(height=16, width=20, cfa="RGGB",
                       noise=ss.noise.PaperNoise(sigma_g=10.0, sigma_p=0.0))
    scene = ss.scenes.procedural("astronaut", motion="pan", size=(16, 20), speed=300.0)
    write_h5(path, ss.simulate(scene, sensor, n_readouts=39, seed=3, gt_readouts=[19]))
    return path


def test_evaluate_passes_ensemble_to_methods_that_take_it(small_h5):
    from spikejdd import evaluate

    frames = evaluate.frames_from_dataset(small_h5, 39, 1)
    methods = ["sjdd", "tfp+malvar2004"]
    one, two = {}, {}
    r1 = evaluate.run(frames, methods, repeats=1, progress=False, outputs=one, ensemble=1)
    r2 = evaluate.run(frames, methods, repeats=1, progress=False, outputs=two)
    assert r1["runtime"]["ensemble"] == 1
    assert r2["runtime"]["ensemble"] == evaluate.DEFAULT_VIEWS
    f = frames[0]
    np.testing.assert_array_equal(one[("sjdd", 0)],
                                  sjdd_method(f.spikes, f.cfa, f.center, ensemble=1))
    np.testing.assert_array_equal(two[("sjdd", 0)], sjdd_method(f.spikes, f.cfa, f.center))
    np.testing.assert_array_equal(one[("tfp+malvar2004", 0)], two[("tfp+malvar2004", 0)])
    with pytest.raises(SpikeSimValueError, match="ensemble"):
        evaluate.run(frames, methods, repeats=1, progress=False, ensemble=3)


def test_cli_ensemble_option(small_h5, tmp_path, capsys):
    import cv2

    from spikejdd.cli import main

    pngs = {}
    for k in ("1", "2"):
        out = tmp_path / f"e{k}"
        assert main(["reconstruct", str(small_h5), "--methods", "sjdd", "--ensemble", k,
                     "--out", str(out), "--quiet"]) == 0, capsys.readouterr().err
        (png,) = sorted(out.glob("*.png"))
        pngs[k] = cv2.imread(str(png))
    assert pngs["1"].shape == (16, 20, 3) and not np.array_equal(pngs["1"], pngs["2"])
    assert main(["evaluate", "--data", str(small_h5.parent), "--methods", "sjdd",
                 "--ensemble", "4", "--repeats", "1", "--out", str(tmp_path / "ev" / "r"),
                 "--quiet"]) == 0, capsys.readouterr().err
    report = (tmp_path / "ev" / "r.md").read_text()
    assert "self-ensemble of learned methods: 4" in report
    with pytest.raises(SystemExit) as exc:
        main(["evaluate", "--sweep", "--methods", "sjdd", "--ensemble", "3"])
    assert exc.value.code == 2 and "--ensemble" in capsys.readouterr().err
