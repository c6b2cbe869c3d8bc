"""Build a dataset: run every sequence task locally or on a Dask cluster, resumably.

* One task per sequence (``plan.py``), seeds derived from the global seed and
  the sequence id, so serial, process-pool and Dask runs give identical files.
* A re-run skips sequences whose files exist and validate (same seed, sensor,
  readouts); stale temporary files of killed workers are removed first.
* Pool workers size their thread pools to their share of the cores (``_threads.py``).
* A process pool gets the clips of one video in batches ordered by start time
  (``batches.py``), so a worker decodes their frames once.
* A failing sequence is reported with its error and does not stop the others.
  A worker process that dies breaks its pool: the pool is rebuilt for the
  rest, and every task the broken pool still held is run again alone in a
  fresh process, so only the task that kills its worker fails.
* Pool workers die with their parent and never rename a file into place after
  it is gone (``_watch.py``).  SIGTERM or Ctrl-C stops the workers, removes
  their temporary files and still writes ``build_summary.json`` and the
  split indexes, counting every file finished before the stop.
* Workers that die while starting (a script calling :func:`build_dataset` at its
  top level, outside ``if __name__ == "__main__":``, which every spawned worker
  imports again) stop the build with an error saying so; a Dask cluster left
  without any worker for :data:`DASK_NO_WORKER_S` seconds stops it too.
* A build in which every sequence it ran failed raises :class:`BuildFailedError`
  (after writing its summary and indexes), so a script cannot miss it.
* The output folder must not lie inside another dataset (one of its split
  folders, say): a build there would nest a dataset in it.
* Stale temporary files of killed writers are removed; those of another live
  run into the same folder are left alone (``spikesim.io.atomic``).
* Each split folder gets an ``index.json`` (``spikesim.io.build_index``), and
  the output folder ``plan.json`` (every task) and ``build_summary.json``.
"""

from __future__ import annotations

import contextlib
import json
import math
import multiprocessing as mp
import os
import sys
import tempfile
import time
import warnings
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import asdict, dataclass, field
from pathlib import Path

from spikesim._numba_cache import compiled_in_this_process
from spikesim.dataset._threads import worker_thread_env
from spikesim.dataset._watch import init_worker
from spikesim.dataset.batches import pool_batches
from spikesim.dataset.manifest import Manifest
from spikesim.dataset.plan import plan_tasks
from spikesim.dataset.record import STAGES, TaskRecord
from spikesim.dataset.worker import run_batch, run_task, validate_existing
from spikesim.errors import SpikeSimError, SpikeSimFileError, bad_value
from spikesim.scenes import frame_cache

__all__ = ["BuildFailedError", "BuildSummary", "build_dataset", "check_executors",
           "estimate_dataset"]

#: Seconds to wait for a Dask scheduler to answer.
SCHEDULER_TIMEOUT_S = 10
#: Seconds a Dask build waits while the scheduler has no worker left (every worker it
#: had died or left) before it stops, keeping what was made.  A scheduler that has had
#: no worker yet (an adaptive cluster scaling up from zero) is waited for, with a warning.
DASK_NO_WORKER_S = 60.0
#: Seconds between two checks of a Dask cluster's workers while no result comes in.
DASK_POLL_S = 1.0
#: ``BuildSummary.executor`` of a build that found every sequence already made.
NOTHING_TO_BUILD = "nothing to build"


@dataclass
class BuildSummary:
    """What a build did; ``records`` has one entry per sequence run or skipped."""

    done: int = 0
    skipped: int = 0
    failed: int = 0
    bytes: int = 0
    seconds: float = 0.0
    px_readouts: int = 0
    executor: str = "serial"
    records: list = field(default_factory=list)

    @property
    def failures(self) -> list[dict]:
        return [r for r in self.records if r["status"] == "failed"]

    def seconds_by_stage(self) -> dict:
        return {s: sum(r["seconds"].get(s, 0.0) for r in self.records if r["status"] == "done")
                for s in STAGES}

    def to_dict(self) -> dict:
        d = asdict(self)
        d["seconds_by_stage"] = self.seconds_by_stage()
        return d

    def line(self) -> str:
        """One line for people: what was done, skipped and failed, size, time and executor."""
        if self.executor == NOTHING_TO_BUILD:
            return (f"done 0, skipped {self.skipped}, failed 0: nothing to build (every "
                    "sequence is already made)")
        rate = self.px_readouts / self.seconds if self.seconds > 0 else 0.0
        return (f"done {self.done}, skipped {self.skipped}, failed {self.failed}; "
                f"{self.bytes / 2**20:.1f} MiB in {self.seconds:.1f} s "
                f"({rate:.3g} px·readouts/s, {self.executor})")


