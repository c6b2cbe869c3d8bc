"""SJDD-Net layout export: folders, names, 39-readout windows, GT arrays, noise labels."""

from __future__ import annotations

import json

import numpy as np
import pytest

from spikesim.errors import SpikeSimFormatError, SpikeSimValueError
from spikesim.io import export_sjdd, open_dataset, write_h5
from spikesim.io.export import sjdd_noise_label


def _paper(sigma_g, sigma_p=0.0):
    return {"type": "paper", "sigma_g": sigma_g, "sigma_p": sigma_p}


def _dataset(tmp_path, make_stream, noises, cfa="RGGB", h=8, w=12, n=80, gt=(10, 19, 40, 60, 79)):
    src = tmp_path / "src"
    src.mkdir(parents=True)
    for i, noise in enumerate(noises):
        s = make_stream(n=n, height=h, width=w, cfa=cfa, seed=i, gt_index=gt, noise=noise)
        write_h5(src / f"seq{i}.h5", s)
    return src


def sjdd_read_dat(path, h, w):
    """What the SJDD-Net loader does (raw2spike, upside_down=False): frames of H*W/8 bytes."""
    raw = np.fromfile(path, np.uint8)
    n = raw.size // (h * w // 8)
    return np.unpackbits(raw.reshape(n, -1), axis=1, bitorder="little").reshape(n, h, w)


def test_fixed_gaussian_level_layout(tmp_path, make_stream):
    src = _dataset(tmp_path, make_stream, [_paper(15.0), _paper(15.0)])
    out = tmp_path / "data" / "train"
    summary = export_sjdd(src, out, subset="synth")
    assert summary["noise_folder"] == "15" and summary["color_mode"] == "rggb"
    # readouts 10 and 79 cannot hold a centred 39-readout window in 80 readouts
    assert summary["samples"] == 2 * 3
    assert sorted(summary["skipped"]) == ["seq0@10", "seq0@79", "seq1@10", "seq1@79"]
    dats = sorted((out / "spk" / "15" / "synth").glob("*.dat"))
    gts = sorted((out / "gt" / "synth").glob("*.npy"))
    assert [p.stem for p in dats] == [p.stem for p in gts]
    assert dats[0].name == "seq0_000019.dat"
    ds = open_dataset(src)
    for dat, gtp in zip(dats, gts, strict=True):
        name, readout = dat.stem.rsplit("_", 1)
        seq, n = ds.sequence(name), int(readout)
        assert dat.stat().st_size == 39 * 8 * 12 // 8
        spikes = sjdd_read_dat(dat, 8, 12)
        assert spikes.shape == (39, 8, 12)
        assert np.array_equal(spikes, seq.read_window(n - 19, 39))
        gt = np.load(gtp)
        assert gt.shape == (1, 3, 8, 12) and gt.dtype == np.uint8
        k = int(np.flatnonzero(seq.gt_index == n)[0])
        want = np.rint(np.clip(seq.read_gt(k), 0, 1) * 255).astype(np.uint8).transpose(2, 0, 1)
        assert np.array_equal(gt[0], want)
    record = json.loads((out / "spikesim_export.json").read_text())
    assert record["gt_encoding"] == "linear" and record["flip"] is False
    assert len(record["sample_list"]) == 6


def test_random_gaussian_levels_go_in_file_names(tmp_path, make_stream):
    src = _dataset(tmp_path, make_stream, [_paper(2.5), _paper(11.0)], gt=(30,))
    out = tmp_path / "eval"
    summary = export_sjdd(src, out, subset="test")
    assert summary["noise_folder"] == "r"
    names = sorted(p.name for p in (out / "spk" / "r" / "test").glob("*.dat"))
    assert names == ["seq0_000030-2.5.dat", "seq1_000030-11.dat"]
    # the SJDD-Net loader's parse: path.split('-')[-1].replace('.dat', '')
    assert [float(n.split("-")[-1].replace(".dat", "")) for n in names] == [2.5, 11.0]


def test_noise_labels_and_refusals(tmp_path, make_stream):
    assert sjdd_noise_label({"sensor": {"noise": None}}) == ("0", 0.0)
    assert sjdd_noise_label({"sensor": {"noise": _paper(5.0, 2.0)}}) == ("gp", None)
    with pytest.raises(SpikeSimValueError, match="noise"):
        sjdd_noise_label({"sensor": {"noise": {"type": "physical"}}})
    gp = _dataset(tmp_path / "a", make_stream, [_paper(3, 1.0)], gt=(40,))
    assert export_sjdd(gp, tmp_path / "gp")["noise_folder"] == "gp"
    assert export_sjdd(gp, tmp_path / "named", noise="mine")["noise_folder"] == "mine"
    with pytest.raises(SpikeSimValueError, match="σ_g = 5"):  # a level folder must be true
        export_sjdd(gp, tmp_path / "five", noise="5")
    mono = _dataset(tmp_path / "b", make_stream, [None], cfa=None)
    with pytest.raises(SpikeSimFormatError, match="Bayer"):
        export_sjdd(mono, tmp_path / "m")
    odd = _dataset(tmp_path / "c", make_stream, [None], h=5, w=7)
    with pytest.raises(SpikeSimValueError, match="multiple of 8"):
        export_sjdd(odd, tmp_path / "o")
    with pytest.raises(SpikeSimValueError, match="gt_encoding"):
        export_sjdd(gp, tmp_path / "x", gt_encoding="gamma")


