"""PKU .dat reading and writing: format rules, peer-sample figures, windows, bad files."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from PIL import Image

from spikesim.errors import SpikeSimFileError, SpikeSimFormatError, SpikeSimValueError
from spikesim.io import DatFile, DatWriter, guess_dat_shape, open_dat, read_dat, write_dat
from tests.support.fixture_paths import PEER_REDS

PEER = PEER_REDS
PEER_DAT = PEER / "203_part2_key_id151.dat"
PEER_PNG = PEER / "203_part2_key_id151.png"
needs_peer = pytest.mark.skipif(not PEER_DAT.is_file(), reason="shared/fixtures not present")


def naive_decode(raw: bytes, n: int, h: int, w: int, flip: bool) -> np.ndarray:
    """Slow reference straight from the format text: pixel k -> byte k//8, bit k%8."""
    fb = (h * w + 7) // 8
    out = np.zeros((n, h, w), np.uint8)
    for t in range(n):
        for k in range(h * w):
            byte = raw[t * fb + k // 8]
            y, x = divmod(k, w)
            out[t, (h - 1 - y) if flip else y, x] = (byte >> (k % 8)) & 1
    return out


def psnr(x, ref):
    return 10 * np.log10(1.0 / np.mean((x - ref) ** 2))


def tfp_db(spikes, first, last, gt):
    img = np.clip(spikes[first:last + 1].mean(axis=0) / 0.6, 0, 1)
    return psnr(img, gt)


@needs_peer
def test_peer_sample_tfp_psnr_pins_the_format():
    spikes = read_dat(PEER_DAT, 250, 400)
    assert spikes.shape == (301, 250, 400) and spikes.dtype == np.uint8
    gt = np.asarray(Image.open(PEER_PNG), np.float64) / 255.0
    assert tfp_db(spikes, 130, 170, gt) == pytest.approx(23.5, abs=0.1)
    assert tfp_db(spikes, 140, 160, gt) == pytest.approx(25.8, abs=0.1)
    # The figure separates the conventions: no flip is far worse.
    unflipped = read_dat(PEER_DAT, 250, 400, flip=False, start=130, length=41)
    assert tfp_db(unflipped, 0, 40, gt) < 15


@needs_peer
def test_peer_sample_byte_exact_round_trip(tmp_path):
    raw = PEER_DAT.read_bytes()
    spikes = read_dat(PEER_DAT, 250, 400)
    out = tmp_path / "copy.dat"
    assert write_dat(out, spikes) == 301
    assert out.read_bytes() == raw
    # and through packed rows (the HDF5 representation), no unpacking on the way
    packed = np.packbits(spikes, axis=-1, bitorder="little")
    with DatWriter(tmp_path / "packed.dat", 250, 400) as w:
        w.write_packed(packed[:100])
        w.write_packed(packed[100:])
    assert (tmp_path / "packed.dat").read_bytes() == raw


@needs_peer
def test_peer_size_is_guessed_with_a_message():
    with pytest.warns(UserWarning, match="assumed 400x250"):
        dat = open_dat(PEER_DAT)
    assert dat.shape == (301, 250, 400)
    assert "301 readouts" in dat.guess_message


@pytest.mark.parametrize("h,w", [(1, 1), (3, 5), (4, 16), (7, 13), (2, 9)])
@pytest.mark.parametrize("flip", [True, False])
def test_decode_matches_naive_reference(tmp_path, h, w, flip):
    rng = np.random.default_rng(h * 100 + w)
    n = 4
    fb = (h * w + 7) // 8
    raw = bytearray(rng.integers(0, 256, n * fb, dtype=np.uint8).tobytes())
    if (h * w) % 8:  # padding bits of each frame are zero in a valid file
        for t in range(n):
            raw[t * fb + fb - 1] &= (1 << ((h * w) % 8)) - 1
    path = tmp_path / "x.dat"
    path.write_bytes(bytes(raw))
    ref = naive_decode(bytes(raw), n, h, w, flip)
    assert np.array_equal(read_dat(path, h, w, flip=flip), ref)
    # writing back reproduces the bytes
    write_dat(tmp_path / "y.dat", ref, flip=flip)
    assert (tmp_path / "y.dat").read_bytes() == bytes(raw)


@pytest.mark.parametrize("h,w", [(9, 24), (10, 21), (250, 40)])
def test_windows_and_crops_equal_slicing(tmp_path, h, w):
    rng = np.random.default_rng(w)
    spikes = (rng.random((30, h, w)) < 0.4).astype(np.uint8)
    path = tmp_path / "s.dat"
    write_dat(path, spikes)
    dat = DatFile(path, h, w)
    assert np.array_equal(dat.read(), spikes)
    for _ in range(25):
        start = int(rng.integers(0, 30))
        length = int(rng.integers(1, 31 - start))
        top, left = int(rng.integers(0, h)), int(rng.integers(0, w))
        ch, cw = int(rng.integers(1, h - top + 1)), int(rng.integers(1, w - left + 1))
        got = dat.read_window(start, length, (top, left, ch, cw))
        want = spikes[start:start + length, top:top + ch, left:left + cw]
        assert np.array_equal(got, want)
        packed = dat.read_window(start, length, (top, left, ch, cw), packed=True)
        assert np.array_equal(packed, np.packbits(want, axis=-1, bitorder="little"))


def test_head_columns_of_raw_416_capture_are_dropped(tmp_path):
    rng = np.random.default_rng(3)
    raw = (rng.random((5, 250, 416)) < 0.5).astype(np.uint8)
    path = tmp_path / "raw.dat"
    write_dat(path, raw)
    dat = DatFile(path, 250, 416, head_columns=16)
    assert dat.shape == (5, 250, 400) and dat.stored_width == 416
    assert np.array_equal(dat.read(), raw[:, :, 16:])
    assert np.array_equal(dat.read_window(1, 2, (10, 3, 20, 50)), raw[1:3, 10:30, 19:69])
    with pytest.raises(SpikeSimValueError, match="head_columns"):
        DatFile(path, 250, 416, head_columns=416)


def test_partial_frame_is_an_error_or_dropped_with_a_warning(tmp_path):
    spikes = np.ones((3, 8, 8), np.uint8)
    path = tmp_path / "p.dat"
    write_dat(path, spikes)
    with open(path, "ab") as fh:
        fh.write(b"\x01\x02\x03")
    with pytest.raises(SpikeSimFormatError, match="3 bytes left over"):
        read_dat(path, 8, 8)
    with pytest.warns(UserWarning, match="partial frame is ignored"):
        got = read_dat(path, 8, 8, partial="drop")
    assert np.array_equal(got, spikes)
    with pytest.raises(SpikeSimValueError, match="partial"):
        read_dat(path, 8, 8, partial="maybe")


def test_hostile_dat_files(tmp_path):
    empty = tmp_path / "empty.dat"
    empty.write_bytes(b"")
    with pytest.raises(SpikeSimFormatError, match="empty"):
        read_dat(empty, 8, 8)
    with pytest.raises(SpikeSimFileError, match="no such"):
        read_dat(tmp_path / "missing.dat", 8, 8)
    short = tmp_path / "short.dat"
    short.write_bytes(b"\x00" * 5)
    with pytest.raises(SpikeSimFormatError, match="no whole"):
        read_dat(short, 8, 8, partial="drop")
    odd = tmp_path / "odd.dat"
    odd.write_bytes(b"\x00" * 12345)
    with pytest.raises(SpikeSimFormatError, match="cannot guess"):
        read_dat(odd)
    with pytest.raises(SpikeSimValueError, match="both"):
        read_dat(odd, height=5)
    with pytest.raises(SpikeSimValueError, match="width"):
        read_dat(odd, 5, 0)


def test_guess_lists_other_fitting_sizes():
    n = 325000  # lcm of 12500 (400x250) and 13000 (416x250) bytes
    h, w, msg = guess_dat_shape(n)
    assert (h, w) == (250, 400)
    assert "also fits 416x250" in msg


def test_bad_window_arguments(tmp_path):
    path = tmp_path / "w.dat"
    write_dat(path, np.zeros((10, 8, 8), np.uint8))
    dat = DatFile(path, 8, 8)
    for kw, name in [({"start": 10}, "start"), ({"start": -1}, "start"),
                     ({"start": 5, "length": 6}, "length"), ({"length": 0}, "length"),
                     ({"crop": (0, 0, 9, 1)}, "crop"), ({"crop": (1, 2)}, "crop")]:
        with pytest.raises(SpikeSimValueError, match=name):
            dat.read_window(**kw)


def test_write_rejects_bad_input_and_leaves_no_file(tmp_path):
    with pytest.raises(SpikeSimValueError, match="0/1"):
        write_dat(tmp_path / "a.dat", np.full((2, 8, 8), 2, np.uint8))
    with pytest.raises(SpikeSimValueError, match="shape"):
        write_dat(tmp_path / "a.dat", np.zeros((8, 8), np.uint8))
    assert not (tmp_path / "a.dat").exists()
    with pytest.raises(RuntimeError), DatWriter(tmp_path / "b.dat", 8, 8) as w:
        w.write(np.ones((4, 8, 8), np.uint8))
        raise RuntimeError("interrupted")
    assert list(tmp_path.iterdir()) == []


def test_datfile_pickles_and_holds_no_handle(tmp_path):
    import pickle

    path = tmp_path / "k.dat"
    spikes = (np.random.default_rng(1).random((6, 8, 16)) < 0.5).astype(np.uint8)
    write_dat(path, spikes)
    dat = pickle.loads(pickle.dumps(DatFile(path, 8, 16, cfa="RGGB", clock_hz=20000)))
    assert np.array_equal(dat.read(), spikes)
    assert dat.cfa == "RGGB" and dat.duration_s == pytest.approx(6 / 20000)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        DatFile(path, 8, 16)  # explicit size: no warning


def test_write_dat_streams_a_simulate_chunks_run(tmp_path, monkeypatch):
    import spikesim as ss
    from spikesim.simulate import SimulationRun

    scene = ss.scenes.procedural("astronaut", size=(16, 20))
    sensor = ss.Sensor(height=16, width=20)
    run = ss.simulate_chunks(scene, sensor, 300, seed=3, chunk_readouts=64)
    assert write_dat(tmp_path / "run.dat", run) == 300
    assert write_dat(tmp_path / "whole.dat", ss.simulate(scene, sensor, 300, seed=3)) == 300
    assert (tmp_path / "run.dat").read_bytes() == (tmp_path / "whole.dat").read_bytes()

    real = SimulationRun.__iter__

    def fail_after_one(self):
        it = real(self)
        yield next(it)
        raise RuntimeError("interrupted")

    monkeypatch.setattr(SimulationRun, "__iter__", fail_after_one)
    with pytest.raises(RuntimeError):
        write_dat(tmp_path / "half.dat", run)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.dat", "whole.dat"]
