"""Damaged files through every reader: an error naming the file, or exactly the original data.

Hypothesis draws truncations, bit flips anywhere, bit flips inside compressed
chunks and inside the header, and attribute tampering.  Whatever it draws,
each reader (``open_h5``, ``read_h5``, ``verify``, spikejdd's
``SpikeWindowDataset``, the ``info``/``verify``/``convert``/``preview``
commands) either raises a :class:`SpikeSimError` (a command: exit 1, one
line, no traceback) or returns data equal to the original: never different
bits, different ground truth or a different header.
"""

from __future__ import annotations

import contextlib
import io
import math
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from spikesim.errors import SpikeSimError
from tests.support.fault_helpers import FULL

EXAMPLES = 150 if FULL else 12
SETTINGS = settings(max_examples=EXAMPLES, deadline=None, derandomize=not FULL,
                    suppress_health_check=list(HealthCheck))


def _chunk_spans(path: Path) -> list[tuple[int, int]]:
    spans = []
    with h5py.File(path, "r") as f:
        for name in ("spikes", "clean_spikes", "gt", "gt_index"):
            ds = f[name]
            for i in range(ds.id.get_num_chunks()):
                info = ds.id.get_chunk_info(i)
                spans.append((info.byte_offset, info.size))
    return spans


def _read_everything(path: Path) -> dict:
    """Every reader of the library; returns what they read (raises SpikeSimError)."""
    from spikesim.io import open_h5, read_h5, verify_file

    with open_h5(path) as seq:
        got = {"packed": seq.read_packed(), "clean": seq.read_packed(clean=True),
               "gt": seq.read_all_gt(), "gt_index": seq.gt_index.copy(), "shape": seq.shape,
               "cfa": seq.cfa, "clock_hz": seq.clock_hz, "meta": seq.meta}
        window = seq.read_window(5, 20, crop=(1, 3, 9, 13))
        np.testing.assert_array_equal(window, np.unpackbits(
            got["packed"], axis=-1, bitorder="little")[5:25, 1:10, 3:16])
    stream = read_h5(path)
    np.testing.assert_array_equal(stream.packed, got["packed"])
    report = verify_file(path)
    assert report["ok"], report  # readers succeeded, so verify must agree
    return got


def _assert_same(got: dict, orig: dict) -> None:
    for key in ("packed", "clean", "gt", "gt_index"):
        np.testing.assert_array_equal(got[key], orig[key], err_msg=f"silently changed {key}")
    for key in ("shape", "cfa", "meta"):
        assert got[key] == orig[key], f"silently changed {key}"
    assert got["clock_hz"] == orig["clock_hz"] or (math.isnan(got["clock_hz"]) and
                                                   math.isnan(orig["clock_hz"]))


def _check(path: Path, orig: dict) -> str:
    """'error' when a reader refused the file, 'same' when everything read equals the original."""
    from spikesim.io import verify_file

    try:
        got = _read_everything(path)
    except SpikeSimError as exc:
        assert str(path.name) in str(exc) or "damaged" in str(exc), exc
        assert not verify_file(path)["ok"]
        return "error"
    _assert_same(got, orig)
    return "same"


def _mutated(tmp_path: Path, src: Path, edit) -> Path:
    data = bytearray(src.read_bytes())
    data = edit(data)
    out = tmp_path / f"m{len(list(tmp_path.iterdir()))}.h5"
    out.write_bytes(bytes(data))
    return out


@SETTINGS
@given(cut=st.floats(0.0, 0.999))
def test_truncation(h5_original, tmp_path_factory, cut):
    src, orig = h5_original
    tmp = tmp_path_factory.mktemp("trunc")
    n = len(src.read_bytes())
    path = _mutated(tmp, src, lambda d: d[: int(cut * n)])
    assert _check(path, orig) == "error"  # every truncation loses something


@SETTINGS
@given(flips=st.lists(st.tuples(st.floats(0.0, 0.9999), st.integers(0, 7)), min_size=1,
                      max_size=4))
def test_bit_flips_anywhere(h5_original, tmp_path_factory, flips):
    src, orig = h5_original
    tmp = tmp_path_factory.mktemp("flip")
    n = len(src.read_bytes())

    def edit(d):
        for pos, bit in flips:
            d[int(pos * n)] ^= 1 << bit
        return d

    _check(_mutated(tmp, src, edit), orig)


@SETTINGS
@given(which=st.integers(0, 10**6), pos=st.floats(0.0, 0.9999), bit=st.integers(0, 7))
def test_bit_flip_inside_a_compressed_chunk_is_an_error(h5_original, tmp_path_factory,
                                                        which, pos, bit):
    src, orig = h5_original
    tmp = tmp_path_factory.mktemp("chunk")
    spans = _chunk_spans(src)
    offset, size = spans[which % len(spans)]

    def edit(d):
        d[offset + int(pos * size)] ^= 1 << bit
        return d

    assert _check(_mutated(tmp, src, edit), orig) == "error"  # the checksum catches it


@SETTINGS
@given(pos=st.integers(0, 4095), bit=st.integers(0, 7))
def test_bit_flip_in_the_header(h5_original, tmp_path_factory, pos, bit):
    src, orig = h5_original
    tmp = tmp_path_factory.mktemp("head")

    def edit(d):
        d[pos % len(d)] ^= 1 << bit
        return d

    _check(_mutated(tmp, src, edit), orig)


