"""The file commands: ``spikesim info``, ``spikesim convert``, ``spikesim preview``."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

import spikesim as ss
from spikesim.cli import main
from spikesim.io import open_h5, read_dat, write_dat, write_h5


@pytest.fixture
def h5file(tmp_path, make_stream):
    s = make_stream(n=120, height=16, width=24, cfa="RGGB", clean=True, gt_index=(20, 60, 100))
    return write_h5(tmp_path / "seq.h5", s), s


def test_info_h5_text_and_json(h5file, capsys):
    path, s = h5file
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "120 readouts x 16 x 24" in out and "RGGB" in out and "20, 60, 100" in out
    assert "clean twin yes" in out and "firing" in out
    assert main(["info", str(path), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["shape"] == [120, 16, 24] and info["duration_s"] == pytest.approx(120 / 20000)
    assert info["firing_rate"]["mean"] == pytest.approx(s.bits.mean())
    assert info["scene"] == s.meta["scene"]


def test_info_dat_guess_note_and_folder(tmp_path, capsys, h5file):
    spikes = (np.random.default_rng(0).random((4, 250, 400)) < 0.2).astype(np.uint8)
    write_dat(tmp_path / "cap.dat", spikes)
    assert main(["info", str(tmp_path / "cap.dat")]) == 0
    captured = capsys.readouterr()
    assert "4 readouts x 250 x 400" in captured.out
    assert "note: cap.dat: assumed 400x250" in captured.err
    assert main(["info", str(tmp_path), "--all", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["name"] == "seq"


def test_info_dat_of_unknown_size_names_the_size_options(tmp_path, capsys):
    (tmp_path / "odd.dat").write_bytes(b"\x00" * 12345)
    assert main(["info", str(tmp_path / "odd.dat")]) == 1
    err = capsys.readouterr().err
    assert "cannot guess the frame size" in err and "--height and --width" in err
    assert main(["info", str(tmp_path / "odd.dat"), "--height", "4", "--width", "8"]) == 1
    assert "--partial drop" in capsys.readouterr().err
    assert main(["info", str(tmp_path / "odd.dat"), "--height", "1", "--width", "8"]) == 0


def test_convert_h5_dat_h5_with_window_and_crop(tmp_path, h5file, capsys):
    path, s = h5file
    dat = tmp_path / "out.dat"
    assert main(["convert", str(path), str(dat), "--quiet"]) == 0
    assert np.array_equal(read_dat(dat, 16, 24), s.bits)
    back = tmp_path / "back.h5"
    assert main(["convert", str(dat), str(back), "--cfa", "RGGB", "--clock-hz", "20000",
                 "--height", "16", "--width", "24",
                 "--quiet", "--compression", "none"]) == 0
    seq = open_h5(back)
    assert np.array_equal(seq.read_packed(), s.packed) and seq.cfa == "RGGB"
    part = tmp_path / "part.h5"
    assert main(["convert", str(path), str(part), "--start", "50", "--length", "30",
                 "--crop", "3,5,9,13", "--quiet"]) == 0
    seq = open_h5(part)
    assert np.array_equal(seq.read_window(0, None), s.bits[50:80, 3:12, 5:18])
    assert np.array_equal(seq.read_window(0, None, clean=True),
                          np.unpackbits(s.clean_packed, axis=-1, count=24,
                                        bitorder="little")[50:80, 3:12, 5:18])
    assert seq.gt_index.tolist() == [10]  # readout 60 of the source
    assert np.array_equal(seq.read_gt(0), s.gt[1, 3:12, 5:18])
    assert seq.cfa == "BGGR"  # crop at an odd row and column of an RGGB mosaic
    capsys.readouterr()


def test_convert_raw_capture_dropping_head_columns(tmp_path):
    raw = (np.random.default_rng(1).random((3, 250, 416)) < 0.5).astype(np.uint8)
    write_dat(tmp_path / "raw.dat", raw)
    out = tmp_path / "clean.dat"
    assert main(["convert", str(tmp_path / "raw.dat"), str(out), "--drop-head",
                 "--height", "250", "--width", "416", "--quiet"]) == 0
    assert np.array_equal(read_dat(out, 250, 400), raw[:, :, 16:])


def test_convert_errors_exit_nonzero_without_output(tmp_path, h5file, capsys):
    path, _ = h5file
    assert main(["convert", str(path), str(tmp_path / "x.dat"), "--start", "500"]) == 1
    assert "start=500 is invalid" in capsys.readouterr().err
    assert not (tmp_path / "x.dat").exists()
    (tmp_path / "bad.dat").write_bytes(b"\x00" * 1001)
    assert main(["convert", str(tmp_path / "bad.dat"), str(tmp_path / "y.h5")]) == 1
    assert "cannot guess" in capsys.readouterr().err
    # the source given again as the output (another spelling of it) is not replaced
    before = path.read_bytes()
    assert main(["convert", str(path), str(path.parent / "." / path.name), "--start", "10"]) == 1
    assert "another file than SRC" in capsys.readouterr().err
    assert path.read_bytes() == before


def test_preview_png_and_gif(tmp_path, h5file, capsys):
    path, _ = h5file
    png = tmp_path / "p.png"
    assert main(["preview", str(path), "--out", str(png), "--readout", "60"]) == 0
    img = np.asarray(Image.open(png))
    assert img.shape == (16, 24, 3) and img.dtype == np.uint8 and img.std() > 0
    gif = tmp_path / "p.gif"
    assert main(["preview", str(path), "--out", str(gif), "--method", "tfi", "--frames", "5",
                 "--quiet"]) == 0
    with Image.open(gif) as g:
        assert g.n_frames == 5 and g.size == (24, 16)
    assert main(["preview", str(path), "--out", str(tmp_path / "p.jpg")]) == 1
    assert "png or .gif" in capsys.readouterr().err


def test_preview_mono_dat_is_grey(tmp_path):
    spikes = np.zeros((50, 8, 16), np.uint8)
    spikes[::2, :, :8] = 1  # left half fires every other readout
    write_dat(tmp_path / "m.dat", spikes)
    out = tmp_path / "m.png"
    assert main(["preview", str(tmp_path / "m.dat"), "--out", str(out), "--height", "8",
                 "--width", "16", "--window", "20", "--rate", "0.5"]) == 0
    img = np.asarray(Image.open(out)).astype(int)
    assert (img[..., 0] == img[..., 1]).all() and (img[..., 1] == img[..., 2]).all()
    assert img[:, :8].min() == 255 and img[:, 8:].max() == 0


def test_preview_of_a_stream_shorter_than_the_default_window(tmp_path, capsys):
    """The default window is 41 readouts or the whole stream when shorter; an
    explicit window longer than the stream is named."""
    spikes = np.zeros((10, 8, 16), np.uint8)
    spikes[::2, :, :8] = 1
    write_dat(tmp_path / "m.dat", spikes)
    base = ["preview", str(tmp_path / "m.dat"), "--height", "8", "--width", "16",
            "--rate", "0.5"]
    assert main(base + ["--out", str(tmp_path / "m.png")]) == 0
    img = np.asarray(Image.open(tmp_path / "m.png")).astype(int)
    assert img[:, :8].min() == 255 and img[:, 8:].max() == 0
    assert main(base + ["--out", str(tmp_path / "n.png"), "--window", "11"]) == 1
    assert "--window=11" in capsys.readouterr().err and not (tmp_path / "n.png").exists()
    assert main(base + ["--out", str(tmp_path / "g.gif"), "--frames", "20", "--step", "1",
                        "--window", "3", "--quiet"]) == 0
    assert "9 of the 20 frames asked for fit" in capsys.readouterr().err


def test_convert_to_sjdd_layout(tmp_path, h5file, capsys):
    path, _ = h5file
    assert main(["convert", str(path), str(tmp_path / "train"), "--sjdd", "--subset", "s1",
                 "--quiet"]) == 0
    assert "wrote 3 samples" in capsys.readouterr().out
    assert len(list((tmp_path / "train" / "spk" / "0" / "s1").glob("*.dat"))) == 3
    assert len(list((tmp_path / "train" / "gt" / "s1").glob("*.npy"))) == 3


def test_info_of_a_folder_says_which_sequence_of_how_many(tmp_path, capsys):
    scene = ss.scenes.Static(np.full((8, 16), 0.3, np.float32))
    for name in ("a", "b", "c"):
        write_h5(tmp_path / f"{name}.h5", ss.simulate(scene, ss.Sensor(height=8, width=16), 5))
    assert main(["info", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert out.rstrip().endswith(f"(sequence 1 of 3 in {tmp_path}: --sequence picks another, "
                                 "--all describes every one)")
    for pick in ("1", "b"):  # by position (0-based) and by name
        assert main(["info", str(tmp_path), "--sequence", pick]) == 0
        out = capsys.readouterr().out
        assert out.startswith("b  ") and "(sequence 2 of 3 in" in out
    assert main(["info", str(tmp_path / "a.h5")]) == 0
    assert "(sequence " not in capsys.readouterr().out


def test_file_commands_take_split_of_a_dataset_root(tmp_path, capsys):
    """preview, convert (also --sjdd) and info read a split of a dataset root with
    --split, as the root's error message tells them to."""
    sensor = ss.Sensor(height=8, width=16, cfa="RGGB")
    for split, seed in (("train", 0), ("val", 1)):
        (tmp_path / "root" / split).mkdir(parents=True)
        scene = ss.scenes.procedural("astronaut", size=(8, 16))
        write_h5(tmp_path / "root" / split / f"s{seed}.h5",
                 ss.simulate(scene, sensor, 45, seed=seed, gt_readouts=[22]))
    root = str(tmp_path / "root")
    assert main(["preview", root, "--out", str(tmp_path / "p.png")]) == 1
    assert "pick one with --split NAME" in capsys.readouterr().err
    assert main(["preview", root, "--split", "val", "--out", str(tmp_path / "p.png")]) == 0
    assert main(["convert", root, str(tmp_path / "c.h5"), "--split", "val", "--quiet"]) == 0
    assert open_h5(tmp_path / "c.h5").meta["seed"] == 1
    assert main(["convert", root, str(tmp_path / "sj"), "--sjdd", "--split", "train",
                 "--quiet"]) == 0
    assert main(["info", root, "--split", "train", "--json"]) == 0
    assert "s0" in capsys.readouterr().out
    assert main(["convert", str(tmp_path / "c.h5"), str(tmp_path / "d.h5"),
                 "--compression", "brotli"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("spikesim convert: error: --compression='brotli'") and "\r" not in err
    assert not (tmp_path / "d.h5").exists()
