"""Real-capture (.dat) loader: window, flip, crop and the crop's CFA phase."""

from __future__ import annotations

import numpy as np
import pytest

from spikejdd.capture import CaptureWindows, centred_window
from spikesim.cfa import mask_planes
from spikesim.errors import SpikeSimValueError
from spikesim.io import open_dat
from tests.support.fixture_paths import PEER_REDS

DAT = PEER_REDS / "203_part2_key_id151.dat"
pytestmark = pytest.mark.skipif(not DAT.is_file(), reason="shared fixtures not present")


def test_window_crop_and_pattern():
    raw = np.fromfile(DAT, np.uint8)
    ref = np.unpackbits(raw.reshape(-1, 250, 50), axis=-1, bitorder="little")[:, ::-1]
    cap = open_dat(DAT, 250, 400, cfa="RGGB")
    spikes, cfa = centred_window(cap, 150, 41, crop=(11, 5, 20, 30))
    np.testing.assert_array_equal(spikes, ref[130:171, 11:31, 5:35])
    assert cfa == "BGGR"  # odd row and odd column offset
    unflipped, _ = centred_window(open_dat(DAT, 250, 400, flip=False), 150, 3)
    np.testing.assert_array_equal(unflipped, ref[149:152, ::-1])
    ds = CaptureWindows(cap, centers=[150], window=39, crop=(1, 0, 8, 8), packed=True)
    s = ds[0]
    assert s["meta"]["cfa"] == "GBRG" and s["spikes"].shape == (39, 8, 1)
    np.testing.assert_array_equal(s["mask"].numpy(), mask_planes("GBRG", 8, 8))
    with pytest.raises(SpikeSimValueError, match="centers"):
        CaptureWindows(cap, centers=[5], window=39)
    with pytest.raises(SpikeSimValueError, match="window"):
        centred_window(cap, 150, 400)


def test_reconstruct_guesses_a_dat_size_and_takes_partial_drop(tmp_path, capsys):
    """A .dat's size is guessed as spikesim guesses it (with a warning), and a capture
    cut mid-frame is read with --partial drop, the option its error names."""
    from spikejdd.cli import main
    from spikesim.io import write_dat

    rng = np.random.default_rng(0)
    write_dat(tmp_path / "cap.dat", (rng.random((60, 250, 400)) < 0.1).astype(np.uint8))
    cut = tmp_path / "cut.dat"
    cut.write_bytes((tmp_path / "cap.dat").read_bytes()[:-100])
    base = ["reconstruct", "--centers", "25", "--methods", "tfp+bilinear", "--quiet"]
    assert main([*base, str(tmp_path / "cap.dat"), "--out", str(tmp_path / "a")]) == 0
    assert "assumed 400x250" in capsys.readouterr().err
    assert main([*base, str(cut), "--height", "250", "--width", "400",
                 "--out", str(tmp_path / "b")]) == 1
    assert "--partial drop" in capsys.readouterr().err and not (tmp_path / "b").exists()
    assert main([*base, str(cut), "--height", "250", "--width", "400", "--partial", "drop",
                 "--out", str(tmp_path / "c")]) == 0
    assert "partial frame is ignored" in capsys.readouterr().err
    assert len(list((tmp_path / "c").glob("*.png"))) == 1
