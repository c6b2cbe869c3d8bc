"""Fixes from a user trial of spikesim.io: empty writes, loose argument checks, guessing the
frame size of a truncated .dat, and the wording of a missing path."""

from __future__ import annotations

import os
import warnings

import numpy as np
import pytest

from spikesim.errors import (
    SpikeSimFileError,
    SpikeSimFormatError,
    SpikeSimTypeError,
    SpikeSimValueError,
)
from spikesim.io import (
    DatFile,
    DatWriter,
    H5Writer,
    atomic_path,
    build_index,
    guess_dat_shape,
    open_dat,
    open_dataset,
    open_h5,
    read_dat,
    resolve_dataset,
    write_dat,
    write_h5,
)


def _names(folder) -> list[str]:
    """Everything in ``folder``, hidden temporaries included."""
    return sorted(os.listdir(folder))


# --- 1. the writers refuse to make a file with no readout, and leave nothing ---------------

def test_write_dat_of_zero_readouts_is_refused(tmp_path):
    with pytest.raises(SpikeSimValueError, match=r"spikes.shape=\(0, 4, 8\).*T >= 1"):
        write_dat(tmp_path / "e.dat", np.zeros((0, 4, 8), np.uint8))
    assert _names(tmp_path) == []


def test_write_dat_of_an_empty_stream_or_run_is_refused(tmp_path, make_stream, make_run):
    empty = make_stream(n=0, height=4, width=8, gt_index=())
    with pytest.raises(SpikeSimValueError, match="no readout was written"):
        write_dat(tmp_path / "s.dat", empty)
    with pytest.raises(SpikeSimValueError, match="no readout was written"):
        write_dat(tmp_path / "r.dat", make_run(empty))
    assert _names(tmp_path) == []


def test_dat_writer_closed_without_frames_leaves_nothing(tmp_path):
    with pytest.raises(SpikeSimValueError, match=r"no readout was written to .*z\.dat"):
        with DatWriter(tmp_path / "z.dat", 64, 100):
            pass
    assert _names(tmp_path) == []


def test_h5_writer_closed_without_readouts_leaves_nothing(tmp_path, make_stream):
    meta = make_stream(n=4, gt_index=(1,)).meta
    with pytest.raises(SpikeSimValueError, match=r"no readout was written to .*z\.h5"):
        with H5Writer(tmp_path / "z.h5", meta):
            pass
    assert _names(tmp_path) == []


def test_write_h5_of_an_empty_stream_leaves_nothing(tmp_path, make_stream):
    with pytest.raises(SpikeSimValueError, match="no readout was written"):
        write_h5(tmp_path / "e.h5", make_stream(n=0, gt_index=()))
    assert _names(tmp_path) == []


def test_writers_still_write_one_readout(tmp_path, make_stream):
    s = make_stream(n=1, height=4, width=8, gt_index=(0,))
    write_h5(tmp_path / "one.h5", s)
    assert open_h5(tmp_path / "one.h5").n_readouts == 1
    assert write_dat(tmp_path / "one.dat", s.bits) == 1
    assert read_dat(tmp_path / "one.dat", 4, 8).shape == (1, 4, 8)


# --- 4. flags are bools, paths name their format, indices are never negative -------------

@pytest.mark.parametrize("flag", ["no", "yes", 1, None])
def test_write_dat_refuses_a_flag_that_is_not_a_bool(tmp_path, flag):
    with pytest.raises(SpikeSimValueError, match="flip=.*expected True or False"):
        write_dat(tmp_path / "f.dat", np.zeros((2, 4, 8), np.uint8), flip=flag)
    assert _names(tmp_path) == []