class BuildFailedError(SpikeSimError, RuntimeError):
    """Every sequence a build ran failed; ``summary`` is its :class:`BuildSummary`
    (``build_summary.json`` is written as for any build)."""

    def __init__(self, message: str, summary: BuildSummary):
        super().__init__(message)
        self.summary = summary


def _remove_stale_temps(out: Path, splits) -> int:
    from spikesim.io.atomic import remove_stale_temps

    return sum(remove_stale_temps(out / split) for split in splits if (out / split).is_dir())


def check_executors(workers: int, scheduler, dask_local,
                    names=("workers", "scheduler", "dask_local")) -> None:
    """Refuse two executors at once (``names``: how the caller calls the options)."""
    w, sch, dl = names
    if scheduler is not None and dask_local is not None:
        raise bad_value(sch, scheduler, f"no {dl} with it: give an existing scheduler or a "
                        "local cluster, not both")
    if workers != 1 and (scheduler is not None or dask_local is not None):
        other = sch if scheduler is not None else dl
        raise bad_value(w, workers, f"1 with {other} (the Dask workers run the tasks): "
                        "give one of the two")


def _probe_scheduler(scheduler: str) -> None:
    """Connect to the Dask scheduler once and close; a clear error when it cannot be reached.
    (The build connects again to submit: one more handshake, nothing beside a build, and
    the client's life stays inside :func:`_run_dask`.)"""
    client = _connect(scheduler)
    with contextlib.suppress(Exception):
        client.close()


def _connect(scheduler: str):
    try:
        from dask.distributed import Client
    except ImportError as exc:  # pragma: no cover - dask is a declared extra
        raise bad_value("scheduler", scheduler,
                        "dask[distributed] installed (pip install 'spikesim[dist]')") from exc
    try:
        return Client(scheduler, timeout=SCHEDULER_TIMEOUT_S)
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        raise SpikeSimFileError(
            f"cannot reach the Dask scheduler {scheduler!r} ({type(exc).__name__}: {exc}): "
            "check the address (tcp://HOST:PORT) and that the scheduler is running"
        ) from None


def _check_workers(workers) -> int:
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise bad_value("workers", workers, "an integer >= 1")
    return workers


#: What to do when a script's top-level call of the builder runs again in its workers.
GUARD_ADVICE = ('a script must make the call under `if __name__ == "__main__":` (each '
                "spawned worker imports the script again)")


def _refuse_in_spawned_import(func: str) -> None:
    """Exit quietly with one line when called while a spawned worker process imports the
    script that started it: the call sits at the script's top level, and a build (or
    calibration) of its own in every worker would write into the same folder."""
    if getattr(mp.current_process(), "_inheriting", False):
        raise SystemExit(f"spikesim: {func} ran again in a worker process while it imported "
                         f"the script that started the workers: {GUARD_ADVICE}")


def _workers_did_not_start(func: str) -> SpikeSimError:
    """The error of a pool whose workers all died before any of them was ready."""
    return SpikeSimError(f"the worker processes of {func} died while starting, before making "
                         f"any sequence (see their messages above): {GUARD_ADVICE}")


def _dataset_root_of(folder: Path) -> bool:
    """Whether ``folder`` is the root of a ``spikesim dataset`` build: it holds that
    build's ``plan.json`` or ``build_summary.json`` (as the build writes them)."""
    for name, key in (("plan.json", "tasks"), ("build_summary.json", "records")):
        path = folder / name
        try:
            data = json.loads(path.read_text()) if path.is_file() else None
        except (OSError, ValueError):
            continue
        if isinstance(data, dict) and key in data:
            return True
    return False


def _check_out_dir(out: Path, name: str = "out_dir") -> None:
    """Refuse an output folder inside an existing dataset (a split folder of it, or any
    folder below its root) or one that holds sequence files itself: a build there would
    nest a dataset in another one."""
    from spikesim.io.index import holds_sequences

    full = out.resolve()
    for parent in full.parents:
        if _dataset_root_of(parent):
            raise bad_value(name, str(out), f"a folder outside the dataset at {str(parent)!r} "
                            "(it lies inside it): give that root to resume or extend it, or "
                            "a new folder")
    if full.is_dir() and not _dataset_root_of(full) and holds_sequences(full):
        raise bad_value(name, str(out), "a dataset root or a new folder, not a folder of "
                        "sequence files (a split folder): give the folder above it to resume "
                        "or extend that dataset, or a new folder")


