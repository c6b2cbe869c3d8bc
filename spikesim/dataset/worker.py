"""Produce one sequence file from a :class:`~spikesim.dataset.plan.SequenceTask`.

Runs in whatever process the executor chose (the caller's, a spawned pool
worker, or a Dask worker).  The file is written atomically by the HDF5
writer, so a crash leaves no file under its final name.  The result records
where the time went (scene decoding and rendering / optical flow / warping of
interpolated key frames / kernel / writing) and, for video clips, the clip's
video, start time, crop box and measured motion (also stored in the file's
``meta`` attribute under ``dataset.clip``).
"""

from __future__ import annotations

import json
import time
import warnings
from pathlib import Path

import numpy as np

from spikesim.dataset.record import TaskRecord
from spikesim.scenes import frame_cache
from spikesim.scenes.video import AspectWarning

__all__ = ["run_task", "run_batch", "validate_existing", "build_scene"]


class _TimedScene:
    """Delegating wrapper that accumulates time spent inside the scene."""

    def __init__(self, scene):
        self._scene = scene
        self.seconds = 0.0
        self.height, self.width = scene.height, scene.width

    def radiance(self, t):
        t0 = time.perf_counter()
        try:
            return self._scene.radiance(t)
        finally:
            self.seconds += time.perf_counter() - t0

    def key_times(self, start_s, stop_s):
        t0 = time.perf_counter()
        try:
            return self._scene.key_times(start_s, stop_s)
        finally:
            self.seconds += time.perf_counter() - t0

    def describe(self):
        return self._scene.describe()

    @property
    def is_static(self):
        return getattr(self._scene, "is_static", False)


def build_scene(spec: dict, seed: int):
    """The scene described by a task's scene spec."""
    import spikesim as ss
    from spikesim.dataset.manifest import resolve_factory

    size = tuple(spec["size"])
    options = dict(spec.get("options") or {})
    if spec["kind"] == "procedural":
        if spec.get("speed") is not None:
            options["speed"] = spec["speed"]
        return ss.scenes.procedural(spec["name"], motion=spec.get("motion"), size=size, **options)
    if spec["kind"] == "python":
        factory = resolve_factory(spec["factory"])
        return factory(index=spec["index"], size=size, seed=seed, **options)
    kwargs = {"fps": spec.get("fps"), "layout": spec.get("layout", "auto"), "resize": size,
              "start_s": spec.get("start_s", 0.0), "crop": spec.get("crop")}
    if spec.get("sequence"):
        kwargs["sequence"] = spec["sequence"]
    with warnings.catch_warnings():  # the plan warned once per source (plan._warn_squashed)
        warnings.simplefilter("ignore", AspectWarning)
        return ss.scenes.video(spec["path"], **kwargs, **options)


def clip_record(spec: dict, scene, clock_hz: float) -> dict | None:
    """What a video clip is: video, start time, crop box and the motion measured in it
    (output pixels per readout: median and 95th percentile of the flow inside the crop)."""
    if spec.get("kind") != "video":
        return None
    motion = scene.motion_stats() if hasattr(scene, "motion_stats") else {}
    video = spec.get("sequence") or Path(spec["path"]).name
    return {
        "video": video, "path": spec["path"], "start_s": spec.get("start_s", 0.0),
        "crop": spec.get("crop"), "clip": spec.get("clip"),
        "motion_px_per_readout": {
            "median": motion.get("median_px_per_s", 0.0) / clock_hz,
            "p95": motion.get("p95_px_per_s", 0.0) / clock_hz,
            "max": motion.get("max_px_per_s", 0.0) / clock_hz,
            "pairs": motion.get("pairs", 0)},
    }


def validate_existing(path: Path, task: dict) -> bool:
    """True when ``path`` is a complete, readable file of exactly this task
    (same seed, sensor, scene specification, readouts and ground-truth readouts)."""
    from spikesim.io import open_h5

    if not path.is_file():
        return False
    try:
        with open_h5(path) as seq:
            meta = seq.meta
            stored = (meta.get("dataset") or {}).get("scene_spec")
            return (seq.n_readouts == task["n_readouts"]
                    and int(meta.get("seed", -1)) == task["seed"]
                    and meta.get("sensor") == task["sensor"]
                    and json.dumps(stored, sort_keys=True) == json.dumps(task["scene"],
                                                                         sort_keys=True)
                    and list(seq.gt_index) == list(task["gt_readouts"]))
    except Exception:  # noqa: BLE001 - any unreadable file is simply redone
        return False


def run_task(task: dict, out_dir: str, threads: int | None = None) -> dict:
    """Simulate and write one sequence; returns a result record (never raises).

    ``threads`` limits numba's and OpenCV's threads in this process (one worker
    per core should not oversubscribe the machine).
    """
    import numba

    from spikesim.io import H5Writer
    from spikesim.sensor import Sensor
    from spikesim.simulate import simulate_chunks

    if threads:
        import cv2

        numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))
        cv2.setNumThreads(max(1, int(threads)))  # decoding, flow and warping: no oversubscription
    path = Path(out_dir) / task["file"]
    t_start = time.perf_counter()
    decoded_before = frame_cache.decodes()
    record = TaskRecord.of(task)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        scene = _TimedScene(build_scene(task["scene"], task["seed"]))
        sensor = Sensor.from_dict(task["sensor"])
        run = simulate_chunks(scene, sensor, task["n_readouts"], seed=task["seed"],
                              clean_twin=task["clean_twin"], gt_readouts=list(task["gt_readouts"]))
        meta = dict(run.meta)
        meta["dataset"] = {"manifest": task["manifest"], "id": task["id"],
                           "split": task["split"], "noise_label": task["noise_label"],
                           "scene_spec": task["scene"]}
        kwargs = {} if task["compression"] is None else {"compression": task["compression"]}
        write_s = 0.0
        produce_start = time.perf_counter()
        with H5Writer(path, meta, clean=task["clean_twin"], **kwargs) as writer:
            for chunk in run:
                t0 = time.perf_counter()
                writer.append(chunk.packed, chunk.clean_packed)
                if len(chunk.gt):
                    writer.add_gt(chunk.gt, chunk.gt_index)
                write_s += time.perf_counter() - t0
            clip = clip_record(task["scene"], scene._scene, sensor.clock_hz)
            if clip is not None:  # measured while simulating; written with the attributes
                writer.meta["dataset"] = {**meta["dataset"], "clip": clip}
                record.clip = clip
            t_close = time.perf_counter()
        write_s += time.perf_counter() - t_close
        produce_s = time.perf_counter() - produce_start - write_s
        stats = getattr(scene._scene, "stats", None) or {}
        flow_s = float(stats.get("flow_s", 0.0))
        warp_s = float(stats.get("interp_s", 0.0))
        record.seconds.update(scene=max(scene.seconds - flow_s - warp_s, 0.0), flow=flow_s,
                                 warp=warp_s, kernel=max(produce_s - scene.seconds, 0.0),
                                 write=write_s)
        record.bytes = path.stat().st_size
        record.px_readouts = int(np.prod(sensor.shape)) * task["n_readouts"]
    except Exception as exc:  # noqa: BLE001 - reported per sequence, others go on
        record.status, record.error = "failed", f"{type(exc).__name__}: {exc}"
    record.seconds["total"] = time.perf_counter() - t_start
    record.frames_decoded = frame_cache.decodes() - decoded_before
    return record.to_dict()


def run_batch(tasks: list[dict], out_dir: str, threads: int | None = None) -> list[dict]:
    """:func:`run_task` for each task in turn, in this process (one record each)."""
    return [run_task(t, out_dir, threads) for t in tasks]