def test_readers_and_writers_refuse_string_flags(tmp_path, make_stream):
    s = make_stream(n=8, height=4, width=8, gt_index=(2,))
    write_h5(tmp_path / "a.h5", s)
    write_dat(tmp_path / "a.dat", s.bits)
    seq = open_h5(tmp_path / "a.h5")
    cases = [
        ("flip", lambda: DatFile(tmp_path / "a.dat", 4, 8, flip="False")),
        ("flip", lambda: open_dat(tmp_path / "a.dat", 4, 8, flip="no")),
        ("packed", lambda: open_dat(tmp_path / "a.dat", 4, 8).read_window(0, 2, packed="no")),
        ("packed", lambda: seq.read_window(0, 2, packed="no")),
        ("clean", lambda: seq.read_window(0, 2, clean="no")),
        ("overwrite", lambda: DatWriter(tmp_path / "b.dat", 4, 8, overwrite="no")),
        ("clean", lambda: H5Writer(tmp_path / "b.h5", s.meta, clean="yes")),
        ("overwrite", lambda: write_h5(tmp_path / "b.h5", s, overwrite="no")),
        ("progress", lambda: write_h5(tmp_path / "b.h5", s, progress="no")),
        ("write", lambda: build_index(tmp_path, write="no")),
    ]
    for name, call in cases:
        with pytest.raises(SpikeSimValueError, match=f"{name}=.*True or False"):
            call()
    with pytest.raises(SpikeSimValueError, match="overwrite="), atomic_path(
            tmp_path / "c.txt", overwrite="no"):
        pass
    assert not [n for n in _names(tmp_path) if n.startswith((".b", "b.", ".c", "c."))]


def test_numpy_bools_are_flags(tmp_path):
    spikes = np.zeros((2, 4, 8), np.uint8)
    assert write_dat(tmp_path / "n.dat", spikes, flip=np.bool_(False)) == 2
    assert not DatFile(tmp_path / "n.dat", 4, 8, flip=np.bool_(False)).flip


@pytest.mark.parametrize("name", ["a.dat", "a", "a.h5.tmp", "a.txt"])
def test_write_h5_refuses_a_name_of_another_format(tmp_path, make_stream, name):
    with pytest.raises(SpikeSimValueError, match=r"path=.*\.h5 or \.hdf5.*write_dat"):
        write_h5(tmp_path / name, make_stream(n=4, gt_index=(1,)))
    assert _names(tmp_path) == []


def test_write_h5_takes_h5_and_hdf5_in_any_case(tmp_path, make_stream):
    for name in ("a.h5", "b.HDF5"):
        write_h5(tmp_path / name, make_stream(n=4, gt_index=(1,)))
        assert open_h5(tmp_path / name).n_readouts == 4


@pytest.mark.parametrize("name", ["a.h5", "a.hdf5"])
def test_write_dat_refuses_an_hdf5_name(tmp_path, name):
    with pytest.raises(SpikeSimValueError, match="path=.*write_h5"):
        write_dat(tmp_path / name, np.zeros((2, 4, 8), np.uint8))
    assert _names(tmp_path) == []


@pytest.mark.parametrize("path", [5, None, b"a.h5", 3.5])
def test_write_h5_names_a_path_of_the_wrong_type(make_stream, path):
    with pytest.raises(SpikeSimTypeError, match=r"^path must be a file path \(str or "
                                                r"os.PathLike\), got"):
        write_h5(path, make_stream(n=4, gt_index=(1,)))


def test_write_dat_names_a_path_of_the_wrong_type():
    with pytest.raises(SpikeSimTypeError, match="^path must be a file path"):
        write_dat(5, np.zeros((2, 4, 8), np.uint8))


def test_write_h5_checks_block_readouts(tmp_path, make_stream):
    with pytest.raises(SpikeSimValueError, match="block_readouts="):
        write_h5(tmp_path / "a.h5", make_stream(n=4, gt_index=(1,)), block_readouts=0)


def test_read_gt_refuses_a_negative_position_like_read_window(tmp_path, make_stream):
    write_h5(tmp_path / "g.h5", make_stream(n=40, gt_index=(5, 25)))
    seq = open_h5(tmp_path / "g.h5")
    with pytest.raises(SpikeSimValueError, match=r"start=-1 is invalid"):
        seq.read_window(-1, 3)
    for k in (-1, -2, 2, True, "0"):
        with pytest.raises(SpikeSimValueError, match=r"k=.*is invalid: expected a position in "
                                                     r"gt_index, in \[0, 1\]"):
            seq.read_gt(k)
    assert seq.read_gt(np.int64(1)).shape == (6, 13, 3)


# --- 5. guessing the size of a truncated .dat with partial="drop" -------------------------

def _truncated_vidar(tmp_path, frames=3, extra=7):
    """A 400x250 capture of ``frames`` frames and ``extra`` bytes of a cut-off frame."""
    spikes = (np.random.default_rng(1).random((frames, 250, 400)) < 0.2).astype(np.uint8)
    write_dat(tmp_path / "whole.dat", spikes)
    data = (tmp_path / "whole.dat").read_bytes()
    path = tmp_path / "trunc.dat"
    path.write_bytes(data + data[:extra])
    return path, spikes


