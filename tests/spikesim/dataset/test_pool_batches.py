"""Process-pool builds of video clips: batches of one video's clips, the per-process
cache of decoded frames, worker thread pools sized by the environment, and files
identical to a serial build."""

from __future__ import annotations

import os

import cv2
import numpy as np
import pytest

from spikesim.dataset import build_dataset, parse_manifest, plan_tasks
from spikesim.dataset._threads import THREAD_VARIABLES, worker_thread_env
from spikesim.dataset.batches import MAX_BATCH, pool_batches
from spikesim.scenes import frame_cache
from spikesim.scenes.readers import open_frames
from tests.support.dataset_helpers import assert_same_files, reds_root, write_frames


def manifest(root, count=8, videos=("000", "001")):
    return parse_manifest({
        "dataset": {"name": "batches", "seed": 11, "size": [32, 32], "window": 5},
        "sensor": {"preset": "ideal"},
        "noise": [{"mode": "paper", "label": "GN", "sigma_g": {"uniform": [0, 15]}}],
        "sources": [{"kind": "reds", "path": str(root), "sequences": list(videos),
                     "count": count, "crop": {"size": [32, 32]}},
                    {"kind": "procedural", "scenes": ["disk"], "count": 2}],
    })


@pytest.fixture(scope="module")
def reds(tmp_path_factory):
    return reds_root(tmp_path_factory.mktemp("reds"), ("000", "001"), n_frames=6,
                     size=(96, 128))


def test_batches_hold_one_video_each_in_start_order(reds):
    tasks = [t.to_dict() for t in plan_tasks(manifest(reds))]
    batches = pool_batches(tasks, workers=2)
    flat = [t["file"] for b in batches for t in b]
    assert sorted(flat) == sorted(t["file"] for t in tasks)  # every task exactly once
    assert max(len(b) for b in batches) == len(tasks) // 4  # 18 tasks, 2 workers: runs of 4
    for b in batches:
        kinds = {t["scene"]["kind"] for t in b}
        if kinds != {"video"}:
            assert len(b) == 1  # other tasks go one by one
            continue
        assert len({t["scene"]["sequence"] for t in b}) == 1
        starts = [t["scene"]["start_s"] for t in b]
        assert starts == sorted(starts)
    # the runs of one video follow each other in start order
    v0 = [t["scene"]["start_s"] for b in batches for t in b if t["scene"].get("sequence") == "000"]
    assert v0 == sorted(v0) and len(v0) == 8
    # many tasks: runs are capped; one worker: still about two batches or more
    assert max(len(b) for b in pool_batches(tasks * 20, 2)) == MAX_BATCH
    assert len(pool_batches(tasks[:8], 1)) == 2


def test_decoded_frames_are_shared_and_refreshed(tmp_path):
    folder = write_frames(tmp_path / "v", 3, size=(24, 32))
    frame_cache.clear()
    a, b = open_frames(folder), open_frames(folder)
    fa = a.read(1)
    fb = b.read(1)
    assert fa is fb and (a.n_decoded, b.n_decoded) == (1, 0)  # decoded once for both
    assert not fa.flags.writeable
    expected = cv2.cvtColor(cv2.imread(str(a.files[1]), cv2.IMREAD_UNCHANGED), cv2.COLOR_BGR2RGB)
    np.testing.assert_array_equal(fa, expected)
    # a file rewritten in place is decoded again
    cv2.imwrite(str(a.files[1]), np.zeros((24, 32, 3), np.uint8))
    os.utime(a.files[1], ns=(1, 1))
    assert int(a.read(1).max()) == 0 and a.n_decoded == 2
    # bounded: the oldest frames go first
    budget = frame_cache.CACHE_BYTES
    try:
        frame_cache.CACHE_BYTES = 2 * fa.nbytes
        frame_cache.clear()
        for i in range(3):
            a.read(i)
        assert frame_cache.cached_bytes() == 2 * fa.nbytes
        a.read(0)
        assert a.n_decoded == 2 + 3 + 1  # frame 0 had been dropped
    finally:
        frame_cache.CACHE_BYTES = budget
        frame_cache.clear()


def test_worker_thread_env_sets_what_the_user_did_not(monkeypatch):
    for name in THREAD_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("OMP_NUM_THREADS", "3")
    with worker_thread_env(1):
        assert os.environ["OMP_NUM_THREADS"] == "3"  # the user's choice stays
        assert all(os.environ[n] == "1" for n in THREAD_VARIABLES if n != "OMP_NUM_THREADS")
    assert [n for n in THREAD_VARIABLES if n in os.environ] == ["OMP_NUM_THREADS"]


@pytest.mark.slow  # starts two worker processes: about 15 s, 40 s loaded
def test_pool_of_batches_writes_the_serial_files(reds, tmp_path):
    m = manifest(reds, count=6, videos=("000",))
    serial = build_dataset(m, tmp_path / "serial", progress=False)
    pool = build_dataset(m, tmp_path / "pool", workers=2, progress=False)
    assert serial.done == pool.done == 8 and pool.failed == 0, pool.failures
    assert max(len(b) for b in pool_batches([t.to_dict() for t in plan_tasks(m)], 2)) == 2
    assert_same_files(tmp_path / "serial", tmp_path / "pool")
    assert {r["file"] for r in pool.records} == {r["file"] for r in serial.records}


DIES = """
import multiprocessing
import os

import numpy as np

from spikesim.scenes import Static


class Dies(Static):
    def radiance(self, t):
        if multiprocessing.parent_process() is not None:  # never the test process
            os._exit(3)
        return super().radiance(t)


def make(index, size, seed):
    img = np.full(tuple(size) + (3,), 0.1 + 0.05 * index, np.float32)
    return Dies(img) if index == 1 else Static(img)
"""


@pytest.mark.slow  # starts pools and lone retries: about 20 s, 60 s loaded
def test_a_batch_lost_with_its_worker_fails_only_the_culprit(tmp_path, monkeypatch):
    """A worker dying inside a batch loses the whole batch: the sequences it had
    finished are checked and kept, the others made again one by one."""
    import sys

    from spikesim.dataset import batches

    (tmp_path / "dies_batch.py").write_text(DIES)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "dies_batch", raising=False)
    # batch these factory tasks as if they were clips of one video (grouping is parent-side)
    monkeypatch.setattr(batches, "_video_of", lambda task: "one video")
    m = parse_manifest({
        "dataset": {"name": "d", "seed": 1, "size": [16, 24], "window": 5},
        "sensor": {"preset": "ideal"},
        "noise": [{"mode": "none", "label": "clean"}],
        "sources": [{"kind": "python", "factory": "dies_batch:make", "count": 8,
                     "split": "inj"}],
    })
    tasks = [t.to_dict() for t in plan_tasks(m)]
    assert [len(b) for b in pool_batches(tasks, 2)] == [2, 2, 2, 2]
    s = build_dataset(m, tmp_path / "out", workers=2, progress=False)
    assert (s.done, s.failed) == (7, 1), [r["error"] for r in s.failures]
    assert s.failures[0]["file"] == tasks[1]["file"] and "died" in s.failures[0]["error"]
    assert sorted(r["file"] for r in s.records if r["status"] == "done") == sorted(
        t["file"] for t in tasks if t["file"] != tasks[1]["file"])
