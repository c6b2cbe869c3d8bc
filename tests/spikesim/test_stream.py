"""One stream type and one source protocol: every reader is a SpikeSource and counts alike."""

from __future__ import annotations

import numpy as np
import pytest

import spikesim as ss
from spikesim.errors import SpikeSimValueError


@pytest.fixture(scope="module")
def stream():
    sensor = ss.Sensor(height=6, width=13, noise=ss.noise.PaperNoise(sigma_g=8.0))
    scene = ss.scenes.procedural("astronaut", size=(6, 13))
    return ss.simulate(scene, sensor, 300, seed=3, clean_twin=True)


def test_every_reader_is_a_source_with_the_same_counts(stream, tmp_path):
    ss.io.write_h5(tmp_path / "s.h5", stream)
    ss.io.write_dat(tmp_path / "s.dat", stream.unpack())
    seq = ss.io.open_h5(tmp_path / "s.h5")
    dat = ss.io.open_dat(tmp_path / "s.dat", 6, 13)
    expected = stream.unpack().sum(axis=0, dtype=np.int64)
    from spikesim.analysis import as_capture

    for src in (stream, seq, dat, as_capture(stream), as_capture(stream.unpack())):
        assert isinstance(src, ss.SpikeSource), type(src).__name__
        assert (src.n_readouts, src.height, src.width) == (300, 6, 13)
        np.testing.assert_array_equal(src.read_window(17, 40), stream.unpack()[17:57])
        for block in (1, 7, 256, 1000):
            np.testing.assert_array_equal(ss.pixel_counts(src, block=block), expected)
        np.testing.assert_array_equal(ss.pixel_counts(src, 50, 120),
                                      stream.unpack()[50:120].sum(axis=0))
    seq.close()
    assert not isinstance(np.zeros((3, 2, 2)), ss.SpikeSource)


def test_stream_windows_and_clean_rates(stream):
    np.testing.assert_array_equal(stream.read_window(0), stream.unpack())
    np.testing.assert_array_equal(stream.read_window(5, 3, clean=True),
                                  stream.unpack(clean=True)[5:8])
    np.testing.assert_allclose(stream.firing_rate(clean=True),
                               stream.unpack(clean=True).mean(axis=0))
    assert not np.array_equal(stream.firing_rate(), stream.firing_rate(clean=True))
    with pytest.raises(SpikeSimValueError, match="start"):
        stream.read_window(300)
    with pytest.raises(SpikeSimValueError, match="length"):
        stream.read_window(290, 11)
