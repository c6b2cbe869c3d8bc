"""Dataset roots (``spikesim dataset`` output with split folders) accepted by every
command and loader that takes data, with a split option and errors naming the splits."""

from __future__ import annotations

import json

import pytest

from spikesim.cli import main as spikesim_main
from spikesim.dataset import build_dataset, parse_manifest


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    out = tmp_path_factory.mktemp("root")
    src = {"kind": "procedural", "scenes": ["astronaut"], "motions": ["pan"], "speed": 500,
           "count": 2}
    m = parse_manifest({
        "dataset": {"name": "r", "seed": 1, "size": [32, 32], "window": 41,
                    "samples_per_sequence": 2},
        "sources": [{**src, "split": "train"}, {**src, "split": "eval"}]})
    assert build_dataset(m, out, progress=False).done == 4
    return out


def test_spikesim_info_on_a_root(root, capsys):
    assert spikesim_main(["info", str(root)]) == 1
    assert "['eval', 'train']" in capsys.readouterr().err
    assert spikesim_main(["info", str(root), "--split", "eval", "--json", "--all"]) == 0
    infos = json.loads(capsys.readouterr().out)
    assert len(infos) == 2 and all("/eval/" in i["path"] for i in infos)
    assert spikesim_main(["info", str(root), "--split", "nope"]) == 1
    assert "split='nope'" in capsys.readouterr().err


def test_spikejdd_loaders_and_commands_on_a_root(root, tmp_path, capsys):
    torch = pytest.importorskip("torch")  # noqa: F841 - spikejdd needs it
    from spikejdd.cli import main
    from spikejdd.data import SpikeWindowDataset

    ds = SpikeWindowDataset(root, split="train", window=39, crop=16)
    assert len(ds) == 4 and ds[0]["spikes"].shape == (39, 16, 16)
    with pytest.raises(ValueError, match=r"\['eval', 'train'\]"):
        SpikeWindowDataset(root)
    assert main(["evaluate", "--data", str(root), "--split", "eval", "--methods", "tfp+bilinear",
                 "--repeats", "1", "--quiet", "--out", str(tmp_path / "ev")]) == 0
    assert main(["evaluate", "--data", str(root), "--methods", "tfp+bilinear",
                 "--out", str(tmp_path / "ev2")]) == 1
    assert "['eval', 'train']" in capsys.readouterr().err
    assert main(["reconstruct", str(root), "--split", "eval", "--method", "tfp+bilinear",
                 "--out", str(tmp_path / "png")]) == 0
    assert len(list((tmp_path / "png").glob("*.png"))) == 4  # 2 sequences x 2 GT readouts
    cfg = tmp_path / "run.json"
    tiny = {"n_readouts": 9, "block_size": 5, "n_blocks": 3, "csr_encoder_feats": 2,
            "csr_align_feats": [4, 4], "csr_align_depth": 0, "csr_decoder_feats": 4,
            "csr_decoder_depth": 0, "offset_groups": 2, "sne_feats": 4, "sne_res_blocks": 1,
            "sne_fusion_depth": 0, "ccp_widths": [4, 8], "ccp_depth": 1, "stages": 1}
    cfg.write_text(json.dumps({"model": "lite", "steps": 1, "batch_size": 2, "crop": 12,
                               "eval_frames": 1, "model_overrides": tiny}))
    assert main(["train", "--data", str(root), "--split", "train", "--eval-split", "eval",
                 "--eval-data", str(root), "--config", str(cfg), "--out",
                 str(tmp_path / "run"), "--quiet"]) == 0
    assert "trained 1 step in" in capsys.readouterr().out
    assert main(["train", "--data", str(root), "--config", str(cfg), "--out",
                 str(tmp_path / "run2"), "--quiet"]) == 1
    assert "['eval', 'train']" in capsys.readouterr().err


@pytest.mark.parametrize("flags, named", [
    (["--dask-local", "-1", "--dry-run"], "--dask-local=-1 is invalid"),
    (["--dask-local", "0"], "--dask-local=0 is invalid"),
    (["--workers", "0", "--dry-run"], "--workers=0 is invalid"),
    (["--limit", "0", "--dry-run"], "--limit=0 is invalid"),
])
def test_dataset_counts_are_checked_as_options_before_a_dry_run(flags, named, tmp_path, capsys):
    """A dry run estimated a build of -1 Dask workers; a build named ``workers=`` for
    ``--dask-local``."""
    assert spikesim_main(["dataset", "builtin:demo", "--out", str(tmp_path / "d"), *flags]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"spikesim dataset: error: {named}"), err
    assert not (tmp_path / "d").exists()
