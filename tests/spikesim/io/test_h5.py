"""spikesim HDF5 format v1: round trips, lazy windows, workers, hostile files, atomic writes."""

from __future__ import annotations

import json
import multiprocessing as mp
import operator
import os
import subprocess
import sys

import h5py
import numpy as np
import pytest

import spikesim as ss
from spikesim.errors import SpikeSimFileError, SpikeSimFormatError, SpikeSimValueError
from spikesim.io import (
    COMPRESSIONS,
    H5Writer,
    Sequence,
    open_h5,
    read_dat,
    read_h5,
    read_header,
    write_dat,
    write_h5,
)
from spikesim.io._compression import compression_kwargs, have_hdf5plugin


def _simulated(h=6, w=13, cfa="RGGB", clean=True, n=60):
    sensor = ss.Sensor(height=h, width=w, cfa=cfa, noise=ss.noise.PaperNoise(sigma_g=5.0))
    image = np.random.default_rng(h * w).random((h, w, 3))
    return ss.simulate(ss.scenes.Static(image), sensor, n_readouts=n, seed=3, clean_twin=clean,
                       gt_readouts=[10, 30])


SIZES = [(1, 1, None), (3, 5, None), (3, 5, "GBRG"), (6, 13, "RGGB"), (6, 13, None),
         (8, 16, "BGGR"), (5, 33, "GRBG"), (5, 33, None)]


@pytest.mark.parametrize("h,w,cfa", SIZES)
@pytest.mark.parametrize("clean", [False, True])
def test_round_trip_memory_h5_dat_is_bit_exact(tmp_path, make_stream, h, w, cfa, clean):
    s = make_stream(n=40, height=h, width=w, cfa=cfa, clean=clean, gt_index=(3, 20))
    path = write_h5(tmp_path / "s.h5", s)
    seq = open_h5(path)
    assert (seq.height, seq.width, seq.n_readouts, seq.cfa, seq.has_clean) == (h, w, 40, cfa, clean)
    assert np.array_equal(seq.read_packed(), s.packed)
    assert np.array_equal(seq.read_window(0, None), s.bits)
    if clean:
        assert np.array_equal(seq.read_packed(clean=True), s.clean_packed)
    assert np.array_equal(seq.gt_index, s.gt_index)
    assert np.array_equal(seq.read_gt(1), s.gt[1])
    # h5 -> .dat -> memory -> h5 again
    write_dat(tmp_path / "s.dat", seq.read_window(0, None))
    back = read_dat(tmp_path / "s.dat", h, w)
    assert np.array_equal(back, s.bits)
    s2 = make_stream(n=40, height=h, width=w, cfa=cfa, clean=clean, gt_index=(3, 20))
    s2.packed = np.packbits(back, axis=-1, bitorder="little")
    write_h5(tmp_path / "t.h5", s2)
    with h5py.File(tmp_path / "s.h5") as a, h5py.File(tmp_path / "t.h5") as b:
        assert np.array_equal(a["spikes"][:], b["spikes"][:])