TAMPER = {
    "cfa XYZW": lambda f: f.attrs.__setitem__("cfa", "XYZW"),
    "clock_hz -5": lambda f: f.attrs.__setitem__("clock_hz", -5.0),
    "clock_hz nan": lambda f: f.attrs.__setitem__("clock_hz", float("nan")),
    "clock_hz inf": lambda f: f.attrs.__setitem__("clock_hz", float("inf")),
    "clock_hz text": lambda f: f.attrs.__setitem__("clock_hz", "fast"),
    "sensor json": lambda f: f.attrs.__setitem__("sensor", "{not json"),
    "sensor list": lambda f: f.attrs.__setitem__("sensor", "[1, 2]"),
    "scene json": lambda f: f.attrs.__setitem__("scene", "{"),
    "n_readouts": lambda f: f.attrs.__setitem__("n_readouts", 7),
    "height 0": lambda f: f.attrs.__setitem__("height", 0),
    "width -3": lambda f: f.attrs.__setitem__("width", -3),
    "format_version 99": lambda f: f.attrs.__setitem__("format_version", 99),
    "format other": lambda f: f.attrs.__setitem__("format", "other"),
    "bitorder big": lambda f: f.attrs.__setitem__("bitorder", "big"),
    "meta list": lambda f: f.attrs.__setitem__("meta", "[]"),
    "meta json": lambda f: f.attrs.__setitem__("meta", "{"),
    "no cfa": lambda f: f.attrs.__delitem__("cfa"),
    "no meta": lambda f: f.attrs.__delitem__("meta"),
    "no spikes": lambda f: f.__delitem__("spikes"),
    "gt nan": lambda f: f["gt"].__setitem__((0, 0, 0, 0), np.nan),
    "gt inf": lambda f: f["gt"].__setitem__((2, 3, 4, 1), np.inf),
    "gt_index out of range": lambda f: f["gt_index"].__setitem__(0, 10**6),
    "gt_index negative": lambda f: f["gt_index"].__setitem__(1, -1),
}


@pytest.mark.parametrize("name", sorted(TAMPER))
def test_attribute_tampering_is_an_error(h5_original, tmp_path, name):
    src, orig = h5_original
    path = tmp_path / "t.h5"
    shutil.copy(src, path)
    with h5py.File(path, "r+") as f:
        TAMPER[name](f)
    assert _check(path, orig) == "error"


def _spikesim(argv) -> tuple[int, str]:
    from spikesim.cli import main

    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        code = main([str(a) for a in argv])
    return code, err.getvalue() + out.getvalue()


@pytest.mark.parametrize("command", ["info", "verify", "convert", "preview"])
@pytest.mark.parametrize("damage", ["chunk", "truncate", "gt nan", "cfa XYZW"])
def test_commands_on_damaged_files_fail_cleanly(h5_original, tmp_path, monkeypatch, command,
                                                damage):
    src, _ = h5_original
    monkeypatch.chdir(tmp_path)
    path = tmp_path / "d.h5"
    data = bytearray(src.read_bytes())
    if damage == "chunk":
        offset, size = _chunk_spans(src)[0]
        data[offset + size // 2] ^= 0x20
        path.write_bytes(bytes(data))
    elif damage == "truncate":
        path.write_bytes(bytes(data[: len(data) * 2 // 3]))
    else:
        path.write_bytes(bytes(data))
        with h5py.File(path, "r+") as f:
            TAMPER[damage](f)
    if damage == "gt nan" and command in ("info", "preview"):
        pytest.skip("info and preview never read ground truth")
    target = "o.h5" if damage == "gt nan" else "o.dat"  # .dat output carries no ground truth
    argv = {"info": ["info", path], "verify": ["verify", path],
            "convert": ["convert", path, target], "preview": ["preview", path, "--out", "o.png"]}
    code, err = _spikesim(argv[command])
    assert code == 1, err
    assert "Traceback" not in err, err
    if command == "verify":  # the report: one DAMAGED line and the count
        assert "DAMAGED" in err and "1 damaged" in err, err
    else:
        assert sum("error" in ln for ln in err.splitlines()) == 1, err
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith(("o.", ".o."))]


@SETTINGS
@given(cut=st.integers(1, 10**6), flips=st.lists(st.integers(0, 10**7), max_size=3))
def test_dat_damage_never_crashes_a_reader(dat_original, tmp_path_factory, cut, flips):
    """A .dat has no checksum: a flipped bit is a different spike.  Readers must still
    never crash: a truncation is an error (partial frame) or fewer whole readouts."""
    from spikesim.io import open_dat, read_dat

    src, frames = dat_original
    tmp = tmp_path_factory.mktemp("dat")
    data = bytearray(src.read_bytes())
    data = data[: max(0, len(data) - cut % len(data))]
    for f in flips:
        if data:
            data[f % len(data)] ^= 0x01
    path = tmp / "d.dat"
    path.write_bytes(bytes(data))
    frame_bytes = 250 * 400 // 8
    try:
        got = read_dat(path, 250, 400)
    except SpikeSimError as exc:
        assert len(data) % frame_bytes or not data, exc
        with pytest.raises(SpikeSimError):
            open_dat(path, 250, 400).read()
        return
    assert got.shape == (len(data) // frame_bytes, 250, 400)
    if not flips:
        np.testing.assert_array_equal(got, frames[: got.shape[0]])


def test_spikejdd_window_dataset_refuses_damaged_chunks(h5_original, tmp_path):
    pytest.importorskip("torch")
    from spikejdd.data import SpikeWindowDataset

    src, _ = h5_original
    path = tmp_path / "d.h5"
    data = bytearray(src.read_bytes())
    for offset, size in _chunk_spans(src):
        data[offset + size // 3] ^= 0x04
    path.write_bytes(bytes(data))
    with pytest.raises(SpikeSimError, match="damaged"):
        ds = SpikeWindowDataset(str(path), window=9, train=False)
        for i in range(len(ds)):
            ds[i]
