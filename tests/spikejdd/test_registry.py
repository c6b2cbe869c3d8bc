"""reconstruct() through the registry: pipelines, third-party methods, bad input."""

from __future__ import annotations

import numpy as np
import pytest

import spikejdd as sj
import spikesim as ss
from spikesim.errors import SpikeSimTypeError, SpikeSimValueError


@pytest.fixture(scope="module")
def stream():
    img = np.ones((24, 30, 3)) * np.array([0.3, 0.6, 0.8])  # TFI of < 1 unclipped
    sensor = ss.Sensor(height=24, width=30, cfa="GBRG", full_scale_rate=0.6)
    return ss.simulate(ss.scenes.Static(img), sensor, n_readouts=81, seed=4), img


@pytest.mark.parametrize("method", ["tfp+bilinear", "tfi+malvar2004", "tfp+menon2007+nlm",
                                    "tfp21+opencv_ea+bilateral", "tfi41+bilinear"])
def test_pipelines_recover_constant_colour(stream, method):
    s, img = stream
    out = sj.reconstruct(s.unpack(), cfa=s.cfa, method=method, center=40, rate=0.6)
    assert out.shape == (24, 30, 3)
    # one spike of quantisation over >= 21 readouts at rate 0.6 is < 0.08
    assert np.abs(out.mean((0, 1)) - img[0, 0]).max() < 0.03
    # TFI's single interval quantises harder than TFP's 21..41-readout count
    assert sj.metrics.psnr(out, img) > (18 if method.startswith("tfi") else 24)


def test_tfp_and_tfi_on_simulator_match_theory(stream):
    s, img = stream
    spikes = s.unpack()
    tfp = sj.baselines.tfp(spikes, 40, 41, 0.6)
    truth = ss.cfa.mosaic(img, s.cfa)
    assert np.abs(tfp - truth).max() <= 1 / (41 * 0.6) + 1e-9
    tfi = sj.baselines.tfi(spikes, 40, 0.6)
    isi = 1 / (0.6 * truth)
    assert np.all(tfi >= 1 / (np.ceil(isi) * 0.6) - 1e-9)
    assert np.all(tfi <= 1 / (np.floor(isi) * 0.6) + 1e-9)


def test_third_party_method_registers_and_validates(stream):
    s, _ = stream

    def grey(spikes, cfa, center, rate=0.6, level=0.5):
        """Constant grey (test method)."""
        return np.full(spikes.shape[1:] + (3,), level)

    sj.register_method("test-grey", grey)
    try:
        out = sj.reconstruct(s.unpack(), s.cfa, "test-grey", level=0.25)
        assert np.all(out == 0.25)
        assert sj.list_methods()["test-grey"] == "Constant grey (test method)."
        with pytest.raises(SpikeSimValueError, match="already registered"):
            sj.register_method("test-grey", grey)
        with pytest.raises(SpikeSimValueError, match="already registered"):
            sj.register_method("tfp+bilinear", grey)
        sj.register_method("test-grey", lambda *a, **k: np.zeros((2, 2, 3)), overwrite=True)
        with pytest.raises(SpikeSimValueError, match="returned shape"):
            sj.reconstruct(s.unpack(), s.cfa, "test-grey")
        sj.register_method("test-grey", lambda sp, *a, **k: np.full(sp.shape[1:] + (3,), np.nan),
                           overwrite=True)
        with pytest.raises(SpikeSimValueError,
                           match=r"method 'test-grey' returned \d+ non-finite values"):
            sj.reconstruct(s.unpack(), s.cfa, "test-grey")
        # an 8-bit image is refused with the conversion to make
        sj.register_method("test-grey", lambda sp, *a, **k: np.full(sp.shape[1:] + (3,), 200,
                                                                    np.uint8), overwrite=True)
        with pytest.raises(SpikeSimTypeError, match=r"dtype uint8.*8-bit image.*srgb_to_linear"):
            sj.reconstruct(s.unpack(), s.cfa, "test-grey")
        # spikes other than 0/1 are refused before any method runs
        with pytest.raises(SpikeSimValueError, match="spikes=.*from 0 to 2.*0/1 spikes"):
            sj.reconstruct(s.unpack() * 2, s.cfa, "tfp+bilinear")
    finally:
        sj.unregister_method("test-grey")
    with pytest.raises(SpikeSimValueError, match="lower-case"):
        sj.register_method("Bad Name", grey)
    with pytest.raises(SpikeSimTypeError, match="callable"):
        sj.register_method("x-not-callable", 3)


def test_bad_input(stream):
    s, _ = stream
    sp = s.unpack()
    with pytest.raises(SpikeSimValueError, match="method"):
        sj.reconstruct(sp, "RGGB", "tfp+ahd")
    with pytest.raises(SpikeSimValueError, match="cfa"):
        sj.reconstruct(sp, "RGBW", "tfp+bilinear")
    with pytest.raises(SpikeSimValueError, match="center"):
        sj.reconstruct(sp, "RGGB", "tfp+bilinear", center=81)
    with pytest.raises(SpikeSimValueError, match="window"):
        sj.reconstruct(sp, "RGGB", "tfp100+bilinear")
    with pytest.raises(SpikeSimValueError, match="spikes.shape"):
        sj.reconstruct(sp[:, 0], "RGGB", "tfp+bilinear")
    with pytest.raises(SpikeSimTypeError, match="dtype|bool or integer"):
        sj.reconstruct(sp.astype(np.float32), "RGGB", "tfp+bilinear")