def test_simulated_stream_and_chunk_run_write_identical_files(tmp_path):
    stream = _simulated()
    write_h5(tmp_path / "a.h5", stream)
    sensor = ss.Sensor.from_dict(stream.meta["sensor"])
    image = np.random.default_rng(6 * 13).random((6, 13, 3))
    run = ss.simulate_chunks(ss.scenes.Static(image), sensor, 60, seed=3, clean_twin=True,
                             gt_readouts=[10, 30], chunk_readouts=7)
    write_h5(tmp_path / "b.h5", run)
    a, b = open_h5(tmp_path / "a.h5"), open_h5(tmp_path / "b.h5")
    for clean in (False, True):
        assert np.array_equal(a.read_packed(clean), b.read_packed(clean))
    assert np.array_equal(a.read_all_gt(), b.read_all_gt())
    assert a.meta == b.meta
    loaded = read_h5(tmp_path / "a.h5")
    assert isinstance(loaded, ss.SpikeStream)
    assert np.array_equal(loaded.packed, stream.packed)
    assert np.array_equal(loaded.clean_packed, stream.clean_packed)
    assert np.array_equal(loaded.gt_index, stream.gt_index)
    assert np.array_equal(loaded.gt, stream.gt)
    assert loaded.sensor == stream.sensor and loaded.seed == 3
    with h5py.File(tmp_path / "a.h5") as f:  # the configuration is in plain attributes
        assert f.attrs["format"] == "spikesim" and f.attrs["format_version"] == 2
        for name in ("spikes", "clean_spikes", "gt", "gt_index"):  # a CRC-32 per chunk
            assert f[f"{name}_crc32"].shape == tuple(
                -(-n // c) for n, c in zip(f[name].shape, f[name].chunks, strict=True))
        assert json.loads(f.attrs["noise"]) == {"type": "paper", "sigma_g": 5.0, "sigma_p": 0.0}
        assert f.attrs["seed"] == 3 and f.attrs["cfa"] == "RGGB" and f.attrs["width"] == 13
        assert f["spikes"].chunks[0] >= 1 and f["gt"].dtype == np.float32


@pytest.mark.parametrize("compression", ["none", "gzip", "gzip:6", "lz4", "zstd", "zstd:9"])
def test_every_compression_round_trips(tmp_path, make_stream, compression):
    if compression.split(":")[0] in ("lz4", "zstd") and not have_hdf5plugin():
        with pytest.raises(SpikeSimValueError, match="hdf5plugin"):
            compression_kwargs(compression)
        return
    s = make_stream(n=70, height=20, width=37)
    seq = open_h5(write_h5(tmp_path / "c.h5", s, compression=compression))
    assert np.array_equal(seq.read_window(0, None), s.bits)


def test_unknown_compression_is_refused():
    assert "gzip" in COMPRESSIONS
    for bad in ("brotli", "gzip:0", "gzip:x", "lz4:3", 5):
        with pytest.raises(SpikeSimValueError, match="compression"):
            compression_kwargs(bad)


def test_windows_and_crops_equal_slicing(tmp_path, make_stream):
    s = make_stream(n=90, height=37, width=75, clean=True)
    seq = open_h5(write_h5(tmp_path / "w.h5", s))
    rng = np.random.default_rng(0)
    for _ in range(40):
        start = int(rng.integers(0, 90))
        length = int(rng.integers(1, 91 - start))
        top, left = int(rng.integers(0, 37)), int(rng.integers(0, 75))
        ch, cw = int(rng.integers(1, 38 - top)), int(rng.integers(1, 76 - left))
        crop = (top, left, ch, cw)
        want = s.bits[start:start + length, top:top + ch, left:left + cw]
        assert np.array_equal(seq.read_window(start, length, crop), want)
        packed = seq.read_window(start, length, crop, packed=True)
        assert np.array_equal(packed, np.packbits(want, axis=-1, bitorder="little"))
        gt = seq.read_gt(0, crop)
        assert np.array_equal(gt, s.gt[0, top:top + ch, left:left + cw])
    for kw in ({"start": 90}, {"start": 0, "length": 91}, {"crop": (0, 70, 1, 6)},
               {"crop": (0, 0, 0, 1)}):
        with pytest.raises(SpikeSimValueError):
            seq.read_window(**kw)
    with pytest.raises(SpikeSimValueError, match="k="):
        seq.read_gt(5)


def test_no_clean_twin_is_a_clear_error(tmp_path, make_stream):
    seq = open_h5(write_h5(tmp_path / "n.h5", make_stream()))
    with pytest.raises(SpikeSimValueError, match="no clean twin"):
        seq.read_window(0, 2, clean=True)


@pytest.mark.timeout(180)
def test_sequence_is_safe_in_spawned_workers(tmp_path, make_stream):
    s = make_stream(n=40, height=16, width=24)
    seq = open_h5(write_h5(tmp_path / "p.h5", s))
    crop = (2, 3, 10, 17)
    seq.read_window(0, 1)  # the parent holds an open handle before the workers start
    # the task is a stdlib callable: spawned children cannot import test modules
    with mp.get_context("spawn").Pool(1) as pool:
        got = pool.apply(operator.methodcaller("read_window", 5, 20, crop), (seq,))
    assert np.array_equal(got, s.bits[5:25, 2:12, 3:20])


FORK_SCRIPT = """
import multiprocessing as mp, sys
import numpy as np
from spikesim.io import open_h5

def work(seq):
    return seq.read_window(5, 20, (2, 3, 10, 17))

if __name__ == "__main__":
    seq = open_h5(sys.argv[1])
    before = seq.read_window(5, 20, (2, 3, 10, 17))   # parent handle open before the fork
    with mp.get_context("fork").Pool(2) as pool:
        results = pool.map(work, [seq] * 4)
    after = seq.read_window(5, 20, (2, 3, 10, 17))    # parent handle still good
    assert all(np.array_equal(r, before) for r in results) and np.array_equal(after, before)
    np.save(sys.argv[2], before)
"""


@pytest.mark.timeout(180)
@pytest.mark.skipif("fork" not in mp.get_all_start_methods(), reason="no fork on this OS")
def test_sequence_is_safe_in_forked_workers(tmp_path, make_stream):
    # Forked from a fresh interpreter: forking this test process, which may run
    # numba worker threads, is unsafe for reasons unrelated to the reader.
    s = make_stream(n=40, height=16, width=24)
    path = write_h5(tmp_path / "f.h5", s)
    script = tmp_path / "fork_read.py"
    script.write_text(FORK_SCRIPT)
    out = tmp_path / "out.npy"
    subprocess.run([sys.executable, str(script), str(path), str(out)], check=True, timeout=150)
    assert np.array_equal(np.load(out), s.bits[5:25, 2:12, 3:20])


def _good_file(tmp_path, make_stream, name="g.h5"):
    return write_h5(tmp_path / name, make_stream(n=64, height=16, width=24))


def _edit(path, fn):
    with h5py.File(path, "r+") as f:
        fn(f)


@pytest.mark.parametrize(
    "damage,match",
    [
        (lambda f: f.attrs.__delitem__("format"), "not a spikesim file"),
        (lambda f: f.attrs.__setitem__("format", "other"), "not a spikesim file"),
        (lambda f: f.attrs.__setitem__("format_version", 3), "format version 3.*upgrade"),
        (lambda f: f.__delitem__("spikes_crc32"), "checksums of 'spikes'.*missing"),
        (lambda f: f.attrs.__delitem__("clock_hz"), "missing root attribute.*clock_hz"),
        (lambda f: f.attrs.__setitem__("bitorder", "big"), "bitorder"),
        (lambda f: f.attrs.__setitem__("meta", "{not json"), "malformed"),
        (lambda f: f.attrs.__setitem__("width", 40), "'spikes' is uint8"),
        (lambda f: f.__delitem__("spikes"), "'spikes' is missing"),
        (lambda f: f.__delitem__("gt_index"), "'gt_index' is missing"),
        (lambda f: f["gt_index"].__setitem__(0, 10_000), "outside"),
    ],
)
def test_wrong_attributes_and_datasets_get_clear_errors(tmp_path, make_stream, damage, match):
    path = _good_file(tmp_path, make_stream)
    _edit(path, damage)
    with pytest.raises(SpikeSimFormatError, match=match):
        open_h5(path)


def test_non_spikesim_hdf5_file(tmp_path):
    path = tmp_path / "other.h5"
    with h5py.File(path, "w") as f:
        f["x"] = np.arange(3)
    with pytest.raises(SpikeSimFormatError, match="HDF5 file but not a spikesim file"):
        read_header(path)


def test_truncated_random_and_empty_files(tmp_path, make_stream):
    good = _good_file(tmp_path, make_stream).read_bytes()
    for cut in (len(good) // 2, 100, 7):
        p = tmp_path / f"cut{cut}.h5"
        p.write_bytes(good[:cut])
        with pytest.raises(SpikeSimFormatError):
            open_h5(p)
    rnd = tmp_path / "random.h5"
    rnd.write_bytes(np.random.default_rng(0).integers(0, 256, 5000, dtype=np.uint8).tobytes())
    with pytest.raises(SpikeSimFormatError, match="not an HDF5 file"):
        open_h5(rnd)
    video = tmp_path / "clip.mp4"  # a video where spikes were expected: say what to do
    video.write_bytes(rnd.read_bytes())
    with pytest.raises(SpikeSimFormatError, match="not an HDF5 file.*spikesim simulate clip.mp4"):
        open_h5(video)
    empty = tmp_path / "empty.h5"
    empty.write_bytes(b"")
    with pytest.raises(SpikeSimFormatError, match="empty"):
        open_h5(empty)
    with pytest.raises(SpikeSimFileError, match="no such"):
        open_h5(tmp_path / "missing.h5")


@pytest.mark.parametrize("dataset, part", [("spikes", r"in its spikes \(readouts 0–63\)"),
                                           ("gt", r"in its ground truth \(frame 0, readout")])
def test_corrupt_chunk_data_is_a_clear_error_that_places_it(tmp_path, make_stream, dataset,
                                                             part):
    path = write_h5(tmp_path / "z.h5", make_stream(n=64, height=16, width=24),
                    compression="gzip")
    with h5py.File(path) as f:
        offset = f[dataset].id.get_chunk_info(0).byte_offset
    raw = bytearray(path.read_bytes())
    raw[offset:offset + 64] = b"\xff" * 64
    path.write_bytes(bytes(raw))
    seq = open_h5(path)
    with pytest.raises(SpikeSimFormatError, match=f"damaged data {part}"):
        seq.read_window(0, 64) if dataset == "spikes" else seq.read_gt(0)


def test_interrupted_write_leaves_no_file(tmp_path, make_stream, make_run):
    s = make_stream(n=64, height=8, width=8)

    def broken():
        for i, chunk in enumerate(make_run(s, chunk=16)):
            if i == 2:
                raise RuntimeError("simulated crash")
            yield chunk

    class Run:
        meta = s.meta

        def __iter__(self):
            return broken()

    with pytest.raises(RuntimeError, match="simulated crash"):
        write_h5(tmp_path / "x.h5", Run())
    assert list(tmp_path.iterdir()) == []


@pytest.mark.timeout(180)
def test_killed_writer_process_leaves_no_final_file(tmp_path):
    code = f"""
import os, numpy as np
from spikesim.io import H5Writer
meta = {{"height": 8, "width": 8, "cfa": None, "clock_hz": 1.0}}
with H5Writer({str(tmp_path / 'k.h5')!r}, meta) as w:
    w.append(np.zeros((32, 8, 1), np.uint8))
    os._exit(3)
"""
    proc = subprocess.run([sys.executable, "-c", code], timeout=120)
    assert proc.returncode == 3
    assert not (tmp_path / "k.h5").exists()


def test_writer_checks_its_input(tmp_path, make_stream):
    with pytest.raises(SpikeSimValueError, match="height"):
        H5Writer(tmp_path / "a.h5", {"width": 3})
    s = make_stream(n=8, height=4, width=9)
    with pytest.raises(SpikeSimValueError, match="packed"), \
            H5Writer(tmp_path / "a.h5", s.meta) as w:
        w.append(np.zeros((2, 4, 1), np.uint8))
    with pytest.raises(SpikeSimValueError, match="gt_index"), \
            H5Writer(tmp_path / "a.h5", s.meta) as w:
        w.append(s.packed)
        w.add_gt(s.gt[:1], [8])
    with pytest.raises(SpikeSimValueError, match="clean_packed"), \
            H5Writer(tmp_path / "a.h5", s.meta, clean=True) as w:
        w.append(s.packed)
    assert not (tmp_path / "a.h5").exists()
    with pytest.raises(ss.SpikeSimTypeError, match="meta"):
        write_h5(tmp_path / "a.h5", object())
    assert sorted(os.listdir(tmp_path)) == []


def test_sequence_repr_and_context(tmp_path, make_stream):
    path = write_h5(tmp_path / "r.h5", make_stream())
    with Sequence(path) as seq:
        assert "50 readouts" in repr(seq)
        seq.read_window(0, 1)
    assert seq._file is None


NO_PLUGIN_SCRIPT = """
import sys
sys.modules["hdf5plugin"] = None        # as if hdf5plugin were not installed
from spikesim.errors import SpikeSimFormatError
from spikesim.io import DEFAULT_COMPRESSION, open_h5
assert DEFAULT_COMPRESSION == "gzip:1", DEFAULT_COMPRESSION
try:
    open_h5(sys.argv[1]).read_window(0, 4)
except SpikeSimFormatError as exc:
    print(exc)
"""


@pytest.mark.timeout(180)
@pytest.mark.skipif(not have_hdf5plugin(), reason="writing a Zstd file needs hdf5plugin")
def test_zstd_file_without_hdf5plugin_says_what_to_install(tmp_path, make_stream):
    path = write_h5(tmp_path / "z.h5", make_stream(n=40, height=8, width=16), compression="zstd")
    env = {k: v for k, v in os.environ.items() if k != "HDF5_PLUGIN_PATH"}
    env["HDF5_PLUGIN_PATH"] = str(tmp_path / "no-plugins")
    proc = subprocess.run([sys.executable, "-c", NO_PLUGIN_SCRIPT, str(path)], env=env,
                          capture_output=True, text=True, timeout=150)
    assert proc.returncode == 0, proc.stderr
    assert "compression filter" in proc.stdout and "hdf5plugin" in proc.stdout


def test_stream_without_ground_truth(tmp_path):
    stream = ss.SpikeStream(packed=np.zeros((5, 3, 1), np.uint8),
                            meta={"height": 3, "width": 4, "cfa": None, "clock_hz": 1000.0})
    seq = open_h5(write_h5(tmp_path / "nogt.h5", stream))
    assert seq.gt_index.size == 0 and seq.n_readouts == 5 and seq.cfa is None
    with pytest.raises(SpikeSimValueError, match="no ground truth"):
        seq.read_gt(0)
    assert read_h5(tmp_path / "nogt.h5").gt.shape == (0, 3, 4, 3)
