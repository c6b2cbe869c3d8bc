"""TFP and TFI (spikesim.estimate) against theory, the peer fixture, and bad input."""

from __future__ import annotations

import numpy as np
import pytest

from spikesim.errors import SpikeSimTypeError, SpikeSimValueError
from spikesim.estimate import tfi, tfp, tfp_std, window_bounds
from tests.support.fixture_paths import PEER_REDS

FIXTURE = PEER_REDS


def ideal_stream(intensity: np.ndarray, n: int, rate: float, phase: np.ndarray) -> np.ndarray:
    """Noise-free clocked integrate-and-fire, modulo reset, threshold 1 (float64 reference).

    Charge after readout k is ``phase + (k+1)·rate·I``; readout k holds a spike
    when that crosses an integer.
    """
    k = np.arange(n + 1, dtype=np.float64)[:, None, None]
    level = np.floor(phase[None] + k * rate * intensity[None])
    return (np.diff(level, axis=0) > 0).astype(np.uint8)


def test_tfp_constant_within_theory():
    rng = np.random.default_rng(1)
    rate, w = 0.6, 41
    intensity = np.full((200, 50), 0.37)
    phase = rng.random(intensity.shape)
    est = tfp(ideal_stream(intensity, 101, rate, phase), 50, w, rate)
    # hard bound: one spike of quantisation
    assert np.all(np.abs(est - 0.37) <= 1 / (w * rate) + 1e-12)
    # unbiased and with the predicted spread over random phases (10 000 pixels, ~5 sigma)
    sd = float(tfp_std(0.37, w, rate))
    assert abs(est.mean() - 0.37) < 5 * sd / 100
    assert est.std() == pytest.approx(sd, rel=0.05)


def test_tfp_integer_count_is_exact():
    # w·rate·I an integer: every phase gives exactly that count
    intensity = np.full((4, 6), 0.5)
    est = tfp(ideal_stream(intensity, 60, 0.6, np.random.default_rng(0).random((4, 6))),
              30, 20, 0.6)
    np.testing.assert_allclose(est, 0.5)


def test_tfi_constant_within_isi_quantisation():
    rng = np.random.default_rng(2)
    rate = 0.6
    for level in (0.9, 0.31, 0.08):
        intensity = np.full((100, 100), level)
        spikes = ideal_stream(intensity, 200, rate, rng.random(intensity.shape))
        est = tfi(spikes, 100, rate)
        isi = 1 / (rate * level)
        lo, hi = 1 / (np.ceil(isi) * rate), 1 / (np.floor(isi) * rate)
        assert est.min() >= lo - 1e-12 and est.max() <= hi + 1e-12
        # unbiased over the random phase (the interval containing the centre is
        # length-biased, its inverse is not); tolerance ~5 standard errors
        se = est.std() / np.sqrt(est.size)
        assert abs(est.mean() - level) < 5 * se + 1e-9


def test_tfi_no_spike_rules():
    s = np.zeros((11, 1, 3), np.uint8)
    s[2, 0, 1] = 1  # only a spike before the centre
    s[3, 0, 2], s[8, 0, 2] = 1, 1
    r = 0.5
    assert tfi(s, 5, r, no_spike="bound")[0, 0] == pytest.approx(1 / (12 * r))
    assert tfi(s, 5, r, no_spike="bound")[0, 1] == pytest.approx(1 / ((11 - 2) * r))
    assert tfi(s, 5, r, no_spike="zero")[0, :2].tolist() == [0.0, 0.0]
    assert np.isnan(tfi(s, 5, r, no_spike="nan")[0, :2]).all()
    assert tfi(s, 5, r, no_spike="tfp")[0, 1] == pytest.approx(1 / (11 * r))
    for rule in ("bound", "zero", "nan", "tfp"):
        assert tfi(s, 5, r, no_spike=rule)[0, 2] == pytest.approx(1 / (5 * r))
    # a search window restricts where spikes are looked for
    assert tfi(s, 5, r, window=5, no_spike="zero")[0, 2] == 0.0


def test_window_bounds_placement():
    assert window_bounds(100, 50, 41) == (30, 71)
    assert window_bounds(100, 50, 40) == (30, 70)
    assert window_bounds(100, 2, 41) == (0, 41)  # shifted in, not shortened
    assert window_bounds(100, 99, 41) == (59, 100)
    assert window_bounds(100, None, 1) == (50, 51)


def _peer():
    from skimage.io import imread

    raw = np.fromfile(FIXTURE / "203_part2_key_id151.dat", np.uint8)
    # PKU .dat: LSB-first, row-major, stored upside down (decoded here independently)
    spikes = np.unpackbits(raw.reshape(-1, 250, 50), axis=-1, bitorder="little")[:, ::-1]
    gt = imread(FIXTURE / "203_part2_key_id151.png").astype(np.float64) / 255.0
    return spikes, gt


@pytest.mark.skipif(not FIXTURE.is_dir(), reason="shared fixtures not present")
def test_tfp_peer_fixture_psnr():
    spikes, gt = _peer()
    assert spikes.shape == (301, 250, 400)

    def psnr(window):
        est = np.clip(tfp(spikes, 150, window, 0.6), 0, 1)
        return 10 * np.log10(1 / np.mean((est - gt) ** 2))

    assert psnr(41) == pytest.approx(23.5, abs=0.1)  # readouts 130..170
    assert psnr(21) == pytest.approx(25.8, abs=0.1)  # readouts 140..160


@pytest.mark.parametrize(
    "call, exc, words",
    [
        (lambda s: tfp(s, 5, window=0), SpikeSimValueError, "window"),
        (lambda s: tfp(s, 5, window=11), SpikeSimValueError, "window"),
        (lambda s: tfp(s, 10, window=3), SpikeSimValueError, "center"),
        (lambda s: tfp(s, -1, window=3), SpikeSimValueError, "center"),
        (lambda s: tfp(s, 5, window=3, rate=0), SpikeSimValueError, "rate"),
        (lambda s: tfp(s, 5, window=3, rate=float("nan")), SpikeSimValueError, "rate"),
        (lambda s: tfp(s.astype(np.float32), 5, 3), SpikeSimTypeError, "dtype"),
        (lambda s: tfp(s[0], 5, 3), SpikeSimValueError, "spikes.shape"),
        (lambda s: tfp(s[:0], 0, 1), SpikeSimValueError, "spikes.shape"),
        (lambda s: tfi(s, 5, no_spike="guess"), SpikeSimValueError, "no_spike"),
        (lambda s: tfi(s, 5, window=12), SpikeSimValueError, "window"),
        (lambda s: tfi(s, 5.5), SpikeSimValueError, "center"),
    ],
)
def test_bad_input(call, exc, words):
    s = np.zeros((10, 4, 4), np.uint8)
    with pytest.raises(exc, match=words):
        call(s)
