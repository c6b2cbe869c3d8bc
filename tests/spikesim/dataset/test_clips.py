"""Clips from video sources: many per video, start-time and crop draws, crop-first
interpolation, what each file records, and identical files from every executor."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest

import spikesim as ss
from spikesim.dataset import build_dataset, parse_manifest, plan_tasks
from spikesim.errors import SpikeSimValueError
from spikesim.io import build_index, open_dataset, read_header
from tests.support.dataset_helpers import assert_same_files, reds_root, write_frames


def clip_manifest(root, **source):
    return {
        "dataset": {"name": "clips", "seed": 3, "size": [256, 256], "window": 39,
                    "samples_per_sequence": 3},
        "sensor": {"preset": "ideal"},
        "noise": [{"mode": "paper", "label": "GN", "sigma_g": {"uniform": [0, 15]}},
                  {"mode": "paper", "label": "GPN", "sigma_g": {"uniform": [0, 5]},
                   "sigma_p": {"uniform": [0, 5]}}],
        "sources": [{"kind": "reds", "path": str(root), "split": "train", **source}],
    }


@pytest.fixture(scope="module")
def reds(tmp_path_factory):
    """One 1280x720, 24 fps video of 12 frames, REDS-shaped."""
    return reds_root(tmp_path_factory.mktemp("reds"))


@pytest.mark.slow  # about 25 s alone (three builds, two of them starting workers), 65 s loaded
def test_acceptance_six_clips_of_one_video_identical_on_every_executor(reds, tmp_path):
    m = parse_manifest(clip_manifest(reds, count=6,
                                     crop={"size": [256, 256], "position": "random"}))
    tasks = plan_tasks(m)
    assert len(tasks) == 6 and len({t.file for t in tasks}) == 6
    starts = [t.scene["start_s"] for t in tasks]
    boxes = [tuple(t.scene["crop"]) for t in tasks]
    assert len(set(starts)) == 6 and len(set(boxes)) == 6
    latest = 11 / 24 - 117 / 20_000
    assert all(0 <= s <= latest for s in starts)
    assert all(b[2:] == (256, 256) and b[0] + 256 <= 720 and b[1] + 256 <= 1280 for b in boxes)

    s1 = build_dataset(m, tmp_path / "serial", progress=False)
    assert s1.done == 6 and s1.failed == 0, s1.failures
    s2 = build_dataset(m, tmp_path / "pool", workers=2, progress=False)
    s3 = build_dataset(m, tmp_path / "dask", dask_local=2, progress=False)
    assert (s2.done, s3.done) == (6, 6), (s2.failures, s3.failures)
    assert_same_files(tmp_path / "serial", tmp_path / "pool")
    assert_same_files(tmp_path / "serial", tmp_path / "dask")

    index = build_index(tmp_path / "serial" / "train")  # validates every file
    by_name = {e["name"]: e for e in index["sequences"]}
    assert len(by_name) == 6
    for t in tasks:
        header = read_header(tmp_path / "serial" / t.file)
        clip = header["meta"]["dataset"]["clip"]
        assert clip == by_name[t.id]["clip"]
        assert clip["video"] == "000" and clip["start_s"] == t.scene["start_s"]
        assert clip["crop"] == t.scene["crop"]
        motion = clip["motion_px_per_readout"]
        # the texture pans 6 px per frame: 6 * 24 / 20000 px per readout
        assert motion["pairs"] >= 1
        assert motion["p95"] == pytest.approx(6 * 24 / 20_000, rel=0.1)
        assert 0 <= motion["median"] <= motion["p95"] <= motion["max"]
        scene = json.loads(h5py.File(tmp_path / "serial" / t.file, "r").attrs["scene"])
        assert scene["crop"] == t.scene["crop"] and scene["start_s"] == t.scene["start_s"]
    assert s1.seconds_by_stage()["flow"] > 0 and s1.seconds_by_stage()["warp"] > 0


def test_start_s_distribution_per_second_and_non_overlap(reds):
    clip_s = 117 / 20_000
    m = parse_manifest(clip_manifest(reds, count=4, start_s={"uniform": [0.1, 0.3]}))
    assert all(0.1 <= t.scene["start_s"] <= 0.3 for t in plan_tasks(m))
    # options take distributions too (the same syntax everywhere)
    m = parse_manifest(clip_manifest(reds, options={"max_px": {"uniform": [0.5, 2]}}))
    assert 0.5 <= plan_tasks(m)[0].scene["options"]["max_px"] <= 2
    # clips per second of video: 11 / 24 s * 8 = 3.7 -> 4
    assert len(plan_tasks(parse_manifest(clip_manifest(reds, per_second=8)))) == 4
    # non-overlap: sorted starts at least clip + gap apart, for any seed
    for seed in range(5):
        d = clip_manifest(reds, count=5, min_gap_s=0.05)
        d["dataset"]["seed"] = seed
        starts = sorted(t.scene["start_s"] for t in plan_tasks(parse_manifest(d)))
        assert np.all(np.diff(starts) >= clip_s + 0.05 - 1e-9)
    # a sequence keeps its clip when more clips are asked for
    few = {t.id: t.scene for t in plan_tasks(parse_manifest(clip_manifest(reds, count=3)))}
    many = {t.id: t.scene for t in plan_tasks(parse_manifest(clip_manifest(reds, count=9)))}
    assert all(many[k] == v for k, v in few.items())


def test_crop_positions_and_noise_labels(reds):
    m = parse_manifest(clip_manifest(reds, count=2, noise="GPN",
                                     crop={"size": [128, 200], "position": "center"}))
    for t in plan_tasks(m):
        assert t.scene["crop"] == [(720 - 128) // 2, (1280 - 200) // 2, 128, 200]
        assert t.noise_label == "GPN"
    m = parse_manifest(clip_manifest(reds, crop={"size": [64, 64], "position": [10, 20]}))
    assert plan_tasks(m)[0].scene["crop"] == [10, 20, 64, 64]


@pytest.mark.parametrize("source, where", [
    ({"crop": {"size": [800, 64]}}, "crop.size"),
    ({"crop": {"size": [64, 64], "position": [700, 0]}}, "crop.position"),
    ({"crop": {"size": [64, 64], "position": "left"}}, "crop.position"),
    ({"start_s": {"uniform": [0, 5]}}, "start_s"),
    ({"count": 2, "per_second": 1}, "per_second"),
    ({"count": 40, "min_gap_s": 0.05}, "min_gap_s"),
    ({"min_gap_s": 0.01, "start_s": {"choice": [0, 0.1]}}, "start_s"),
    ({"noise": "XYZ"}, "noise"),
    ({"options": {"crop": [0, 0, 8, 8]}}, "options.crop"),
])
def test_clip_errors_name_the_key(reds, source, where):
    with pytest.raises(SpikeSimValueError, match=rf"sources\[0\]\.{where}"):
        parse_manifest(clip_manifest(reds, **source))


def test_crop_first_matches_full_frame_interpolation(tmp_path):
    """Cropping first (with the margin) gives the full-frame interpolation's crop."""
    folder = write_frames(tmp_path / "v", 3, size=(200, 300), px_per_frame=5)
    box = (60, 90, 64, 80)
    full = ss.scenes.video(folder, fps=24)
    crop = ss.scenes.video(folder, fps=24, crop=box, margin=16)
    assert crop.n_intermediate(0) == full.n_intermediate(0) > 0
    top, left, h, w = box
    for t in (0.3 / 24, 0.5 / 24, 1.7 / 24):
        a = full.radiance(t)[top : top + h, left : left + w]
        b = crop.radiance(t)
        assert b.shape == (h, w, 3)
        assert np.abs(a - b).mean() < 2e-3
    assert crop.source.n_decoded <= 3 and crop.motion_stats()["pairs"] >= 1


