"""Torch dataset: crops at any offset and flips carry the true Bayer mask; spawn workers."""

from __future__ import annotations

import pickle

import h5py
import numpy as np
import pytest
import torch

from spikejdd.data import SpikeWindowDataset, unpack_spikes
from spikesim.cfa import channel_index
from spikesim.errors import SpikeSimFormatError, SpikeSimValueError
from spikesim.io import H5Writer

H, W, T = 10, 13, 30


def _write(path, cfa="GRBG", seed=0, version=None):
    rng = np.random.default_rng(seed)
    spikes = (rng.random((T, H, W)) < 0.3).astype(np.uint8)
    yy, xx = np.mgrid[0:H, 0:W]
    gt = np.stack([yy / H, xx / W, np.full((H, W), 0.5)], -1).astype(np.float32)
    gt_index = np.array([3, 12, 15, 20, 28], np.int64)
    meta = {"height": H, "width": W, "cfa": cfa, "clock_hz": 20000.0, "seed": seed,
            "sensor": {"full_scale_rate": 0.6,
                       "noise": {"type": "paper", "sigma_g": 5.0, "sigma_p": 1.0}},
            "scene": {"type": "test"}}
    with H5Writer(path, meta) as w:
        w.append(np.packbits(spikes, axis=-1, bitorder="little"))
        w.add_gt(np.stack([gt + 0.01 * k for k in range(5)]), gt_index)
    if version is not None:
        with h5py.File(path, "r+") as f:
            f.attrs["format_version"] = version
    return spikes, gt


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    d = tmp_path_factory.mktemp("ds")
    spikes, gt = _write(d / "seq_a.h5", "GRBG")
    return d, spikes, gt


def _true_planes(cfa, top, left, h, w, hflip, vflip):
    """Independent: crop the full-frame channel map, flip it, split greens by red rows."""
    idx = channel_index(cfa, H, W)
    red_rows = np.isin(np.arange(H) % 2, np.nonzero((idx == 0).any(1))[0] % 2)
    idx, rr = idx[top:top + h, left:left + w], red_rows[top:top + h]
    rr = np.repeat(rr[:, None], w, 1)
    planes = np.stack([idx == 0, (idx == 1) & rr, (idx == 1) & ~rr, idx == 2]).astype(np.float32)
    if hflip:
        planes = planes[..., ::-1]
    if vflip:
        planes = planes[..., ::-1, :]
    return planes


def test_train_crops_and_flips_follow_true_pattern(folder):
    d, spikes, gt = folder
    ds = SpikeWindowDataset(d, window=7, crop=(5, 7), train=True, seed=3)
    assert len(ds) == 4  # readout 3 has no room for a centred window of 7; 28 neither
    offsets, flips = set(), set()
    for epoch in range(6):
        ds.set_epoch(epoch)
        for i in range(len(ds)):
            s = ds[i]
            m = s["meta"]
            top, left, hf, vf = m["top"], m["left"], m["hflip"], m["vflip"]
            offsets.add((top % 2, left % 2))
            flips.add((hf, vf))
            np.testing.assert_array_equal(
                s["mask"].numpy(), _true_planes("GRBG", top, left, 5, 7, hf, vf))
            ref = spikes[m["readout"] - 3:m["readout"] + 4, top:top + 5, left:left + 7]
            ref_gt = gt[top:top + 5, left:left + 7] + 0.01 * m["gt_position"]
            if hf:
                ref, ref_gt = ref[..., ::-1], ref_gt[:, ::-1]
            if vf:
                ref, ref_gt = ref[..., ::-1, :], ref_gt[::-1]
            np.testing.assert_array_equal(s["spikes"].numpy(), ref)
            np.testing.assert_allclose(s["gt"].numpy(), ref_gt.transpose(2, 0, 1), atol=1e-6)
            # the reported pattern names the delivered top-left tile
            tile = "".join("RGGB"[int(p)] for p in
                           np.argmax(s["mask"].numpy()[:, :2, :2], 0).ravel())
            assert tile == m["cfa"]
    assert offsets == {(0, 0), (0, 1), (1, 0), (1, 1)}
    assert flips == {(False, False), (False, True), (True, False), (True, True)}
    assert s["meta"]["noise"] == "paper" and s["meta"]["sigma_g"] == 5.0


def test_eval_mode_is_deterministic_and_packed_roundtrip(folder):
    d, spikes, _ = folder
    a = SpikeWindowDataset(d, window=5, crop=4, train=False)
    b = SpikeWindowDataset(d, window=5, crop=4, train=False, packed=True)
    b.set_epoch(9)
    for i in range(len(a)):
        sa, sb = a[i], b[i]
        assert (sa["meta"]["top"], sa["meta"]["left"]) == ((H - 4) // 2, (W - 4) // 2)
        assert not sa["meta"]["hflip"] and not sa["meta"]["vflip"]
        assert sb["spikes"].dtype == torch.uint8 and sb["spikes"].shape == (5, 4, 1)
        assert torch.equal(unpack_spikes(sb["spikes"], 4), sa["spikes"])
        assert torch.equal(a[i]["spikes"], sa["spikes"])


def test_spawn_workers_and_pickle(folder):
    d, _, _ = folder
    ds = SpikeWindowDataset(d, window=5, crop=4, train=True, seed=1)
    ds[0]  # opens the file in this process; pickling must drop the handle
    clone = pickle.loads(pickle.dumps(ds))
    assert torch.equal(clone[1]["spikes"], ds[1]["spikes"])
    loader = torch.utils.data.DataLoader(ds, batch_size=2, num_workers=2,
                                         multiprocessing_context="spawn")
    batches = list(loader)
    assert sum(b["spikes"].shape[0] for b in batches) == len(ds)
    assert torch.equal(batches[0]["mask"][1], ds[1]["mask"])


def test_unknown_format_version_and_bad_args(tmp_path, folder):
    _write(tmp_path / "new.h5", version=99)
    with pytest.raises(SpikeSimFormatError, match="version"):
        SpikeWindowDataset(tmp_path / "new.h5")
    d, _, _ = folder
    with pytest.raises(SpikeSimValueError, match="window"):
        SpikeWindowDataset(d, window=31)
    with pytest.raises(SpikeSimValueError, match="window"):
        SpikeWindowDataset(d, window=0)
    with pytest.raises(SpikeSimValueError, match="crop"):
        SpikeWindowDataset(d, window=5, crop=(11, 4))
    with pytest.raises(SpikeSimValueError, match="crop"):
        SpikeWindowDataset(d, window=5, crop=1)
    with pytest.raises(SpikeSimValueError, match="sequences"):
        SpikeWindowDataset(d, window=5, sequences=["nope"])