def test_read_dat_guesses_the_size_of_a_truncated_capture_with_partial_drop(tmp_path):
    """Guessed where one known size alone fits a whole frame; where several do, a cut
    capture could be any of them, so the reader asks for the size instead of taking
    the first (a cut 1000x1000 capture read as 400x250)."""
    path, spikes = _truncated_vidar(tmp_path, frames=1)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        got = read_dat(path, partial="drop")
    np.testing.assert_array_equal(got, spikes)
    text = " | ".join(str(w.message) for w in caught)
    assert "assumed 400x250" in text and "7 trailing bytes" in text
    assert "the partial frame is ignored" in text
    path, spikes = _truncated_vidar(tmp_path, frames=3)
    with pytest.raises(SpikeSimFormatError, match=r"could be any of 400x250, 416x250, 448x256 "
                                                  r"\(W x H\); pass height and width"):
        read_dat(path, partial="drop")
    with pytest.warns(UserWarning, match="the partial frame is ignored"):
        np.testing.assert_array_equal(read_dat(path, 250, 400, partial="drop"), spikes)
    cut_colour = np.zeros(125_000 * 2 + 99, np.uint8)  # two 1000x1000 frames and a part
    with pytest.raises(SpikeSimFormatError, match="400x250, 416x250, 1000x1000"):
        guess_dat_shape(cut_colour.size, partial="drop")


def test_guessing_a_truncated_capture_without_drop_says_how(tmp_path):
    path, _ = _truncated_vidar(tmp_path)
    with pytest.raises(Exception, match=r"cannot guess the frame size.*--height and --width"
                                        r".*partial='drop' \(--partial drop\)"):
        read_dat(path)


def test_guess_prefers_an_exact_fit_and_drop_needs_a_whole_frame():
    assert guess_dat_shape(13000 * 2, partial="drop")[:2] == (250, 416)  # exact, not 400x250
    h, w, msg = guess_dat_shape(12500 + 3, partial="drop")
    assert (h, w) == (250, 400) and "1 readouts and 3 trailing bytes" in msg
    with pytest.raises(Exception, match="cannot guess"):
        guess_dat_shape(100, partial="drop")  # not one whole frame of any known size
    with pytest.raises(SpikeSimValueError, match="partial="):
        guess_dat_shape(12500, partial="yes")


# --- 6. a missing path that looks like a file ----------------------------------------------

@pytest.mark.parametrize("name", ["nope.h5", "x.h5x", "seq.hdf5"])
def test_a_missing_file_path_is_no_such_file_or_dataset_folder(tmp_path, name):
    pattern = r"^no such file or dataset folder: '.*" + name.replace(".", r"\.")
    for call in (open_dataset, resolve_dataset):
        with pytest.raises(SpikeSimFileError, match=pattern):
            call(tmp_path / name)


def test_a_missing_folder_is_still_no_such_dataset_folder(tmp_path):
    with pytest.raises(SpikeSimFileError, match="^no such dataset folder"):
        open_dataset(tmp_path / "nosuch")


def test_info_of_a_missing_file_says_no_such_file_or_dataset_folder(tmp_path, capsys):
    from spikesim.cli import main

    assert main(["info", str(tmp_path / "nope.h5")]) == 1
    err = capsys.readouterr().err
    assert "no such file or dataset folder" in err and len(err.strip().splitlines()) == 1


def test_dropping_head_columns_of_a_frame_that_has_none_warns(tmp_path):
    """The 16 head columns belong to raw 416-wide captures: asking to drop them from a
    400-wide file warns that real columns go; a 416-wide file drops them silently."""
    write_dat(tmp_path / "a.dat", np.zeros((3, 8, 400), np.uint8))
    with pytest.warns(UserWarning, match="head_columns=16 on a 400-wide frame"):
        assert read_dat(tmp_path / "a.dat", 8, 400, head_columns=16).shape == (3, 8, 384)
    write_dat(tmp_path / "b.dat", np.zeros((3, 8, 416), np.uint8))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert read_dat(tmp_path / "b.dat", 8, 416, head_columns=16).shape == (3, 8, 400)