def test_fractional_start_is_the_same_video_time(tmp_path):
    folder = write_frames(tmp_path / "v", 4, size=(48, 64), px_per_frame=3)
    whole = ss.scenes.video(folder, fps=24)
    start = 1.37 / 24
    clip = ss.scenes.video(folder, fps=24, start_s=start)
    for t in (0.0, 0.2 / 24, 0.9 / 24, 1.5 / 24):
        np.testing.assert_allclose(clip.radiance(t), whole.radiance(start + t), atol=1e-6)
    keys = clip.key_times(0.0, 1.0 / 24)
    assert keys[0] == 0.0 and np.all(np.diff(keys) > 0)
    # the grid is global: a later window selects from the same times
    later = clip.key_times(0.5 / 24, 1.0 / 24)
    assert set(np.round(later, 12)) <= set(np.round(clip.key_times(0.0, 2.0 / 24), 12))


def test_dataset_roots_and_splits(reds, tmp_path):
    d = clip_manifest(reds, count=1)
    d["dataset"].update(size=[32, 32], window=5, samples_per_sequence=1)
    d["sources"][0]["crop"] = {"size": [32, 32]}
    d["sources"].append({**d["sources"][0], "split": "eval"})
    build_dataset(parse_manifest(d), tmp_path / "root", progress=False)
    root = tmp_path / "root"
    assert ss.io.dataset_splits(root) == ["eval", "train"]
    assert ss.io.resolve_dataset(root, "eval") == root / "eval"
    assert ss.io.resolve_dataset(root / "train") == root / "train"
    assert len(open_dataset(root, split="train")) == 1
    with pytest.raises(SpikeSimValueError, match=r"\['eval', 'train'\]"):
        open_dataset(root)
    with pytest.raises(SpikeSimValueError, match=r"split=.*\['eval', 'train'\]"):
        ss.io.resolve_dataset(root, "test")
    f = next((root / "train").glob("*.h5"))
    assert ss.io.resolve_dataset(f) == f
    with pytest.raises(SpikeSimValueError, match="single file"):
        ss.io.resolve_dataset(f, "train")