def compile_first(tasks: list[dict]) -> list[str]:
    """Compile the kernel families ``tasks`` need (:mod:`spikesim.families`) in
    this process, before local workers start, so that they load the machine
    code from numba's cache rather than each compiling it at the same time.
    Returns the kernels compiled (:func:`spikesim.families.kernel_name`; none
    when all were cached)."""
    from spikesim.families import family_of_noise, is_compiled, kernel_name
    from spikesim.precompile import precompile
    from spikesim.sensor import Sensor

    needed = set()
    for task in tasks:
        sensor = Sensor.from_dict(task["sensor"])
        family = family_of_noise(sensor.noise)
        needed.add((kernel_name(family, sensor.reset), family, sensor.reset))
    cold = sorted(k for k in needed if not is_compiled(k[0]))
    for _, family, reset in cold:
        precompile([family], resets=[reset])
    return [name for name, _, _ in cold]


def build_dataset(manifest: Manifest, out_dir: str | os.PathLike, workers: int = 1,
                  scheduler: str | None = None, dask_local: int | None = None,
                  progress: bool = True, limit: int | None = None,
                  prune: bool = False) -> BuildSummary:
    """Generate every sequence of ``manifest`` under ``out_dir/<split>/``.

    Parameters
    ----------
    workers : int
        Local processes (spawned); 1 runs in this process.
    scheduler : str, optional
        Address of an existing Dask distributed scheduler (``tcp://host:8786``).
    dask_local : int, optional
        Start a local Dask cluster with this many worker processes.
    limit : int, optional
        Only the first ``limit`` sequences of the plan (for trials).
    prune : bool
        Delete the sequence files of the plan's split folders that the plan does not
        make (left by a build of an earlier version of the manifest); without it they
        are kept, indexed with the rest, and a warning names them.  Not with ``limit``.

    Returns the :class:`BuildSummary`; a sequence that fails is in its ``failures``
    (and printed) while the others go on.  Raises :class:`BuildFailedError` (its
    ``summary`` attached) when every sequence the build ran failed, and
    :class:`~spikesim.errors.SpikeSimError` when the workers die while starting
    (``workers`` > 1 from a script without ``if __name__ == "__main__":``) or a
    Dask cluster keeps no worker for :data:`DASK_NO_WORKER_S` seconds; what was made
    until then is kept, counted in ``build_summary.json`` and indexed.  ``out_dir``
    inside an existing dataset (one of its split folders, say) is refused.
    """
    from tqdm.auto import tqdm

    from spikesim.io import build_index

    _refuse_in_spawned_import("build_dataset")
    workers = _check_workers(workers)
    if dask_local is not None:
        _check_workers(dask_local)
    check_executors(workers, scheduler, dask_local)
    if not isinstance(prune, bool):
        raise bad_value("prune", prune, "True or False")
    if prune and limit is not None:
        raise bad_value("prune", prune, "False with limit (a limited build makes only part "
                        "of the plan: the rest would be deleted)")
    if scheduler is not None:
        _probe_scheduler(scheduler)  # an unreachable scheduler is refused before any write
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise SpikeSimFileError(f"output folder {str(out)!r} is an existing file: give a folder "
                                "name (new or holding an earlier build)")
    _check_out_dir(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise SpikeSimFileError(f"cannot create output folder {str(out)!r}: "
                                f"{exc.strerror or exc}") from None
    tasks = [t.to_dict() for t in plan_tasks(manifest)]
    if limit is not None:
        if isinstance(limit, bool) or not isinstance(limit, int) or limit < 1:
            raise bad_value("limit", limit, "an integer >= 1")
        tasks = tasks[:limit]
    splits = sorted({t["split"] for t in tasks})
    _write_json(out / "plan.json", {"manifest": manifest.origin or manifest.name,
                                    "tasks": tasks})
    _remove_stale_temps(out, splits)

    summary = BuildSummary()
    pending = []
    for t in tasks:
        if validate_existing(out / t["file"], t):
            summary.skipped += 1
            summary.records.append(TaskRecord.of(
                t, status="skipped", bytes=(out / t["file"]).stat().st_size,
                seconds={}).to_dict())
        else:
            pending.append(t)
    t0 = time.perf_counter()
    bar = tqdm(total=len(pending), desc=f"dataset {manifest.name}", unit="seq",
               disable=not progress or not pending)

    def on_result(rec):
        summary.records.append(rec)
        if rec["status"] == "done":
            summary.done += 1
            summary.bytes += rec["bytes"]
            summary.px_readouts += rec["px_readouts"]
        else:
            summary.failed += 1
            bar.write(f"failed {rec['file']}: {rec['error']}")
        elapsed = time.perf_counter() - t0
        bar.set_postfix_str(f"{summary.px_readouts / max(elapsed, 1e-9):.3g} px·readouts/s")
        bar.update(1)

    try:
        if not pending:
            summary.executor = NOTHING_TO_BUILD  # no executor started for nothing
        elif scheduler is not None or dask_local is not None:
            summary.executor = (f"dask scheduler {scheduler}" if scheduler is not None
                                else f"dask LocalCluster ({dask_local} workers)")
            if dask_local is not None:
                compile_first(pending)
            _run_dask(pending, out, scheduler, dask_local, on_result)
        elif workers == 1 or len(pending) <= 1:
            summary.executor = "serial"
            frame_cache.clear()  # as a fresh process: nothing decoded by earlier work
            try:
                for t in pending:
                    on_result(run_task(t, str(out)))
            finally:
                frame_cache.clear()  # the memory goes back when the build ends
        else:
            summary.executor = f"{workers} local processes"
            compile_first(pending)
            with worker_thread_env(max(1, (os.cpu_count() or 1) // workers)):
                _run_pool(pending, out, workers, on_result)
    except BaseException as exc:
        # stopped (SIGTERM, Ctrl-C) or a scheduler error: record what was done,
        # the files workers finished but had not reported yet included, and index it
        summary.seconds = time.perf_counter() - t0
        stopped = " (stopped by an error)" if isinstance(exc, Exception) else " (interrupted)"
        summary.executor += stopped
        with contextlib.suppress(Exception):
            _record_finished(pending, out, summary)
            for split in splits:
                if (out / split).is_dir():
                    build_index(out / split)
        with contextlib.suppress(Exception):
            _write_summary(out / "build_summary.json", summary)
        if progress and not isinstance(exc, Exception):  # a stop, not an error
            bar.leave = False
            bar.close()  # its count lags the files kept: cleared, not drawn again
            print(f"stopped: {summary.done} of {len(pending)} sequences to make were "
                  f"finished and kept in {out}; running the same build again makes the "
                  f"other {len(pending) - summary.done - summary.failed}", file=sys.stderr)
        raise
    finally:
        bar.close()
    summary.seconds = time.perf_counter() - t0
    _remove_stale_temps(out, splits)  # those of workers that died (os._exit, kill -9)
    if limit is None:
        _unplanned(out, tasks, prune)
    for split in splits:
        if (out / split).is_dir():
            build_index(out / split)
    _write_summary(out / "build_summary.json", summary)
    if summary.failed and not summary.done:
        first = summary.failures[0]
        raise BuildFailedError(
            f"every sequence this build ran failed ({summary.failed}; the first, "
            f"{first['file']}: {first['error']}): see {str(out / 'build_summary.json')!r} "
            "for all of them", summary)
    return summary


def _unplanned(out: Path, tasks: list[dict], prune: bool) -> None:
    """Sequence files in the split folders that this plan does not make (left by a build
    of an earlier version of the manifest): deleted with ``prune``, else a warning (they
    are indexed and read with the rest)."""
    planned = {t["file"] for t in tasks}
    extra = sorted(out / split / p.name for split in {t["split"] for t in tasks}
                   for p in (out / split).glob("*.h5") if f"{split}/{p.name}" not in planned)
    if not extra:
        return
    names = [f"{p.parent.name}/{p.name}" for p in extra]
    shown = ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")
    if prune:
        for p in extra:
            p.unlink(missing_ok=True)
        print(f"pruned {len(extra)} sequence file(s) the plan does not make ({shown})",
              file=sys.stderr)
        return
    warnings.warn(f"{len(extra)} sequence file(s) in {out} are not in this manifest's plan "
                  f"({shown}), left by an earlier build: they are indexed and read with the "
                  "rest; --prune (prune=True) deletes them", UserWarning, stacklevel=3)


def _record_finished(pending: list[dict], out: Path, summary: BuildSummary) -> None:
    """Count as done the tasks of ``pending`` with no record whose file is complete
    on disk: a worker's batch reports only when all of it is made, so an
    interruption stops workers that had finished files the parent never heard of.
    (Only complete files get their final name.)"""
    reported = {r["file"] for r in summary.records}
    for t in pending:
        path = out / t["file"]
        if t["file"] in reported or not validate_existing(path, t):
            continue
        size = path.stat().st_size
        sensor = t["sensor"]
        px = int(sensor["height"]) * int(sensor["width"]) * int(t["n_readouts"])
        summary.records.append(TaskRecord.of(t, bytes=size, px_readouts=px,
                                             seconds={}).to_dict())
        summary.done += 1
        summary.bytes += size
        summary.px_readouts += px


#: Seconds a stopped worker gets to remove its temporary file before it is killed.
STOP_GRACE_S = 10.0


def _new_pool(workers: int, started=None) -> ProcessPoolExecutor:
    """A pool of ``workers`` spawned processes set up by :func:`init_worker`, which sets
    the event ``started`` (when given) once a worker is ready to run tasks."""
    return ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("spawn"),
                               initializer=init_worker, initargs=(os.getpid(), started))


def _stop_pool(pool: ProcessPoolExecutor) -> None:
    """Cancel what is queued and SIGTERM the workers (each removes its temporary file);
    a worker still alive after :data:`STOP_GRACE_S` seconds is killed, so the stop
    cannot hang on it (its temporary is then removed by the next build)."""
    procs = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        with contextlib.suppress(Exception):
            p.terminate()
    for p in procs:
        with contextlib.suppress(Exception):
            p.join(timeout=STOP_GRACE_S)
            if p.is_alive():
                p.kill()
                p.join(timeout=5)


def _write_summary(path: Path, summary: BuildSummary) -> None:
    """Write ``build_summary.json`` with a ``history`` of every run; a run that made
    and failed nothing (all skipped) keeps the summary, and timing, of the last real one."""
    previous = None
    if path.is_file():
        try:
            previous = json.loads(path.read_text())
        except (OSError, ValueError):
            previous = None
    history = list((previous or {}).get("history", []))
    history.append({"finished": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "executor": summary.executor,
                    "done": summary.done, "skipped": summary.skipped, "failed": summary.failed,
                    "seconds": summary.seconds})
    if previous is not None and summary.done == 0 and summary.failed == 0:
        data = previous
    else:
        data = summary.to_dict()
    data["history"] = history
    _write_json(path, data)


def _run_pool(pending: list[dict], out: Path, workers: int, on_result) -> None:
    """Run ``pending`` on pools of ``workers`` spawned processes, in batches; a pool that
    breaks is replaced and what it held is retried alone (:func:`_retry_alone`).  Raises
    when the first pool breaks before any worker started (the script's top level runs in
    every worker: :data:`GUARD_ADVICE`), instead of retrying every task in vain."""
    threads = max(1, (os.cpu_count() or 1) // workers)
    queue = pool_batches(pending, workers)  # clips of one video together: frames decoded once
    started = mp.get_context("spawn").Event()
    while queue:
        lost: list[dict] = []
        pool = _new_pool(workers, started)
        try:
            futures = {}
            while (queue or futures) and not lost:
                while queue and len(futures) < 2 * workers:
                    batch = queue.pop(0)
                    futures[pool.submit(run_batch, batch, str(out), threads)] = batch
                done, _ = wait(futures, return_when=FIRST_COMPLETED)
                for fut in done:
                    batch = futures.pop(fut)
                    try:
                        records = fut.result()
                    except BrokenProcessPool:
                        lost += batch
                        continue
                    for rec in records:
                        on_result(rec)
            # the pool is unusable: what it still held is lost too
            lost += [t for batch in futures.values() for t in batch]
            pool.shutdown(wait=True)
        except BaseException:
            _stop_pool(pool)
            raise
        if lost and not started.is_set():
            raise _workers_did_not_start("build_dataset")
        # only now, with every worker of the broken pool stopped, is each
        # lost task's file final (complete and renamed, or never renamed);
        # the others are run again, each alone, so that only the culprit fails
        for t in lost:
            on_result(_retry_alone(t, out, threads))


def _retry_alone(task: dict, out: Path, threads: int) -> dict:
    """Run a task lost with a broken pool again in a fresh process of its own."""
    if validate_existing(out / task["file"], task):
        return _lost(task, None, out)
    pool = _new_pool(1)
    try:
        rec = pool.submit(run_task, task, str(out), threads).result()
        pool.shutdown(wait=True)
        return rec
    except BrokenProcessPool:
        pool.shutdown(wait=True)
        return _lost(task, BrokenProcessPool("its worker process died (killed or crashed) "
                                             "while generating this sequence, twice"), out)
    except BaseException:
        _stop_pool(pool)
        raise


def _lost(task: dict, exc: BaseException | None, out: Path | None = None) -> dict:
    """The record of a task whose result was lost with its worker.

    A task can finish (its file renamed into place) in a surviving worker just
    before the pool breaks; its result is then lost although its file is
    complete. Such a file is checked like one of an earlier run and counted as
    done, so the summary never calls a finished, valid file failed.
    """
    if out is not None and validate_existing(out / task["file"], task):
        from spikesim.io import open_h5

        path = out / task["file"]
        with open_h5(path) as seq:
            n, h, w = seq.shape
        return TaskRecord.of(task, bytes=path.stat().st_size,
                             px_readouts=n * h * w).to_dict()
    return TaskRecord.of(task, status="failed",
                         error=f"{type(exc).__name__}: {exc or 'a worker process died'}").to_dict()


def _local_cluster(n: int):
    """A local Dask cluster of ``n`` one-thread worker processes; a clear error when
    they do not start (a script's top level run again in each of them, say)."""
    from dask.distributed import LocalCluster

    try:
        return LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                            dashboard_address=None)
    except Exception as exc:  # noqa: BLE001 - Dask says only "Nanny failed to start"
        raise SpikeSimError(f"the workers of a local Dask cluster (dask_local={n}) did not "
                            f"start ({type(exc).__name__}: {exc}; see their messages above): "
                            f"{GUARD_ADVICE}") from None


def _dask_workers(client) -> int:
    """Workers the scheduler has now (0 when it does not answer)."""
    try:
        return len(client.nthreads())
    except Exception:  # noqa: BLE001 - a scheduler that does not answer has none for us
        return 0


def _run_dask(pending: list[dict], out: Path, scheduler, dask_local, on_result) -> None:
    """Run ``pending`` on a Dask cluster (an existing ``scheduler`` or a local one of
    ``dask_local`` workers), one task a sequence.  A task whose workers died fails
    alone (Dask's ``KilledWorker``); a cluster left with no worker for
    :data:`DASK_NO_WORKER_S` seconds (every worker died or left) stops the build with
    an error, where Dask would wait for workers forever.  Before its first worker
    joins, the build waits (a warning says so)."""
    try:
        from dask.distributed import Client, as_completed
    except ImportError as exc:  # pragma: no cover - dask is a declared extra
        raise bad_value("scheduler", scheduler or dask_local,
                        "dask[distributed] installed (pip install 'spikesim[dist]')") from exc
    cluster = None
    if scheduler is not None:
        client = _connect(scheduler)
    else:
        cluster = _local_cluster(dask_local)
        client = Client(cluster)
    try:
        futures = [client.submit(run_task, t, str(out.resolve()), 1, pure=False,
                                 key=f"seq-{t['file']}") for t in pending]
        by_key = {f.key: t for f, t in zip(futures, pending, strict=True)}
        results = as_completed(futures)
        checked = alone_since = None
        seen = _dask_workers(client) > 0  # a worker was there: its loss can be told
        while not results.is_empty():
            batch = results.next_batch(block=False)
            for fut in batch:
                try:
                    on_result(fut.result())
                except Exception as exc:  # noqa: BLE001 - a lost worker fails only its task
                    on_result(_lost(by_key[fut.key], exc, out))
            if batch:
                alone_since = None
                continue
            time.sleep(0.1)
            now = time.monotonic()
            if checked is not None and now - checked < DASK_POLL_S:
                continue
            checked = now
            if _dask_workers(client):
                seen, alone_since = True, None
            elif not seen:
                if alone_since is None:
                    warnings.warn(f"the Dask scheduler {scheduler or ''} has no worker yet: "
                                  "waiting for workers to join (start them with `dask worker "
                                  "SCHEDULER_ADDRESS`)", stacklevel=2)
                    alone_since = now
            elif alone_since is None:
                alone_since = now
            elif now - alone_since >= DASK_NO_WORKER_S:
                raise SpikeSimError(
                    f"the Dask cluster has had no worker for {DASK_NO_WORKER_S:.0f} "
                    f"s (they died or left) with {results.count()} of {len(pending)} "
                    "sequences not made: see the workers' logs, start workers and run the "
                    "same build again (it makes only what is missing)")
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _write_json(path: Path, data) -> None:
    from spikesim.io.atomic import atomic_path

    with atomic_path(path) as tmp:
        Path(tmp).write_text(json.dumps(data, indent=1))


def _warm_up(task: dict, out_dir: str, threads: int, barrier=None) -> int:
    """One untimed sequence in this worker (imports, kernel loading, flow and codec
    set-up); with a ``barrier``, wait until every worker has made its own, so that
    no worker takes two warm-ups while another is still starting."""
    run_task(task, f"{out_dir}/warm-{os.getpid()}", threads)
    if barrier is not None:
        barrier.wait(timeout=600)
    return os.getpid()


def _parallel_calibration(tasks: list[dict], workers: int, warm: dict,
                          dask_local: int | None) -> tuple:
    """Run ``tasks`` on the executor a build would start; returns
    (start-up seconds, seconds of work per task in parallel, results).

    Start-up is the time from asking for the workers until each has made one
    warm-up sequence of its own (imports, kernel loading, flow and codec
    set-up), less one ordinary sequence; the tasks are then timed with all
    workers busy at once, so contention for cores, memory and disk is in the
    figure.
    """
    threads = max(1, (os.cpu_count() or 1) // workers)
    # a barrier for the pool's warm-ups (its manager process is no part of a build's start-up)
    manager = mp.get_context("spawn").Manager() if dask_local is None else None
    with tempfile.TemporaryDirectory(prefix="spikesim-calib-") as tmp:
        t0 = time.perf_counter()
        if dask_local is not None:
            from dask.distributed import Client

            cluster = _local_cluster(dask_local)
            client = Client(cluster)
            client.run(_warm_up, warm, tmp, 1)  # on every worker at once
            submit = lambda fn, *a: client.submit(fn, *a, pure=False)  # noqa: E731
            threads = 1

            def close():
                client.close()
                cluster.close()
        else:
            started = mp.get_context("spawn").Event()
            pool = _new_pool(workers, started)  # as the build's: workers die with this process
            env = contextlib.ExitStack()  # the workers start on the first submits below
            env.enter_context(worker_thread_env(threads))
            barrier = manager.Barrier(workers)
            submit = pool.submit

            def close():
                pool.shutdown()
                manager.shutdown()
                env.close()

            try:
                for f in [submit(_warm_up, warm, tmp, threads, barrier) for _ in range(workers)]:
                    f.result()
            except BaseException as exc:
                close()
                if isinstance(exc, BrokenProcessPool) and not started.is_set():
                    raise _workers_did_not_start("estimate_dataset") from None
                raise
        try:
            ready = time.perf_counter() - t0
            t1 = time.perf_counter()
            recs = [f.result() for f in [submit(run_task, t, tmp, threads) for t in tasks]]
            per_task = (time.perf_counter() - t1) / len(tasks)
        finally:
            close()
    # the warm-up sequence itself is work a build does too: one lane-task of it is not start-up
    return max(ready - per_task * workers, 0.0), per_task, recs


def _spread(items: list, n: int) -> list:
    """``n`` items (at most all) spread evenly over ``items``, in order."""
    if not items or n <= 0:
        return []
    n = min(n, len(items))
    return [items[round(i * (len(items) - 1) / max(n - 1, 1))] for i in range(n)]


def _task_frames(task: dict, fps_of: dict) -> set:
    """(video, frame index) of every frame a video task reads; empty for other tasks."""
    spec = task["scene"]
    info = fps_of.get((spec.get("path"), spec.get("sequence")))
    if spec.get("kind") != "video" or info is None:
        return set()
    fps, n_frames = info
    start = float(spec.get("start_s", 0.0))
    stop = start + task["n_readouts"] / float(task["sensor"]["clock_hz"])
    first = min(max(math.floor(start * fps), 0), n_frames - 1)
    last = min(max(math.ceil(stop * fps), first), n_frames - 1)
    key = (spec.get("path"), spec.get("sequence"))
    return {(key, i) for i in range(first, last + 1)}


def _frames_to_decode(tasks: list[dict], manifest: Manifest, lanes: int, dask: bool) -> int:
    """Image files of video frames the build decodes (frame folders; a video file's
    decoding stays in the time per task): each once per process that needs it, with a
    serial build's clips of a video sharing its frames, a pool's within a batch
    (``batches.py``), and a Dask build's none (one task at a time, anywhere)."""
    fps_of = {}
    for src in manifest.sources:
        if src.kind == "video" and Path(src.path).is_file():
            continue  # a video file is decoded by its container reader, not per frame file
        for v in src.videos:
            fps_of[(src.path, v.name if src.kind != "video" else None)] = (v.fps, v.n_frames)
    if not fps_of:
        return 0
    if dask:
        groups = [[t] for t in tasks]
    elif lanes > 1:
        groups = pool_batches(tasks, lanes)
    else:
        groups = [tasks]
    return sum(len(set().union(*(_task_frames(t, fps_of) for t in g))) for g in groups if g)


def estimate_dataset(manifest: Manifest, workers: int = 1, calibration_tasks: int = 3,
                     limit: int | None = None, dask_local: int | None = None,
                     out_dir: str | os.PathLike | None = None) -> dict:
    """The plan of a build with disk and time estimates from a short calibration run.

    Sequences spread over the plan are generated into a temporary folder the
    way the build will make them: ``calibration_tasks`` of them serially in
    this process after one untimed warm-up, or, on the executor the build
    starts (``workers`` spawned processes or a local Dask cluster), at least
    two per worker after every worker has made one untimed warm-up sequence;
    that start-up (each worker importing spikesim and loading its kernels) is
    timed too.  Bytes and seconds are extrapolated to the sequences still to
    make (those already valid in ``out_dir`` are skipped, as a build would):
    time = start-up + rounds of ``workers`` sequences in parallel, with video
    decoding counted per frame rather than per clip: the calibration measures
    seconds per decoded frame, and the build decodes each frame once per
    process that needs it (a serial build's clips of one video share their
    frames, a pool's share them within a batch), ``frames_to_decode`` in all.
    """

    _refuse_in_spawned_import("estimate_dataset")
    workers = _check_workers(workers)
    if out_dir is not None:
        _check_out_dir(Path(out_dir))
    parallel = dask_local if dask_local is not None else workers
    tasks = [t.to_dict() for t in plan_tasks(manifest)]
    if limit is not None:
        tasks = tasks[:limit]
    all_tasks = tasks
    if out_dir is not None and Path(out_dir).is_dir():
        tasks = [t for t in tasks if not validate_existing(Path(out_dir) / t["file"], t)]
    px = int(manifest.size[0] * manifest.size[1])
    total_px = px * sum(t["n_readouts"] for t in tasks)
    bytes_per_px = seconds_per_task = decode_s = 0.0
    recs, startup_s, compile_s = [], 0.0, 0.0
    cal = _spread(tasks, calibration_tasks)
    lanes = min(parallel, len(tasks)) if len(tasks) > 1 else 1
    if tasks and lanes > 1:
        # one sequence here first: a cold numba cache is compiled and written once, so the
        # workers below load kernels as a real build's do (compiling is a one-off cost)
        with tempfile.TemporaryDirectory(prefix="spikesim-calib-") as tmp:
            t0 = time.perf_counter()
            run_task(tasks[0], tmp)
            if compiled_in_this_process():
                compile_s = time.perf_counter() - t0
        cal = _spread(tasks, max(calibration_tasks, 2 * lanes))  # every worker busy twice
        startup_s, per_task, recs = _parallel_calibration(cal, lanes, tasks[0], dask_local)
        seconds_per_task = per_task * lanes  # one lane's time per task
    elif tasks:
        with tempfile.TemporaryDirectory(prefix="spikesim-calib-") as tmp:
            t0 = time.perf_counter()
            frame_cache.clear()
            run_task(cal[0], tmp + "/warm")  # loads kernels, fills OS caches
            warm_s = time.perf_counter() - t0
            recs = []
            for t in cal:
                frame_cache.clear()  # each decodes its frames: counted and timed below
                recs.append(run_task(t, tmp))
            frame_cache.clear()
    ok = [r for r in recs if r["status"] == "done"]
    if ok:
        cal_px = sum(r["px_readouts"] for r in ok)
        bytes_per_px = sum(r["bytes"] for r in ok) / cal_px
        if lanes == 1:
            seconds_per_task = sum(r["seconds"]["total"] for r in ok) / len(ok)
            # this process pays the kernel loading once, like the build's; compiling
            # them (a cold cache) is a one-off this dry run has now paid
            startup_s = max(warm_s - seconds_per_task, 0.0)
            if compiled_in_this_process():
                compile_s, startup_s = startup_s, 0.0
        decoded = sum(r.get("frames_decoded", 0) for r in ok)
        if decoded:
            # decoding is paid once per frame and process, not per clip: take it out of
            # the time per task and add it back for the frames the build will decode
            decode_s = sum(r["seconds"]["scene"] for r in ok) / decoded
            seconds_per_task -= decode_s * decoded / len(ok)
    rounds = math.ceil(len(tasks) / max(lanes, 1))
    to_decode = _frames_to_decode(tasks, manifest, lanes, dask_local is not None)
    seconds = startup_s + rounds * seconds_per_task + decode_s * to_decode / max(lanes, 1)
    by_split: dict[str, int] = {}
    for t in all_tasks:
        by_split[t["split"]] = by_split.get(t["split"], 0) + 1
    return {
        "manifest": manifest.origin or manifest.name,
        "sequences": len(all_tasks),
        "to_make": len(tasks),
        "by_split": by_split,
        "readouts_per_sequence": manifest.n_readouts,
        "size": list(manifest.size),
        "px_readouts": total_px,
        "estimated_bytes": int(math.ceil(bytes_per_px * total_px)),
        "estimated_seconds": seconds if tasks else 0.0,
        "seconds_per_sequence": (seconds - startup_s) / rounds if tasks else 0.0,
        "frames_to_decode": to_decode,
        "startup_seconds": startup_s,
        "compile_seconds": compile_s,
        "executor": (NOTHING_TO_BUILD if not tasks
                     else f"dask LocalCluster ({dask_local} workers)" if dask_local is not None
                     else f"{workers} local processes" if workers > 1 else "serial"),
        "calibrated_on": [t["file"] for t in cal],
        "calibration_failures": [r["error"] for r in recs if r["status"] != "done"],
    }