def test_srgb_ground_truth_option(tmp_path, make_stream):
    src = _dataset(tmp_path, make_stream, [None], gt=(40,))
    export_sjdd(src, tmp_path / "lin")
    export_sjdd(src, tmp_path / "srgb", gt_encoding="srgb")
    lin = np.load(next((tmp_path / "lin" / "gt" / "spikesim").glob("*.npy"))).astype(float)
    srgb = np.load(next((tmp_path / "srgb" / "gt" / "spikesim").glob("*.npy"))).astype(float)
    assert (srgb >= lin).all() and srgb.mean() > lin.mean() + 20  # sRGB lifts mid-tones


def _physical(tmp_path, make_stream):
    return _dataset(tmp_path, make_stream, [{"type": "physical", "shot": True}], gt=(40,))


def test_named_folder_wins_for_physical_noise(tmp_path, make_stream):
    src = _physical(tmp_path / "p", make_stream)
    summary = export_sjdd(src, tmp_path / "out", noise="phy")
    assert summary["noise_folder"] == "phy" and summary["samples"] == 1
    assert (tmp_path / "out" / "spk" / "phy" / "spikesim" / "seq0_000040.dat").is_file()
    auto = export_sjdd(src, tmp_path / "auto")  # physical mode: its own label, 'phy'
    assert auto["noise_folder"] == "phy"
    assert (tmp_path / "auto" / "spk" / "phy" / "spikesim" / "seq0_000040.dat").is_file()
    with pytest.raises(SpikeSimValueError, match="Gaussian sequences only"):
        export_sjdd(src, tmp_path / "r", noise="r")


def test_mixed_paper_and_physical_export_each_to_its_folder(tmp_path, make_stream):
    src = _dataset(tmp_path, make_stream, [_paper(5.0), {"type": "physical", "shot": True}],
                   gt=(40,))
    summary = export_sjdd(src, tmp_path / "mix", subset="s")
    got = {(e["noise_folder"], e["subset"], e["samples"]) for e in summary["exports"]}
    assert got == {("5", "s-5", 1), ("phy", "s-phy", 1)}


def test_mixed_labels_export_each_to_its_folder(tmp_path, make_stream):
    src = _dataset(tmp_path, make_stream, [_paper(5.0), _paper(3.0, 1.0), _paper(10.0)],
                   gt=(40,))
    out = tmp_path / "mix"
    summary = export_sjdd(src, out, subset="s")
    assert summary["noise_folder"] == "mixed"
    got = {(e["noise_folder"], e["subset"], e["samples"]) for e in summary["exports"]}
    assert got == {("gp", "s-gp", 1), ("r", "s-r", 2)}
    # each (noise, subset) pairs one to one by sorted name, as the SJDD-Net loader reads it
    assert sorted(p.name for p in (out / "spk" / "r" / "s-r").glob("*.dat")) == [
        "seq0_000040-5.dat", "seq2_000040-10.dat"]
    assert sorted(p.name for p in (out / "gt" / "s-r").glob("*.npy")) == [
        "seq0_000040.npy", "seq2_000040.npy"]
    assert [p.name for p in (out / "spk" / "gp" / "s-gp").glob("*")] == ["seq1_000040.dat"]
    assert [p.name for p in (out / "gt" / "s-gp").glob("*")] == ["seq1_000040.npy"]


def test_cli_names_the_flag(tmp_path, make_stream, capsys):
    from spikesim.cli import main

    src = _physical(tmp_path / "p", make_stream)
    assert main(["convert", str(src), str(tmp_path / "o"), "--sjdd", "--noise", "r",
                 "--quiet"]) != 0
    err = capsys.readouterr().err
    assert "--noise 'r' is invalid" in err and "noise=" not in err
    assert len(err.strip().splitlines()) == 1
    assert main(["convert", str(src), str(tmp_path / "o"), "--sjdd", "--noise", "phy",
                 "--quiet"]) == 0
    assert "noise phy, eval_set spikesim" in capsys.readouterr().out


def test_a_level_folder_must_match_the_data_and_nothing_is_written_on_refusal(tmp_path,
                                                                               make_stream):
    src = _dataset(tmp_path, make_stream, [_paper(5.0), _paper(13.6), _paper(3.0, 1.0)],
                   gt=(40,))
    for folder, match in (("5", r"σ_g = 5 DN .*σ_g 13.6"), ("r", "Gaussian sequences only"),
                          ("gp", "Poisson-Gaussian paper-mode sequences only")):
        out = tmp_path / f"out-{folder}"
        with pytest.raises(SpikeSimValueError, match=match):
            export_sjdd(src, out, noise=folder)
        assert not out.exists() or not any(out.rglob("*.dat"))
    only5 = _dataset(tmp_path / "five", make_stream, [_paper(5.0), _paper(5.0)], gt=(40,))
    assert export_sjdd(only5, tmp_path / "ok5", noise="5")["samples"] == 2
    assert export_sjdd(src, tmp_path / "label", noise="mine")["samples"] == 3  # a plain label