@pytest.mark.parametrize("names", [("vidA", "vida"), ("vid-a", "vid_a")])
def test_videos_whose_ids_collide_are_named(tmp_path, names):
    """Sequence ids are lower-case slugs of the video names; two videos that give
    the same id are refused naming both (it used to be an internal error)."""
    root = reds_root(tmp_path / "reds", videos=names, n_frames=3, size=(64, 96))
    with pytest.raises(SpikeSimValueError, match=rf"sources\[0\]=.*'{names[0]}' and "
                                                 rf"'{names[1]}'.*rename one"):
        plan_tasks(parse_manifest(clip_manifest(root, count=1)))


def test_a_clip_longer_than_the_video_names_the_keys_to_change(reds):
    d = clip_manifest(reds)
    d["dataset"]["samples_per_sequence"] = 100_000
    with pytest.raises(SpikeSimValueError, match=r"sources\[0\]: video '000'.*shorter than one "
                                                 r"clip \(dataset\.window × dataset\.samples_per"):
        parse_manifest(d)


def test_plan_warns_once_per_source_that_squashes_its_frames(reds):
    import warnings

    from spikesim.scenes.video import AspectWarning

    with pytest.warns(AspectWarning, match=r"sources\[0\]: 1 of its 1 video\(s\) \(e\.g\. "
                                           r"720x1280 frames\) are resized.*256x256") as caught:
        plan_tasks(parse_manifest(clip_manifest(reds, count=2)))
    assert len([w for w in caught if w.category is AspectWarning]) == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error", AspectWarning)
        plan_tasks(parse_manifest(clip_manifest(reds, count=2, crop={"size": [300, 300]})))
    with pytest.warns(AspectWarning, match=r"its crop\.size 300x400 is resized"):
        plan_tasks(parse_manifest(clip_manifest(reds, count=2, crop={"size": [300, 400]})))
