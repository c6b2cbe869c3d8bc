"""build_summary.json keeps the real build's timing across do-nothing re-runs; the dry
run counts worker start-up and skips what is already built."""

from __future__ import annotations

import json

from spikesim.dataset import build_dataset, estimate_dataset, parse_manifest


def _manifest(count=3):
    return parse_manifest({
        "dataset": {"name": "h", "seed": 2, "size": [24, 32], "window": 9,
                    "samples_per_sequence": 2},
        "sources": [{"kind": "procedural", "scenes": ["coffee"], "motions": ["pan"],
                     "speed": 300, "count": count}]})


def test_rerun_that_does_nothing_keeps_the_real_timing(tmp_path):
    m = _manifest()
    first = build_dataset(m, tmp_path, progress=False)
    summary = json.loads((tmp_path / "build_summary.json").read_text())
    assert summary["done"] == 3 and summary["seconds"] == first.seconds
    again = build_dataset(m, tmp_path, progress=False)
    assert again.skipped == 3 and again.done == 0
    kept = json.loads((tmp_path / "build_summary.json").read_text())
    assert kept["done"] == 3 and kept["seconds"] == first.seconds
    assert kept["seconds_by_stage"] == summary["seconds_by_stage"]
    assert [h["done"] for h in kept["history"]] == [3, 0]
    assert [h["skipped"] for h in kept["history"]] == [0, 3]
    # a run that does work writes its own summary, the history goes on
    build_dataset(_manifest(count=4), tmp_path, progress=False)
    last = json.loads((tmp_path / "build_summary.json").read_text())
    assert last["done"] == 1 and last["skipped"] == 3 and len(last["history"]) == 3


def test_dry_run_counts_startup_and_skips_what_is_built(tmp_path):
    m = _manifest(count=4)
    serial = estimate_dataset(m, calibration_tasks=2)
    assert serial["to_make"] == 4 and serial["executor"] == "serial"
    assert serial["estimated_seconds"] >= 4 * serial["seconds_per_sequence"] > 0
    pool = estimate_dataset(m, workers=2, calibration_tasks=1)
    assert pool["startup_seconds"] > 0 and pool["executor"] == "2 local processes"
    assert pool["estimated_seconds"] >= pool["startup_seconds"] + 2 * pool["seconds_per_sequence"]
    build_dataset(_manifest(count=3), tmp_path, progress=False)
    rest = estimate_dataset(m, out_dir=tmp_path, calibration_tasks=1)
    assert rest["sequences"] == 4 and rest["to_make"] == 1


def test_dry_run_counts_video_decoding_per_frame_not_per_clip(tmp_path):
    """The dry run's model of frame decoding matches what a serial build decodes:
    every frame once, however many clips read it; a pool decodes at most its model."""
    from spikesim.dataset.build import _frames_to_decode
    from spikesim.dataset.plan import plan_tasks
    from tests.support.dataset_helpers import reds_root

    root = reds_root(tmp_path / "reds", n_frames=6, size=(48, 64))
    m = parse_manifest({
        "dataset": {"name": "v", "seed": 1, "size": [32, 32], "window": 39,
                    "samples_per_sequence": 3},
        "sources": [{"kind": "reds", "path": str(root), "count": 8,
                     "crop": {"size": [32, 32], "position": "random"}}]})
    tasks = [t.to_dict() for t in plan_tasks(m)]
    serial = build_dataset(m, tmp_path / "serial", progress=False)
    decoded = sum(r["frames_decoded"] for r in serial.records)
    assert decoded == _frames_to_decode(tasks, m, 1, False)
    # eight clips of 117 readouts at 20 kHz read 2 frames each: fewer than 16 decodes
    assert 2 <= decoded < 16 <= _frames_to_decode(tasks, m, 1, True)
    pool = build_dataset(m, tmp_path / "pool", workers=2, progress=False)
    assert sum(r["frames_decoded"] for r in pool.records) <= _frames_to_decode(tasks, m, 2, False)
    est = estimate_dataset(m, calibration_tasks=2)
    assert est["frames_to_decode"] == decoded


def test_dry_run_counts_no_frame_files_for_a_video_file(tmp_path):
    """A video file is decoded by its container reader (no frame files, no frame cache):
    the model counts nothing and the build decodes no frame files."""
    import cv2
    import numpy as np

    from spikesim.dataset.build import _frames_to_decode
    from spikesim.dataset.plan import plan_tasks

    big = cv2.GaussianBlur((np.random.default_rng(0).random((64, 200, 3)) * 255)
                           .astype(np.uint8), (0, 0), 3)
    writer = cv2.VideoWriter(str(tmp_path / "clip.avi"), cv2.VideoWriter_fourcc(*"MJPG"),
                             25.0, (96, 64))
    for i in range(8):
        writer.write(np.ascontiguousarray(big[:, 8 * i: 8 * i + 96]))
    writer.release()
    m = parse_manifest({
        "dataset": {"name": "f", "seed": 1, "size": [32, 32], "window": 39,
                    "samples_per_sequence": 2},
        "sources": [{"kind": "video", "path": str(tmp_path / "clip.avi"), "count": 3,
                     "crop": {"size": [32, 32], "position": "random"}}]})
    tasks = [t.to_dict() for t in plan_tasks(m)]
    built = build_dataset(m, tmp_path / "out", progress=False)
    assert built.done == 3
    assert sum(r["frames_decoded"] for r in built.records) == 0
    assert _frames_to_decode(tasks, m, 1, False) == 0
