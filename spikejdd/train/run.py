"""The thin ``train`` entry: build a :class:`~spikejdd.train.trainer.Trainer`, resume,
loop over batches, validate / checkpoint / log on schedule, end each chunk with a
validation, ``last.pt`` and a benchmark row."""

from __future__ import annotations

import json
import math
import shutil
import sys
import time
from pathlib import Path

from tqdm import tqdm

from spikejdd.train.config import TrainConfig
from spikesim.cli_guard import Terminated
from spikesim.errors import SpikeSimTypeError, bad_value
from spikesim.stops import deferred_stops

__all__ = ["train"]


def _append(path, row: dict) -> None:
    with open(path, "a", encoding="utf-8") as fh:
        fh.write(json.dumps(row) + "\n")


def _keep_rows_up_to(path: Path, step: int) -> None:
    """Drop the rows of the JSON-lines log ``path`` whose ``step`` is beyond ``step``,
    and a last row cut short by a kill."""
    if not path.exists():
        return
    rows = path.read_text(encoding="utf-8").splitlines()
    kept = []
    for row in rows:
        try:
            if json.loads(row).get("step", 0) <= step:
                kept.append(row)
        except ValueError:
            continue
    if len(kept) != len(rows):
        path.write_text("".join(r + "\n" for r in kept), encoding="utf-8")


def _refuse_results_without_checkpoint(cfg: TrainConfig) -> None:
    """Refuse to start afresh (``resume`` None or "auto") in a folder holding an earlier
    run's ``best.pt`` or validation rows but no ``last.pt``: a run stopped before its
    first checkpoint, whose results the new run would overwrite."""
    out = Path(cfg.out)
    if cfg.resume not in (None, "auto") or (out / "last.pt").exists():
        return
    held = [name for name in ("best.pt", "log.jsonl")
            if (out / name).is_file() and (out / name).stat().st_size > 0]
    if held:
        raise bad_value("out", str(cfg.out), "a folder without an earlier run's results: it "
                        f"holds {' and '.join(held)} but no last.pt to resume from (that run "
                        "stopped before its first checkpoint; checkpoint_every, or "
                        "--checkpoint-every, sets how often they come); choose another "
                        "folder, or remove those files to start over")


def _first_missing(path: Path) -> Path | None:
    """The outermost folder of ``path`` that does not exist yet (None: it exists)."""
    missing = None
    for p in (path, *path.parents):
        if p.exists():
            return missing
        missing = p
    return missing


def train(cfg: TrainConfig | dict) -> dict:
    """Run (or resume) a training run; returns the final summary (also in ``run.json``):
    ``steps_done``, ``minutes`` and ``setup_minutes`` count the whole run,
    ``resumed_at_step``, ``minutes_this_call`` and ``setup_minutes_this_call`` this call.

    Times are wall-clock minutes. ``minutes`` is training time: it starts when a call's
    first batch is ready and counts steps, validations and checkpoints. What comes
    before is ``setup_minutes``: building the model and data, resuming, starting the
    loader's workers, compiling the simulation kernels (numba, on the first run after
    an install: a minute or more) and building the validation sweep's frames. The
    time limit (``time_limit_min``) counts the whole call, setup included.

    Writes under ``cfg.out``: ``run.json``, ``log.jsonl`` (one validation per
    line), ``bench.jsonl`` (one benchmark row per chunk, sweep validation
    only), ``last.pt`` and ``best.pt`` (highest validation PSNR).
    """
    from spikejdd.train.trainer import Trainer

    t_call = time.time()  # the time limit counts from here: the whole call
    if isinstance(cfg, dict):
        cfg = TrainConfig.from_dict(cfg)
    if not isinstance(cfg, TrainConfig):
        raise SpikeSimTypeError(f"cfg must be a TrainConfig or dict, got {type(cfg).__name__}")
    cfg.validate()
    if cfg.resume is None and (Path(cfg.out) / "last.pt").exists():
        # training from scratch would overwrite the run's checkpoints and log
        raise bad_value("out", str(cfg.out), "a folder without a run: it holds one (last.pt); "
                        "resume='auto' (--resume auto) continues it, or choose another folder")
    _refuse_results_without_checkpoint(cfg)
    made = _first_missing(Path(cfg.out))
    try:
        tr = Trainer(cfg)
        path = tr.resume_path()
        if path:
            tr.resume(path)
        elif cfg.init:
            tr.initialise(cfg.init)
    except BaseException:  # a refused start (weights of another model…) leaves no folder
        if made is not None and made.is_dir() and not any(p.is_file() for p in made.rglob("*")):
            shutil.rmtree(made)
        raise
    out, main = tr.out, tr.main
    if main:
        (out / "run.json").write_text(json.dumps(tr.run_info, indent=1, default=str))
        for log in ("log.jsonl", "bench.jsonl"):  # rows of steps the checkpoint does not hold
            _keep_rows_up_to(out / log, tr.state.step)  # (a run killed after them) go
    start_step, start_minutes = tr.state.step, tr.state.minutes
    start_setup, t_train = tr.state.setup_minutes, None  # t_train: the first batch's arrival

    def minutes() -> float:  # the run's training time, over every call
        return start_minutes + (0.0 if t_train is None else (time.time() - t_train) / 60)

    def setup_minutes() -> float:  # the run's set-up time (before each call's first batch)
        return start_setup + ((t_train or time.time()) - t_call) / 60

    resumed_here = bool(path) and Path(path).resolve() == (out / "last.pt").resolve()
    saved_step = start_step if resumed_here else -1  # the step out/last.pt holds (-1: none)

    bar = tqdm(total=cfg.steps, initial=tr.state.step, desc="train",
               disable=not (main and cfg.progress))
    running, seen, t_last = tr.state.running_loss, 0, time.time()
    if main and cfg.validation_kind() == "sweep":
        # before the loader's workers start: on a cold numba cache, simulating the sweep
        # here compiles the kernels it uses once, and the workers load them from the
        # cache instead of each compiling its own (measured in docs/sjdd.md)
        tr.validation_frames()
    batches = tr.batches() if tr.state.step < cfg.steps else iter(())
    try:
        for batch in batches:
            if t_train is None:  # the set-up ends
                t_train = time.time()
                tr.state.setup_minutes = setup_minutes()
            with deferred_stops():  # a stop waits for the step's end: the state saved is whole
                lv = tr.step(batch)
                st = tr.state
                running = lv if running is None else 0.9 * running + 0.1 * lv
                st.running_loss = running
            seen += batch["spikes"].shape[0] * tr.world
            if main and st.step % cfg.log_every == 0:
                now = time.time()
                psnr = -10 * math.log10(max(running, 1e-12))
                bar.set_postfix(loss=f"{running:.2e}", psnr=f"{psnr:.2f}",
                                samples_s=f"{seen / max(now - t_last, 1e-9):.1f}",
                                lr=f"{tr.scheduler.get_last_lr()[0]:.1e}")
                seen, t_last = 0, now
            bar.update(1)
            last = st.step >= cfg.steps or tr.over_time(t_call)
            if main and (st.step % cfg.eval_every == 0 or last):
                res = tr.validate()
                res.update(step=st.step, train_loss=running, minutes=minutes(),
                           setup_minutes=st.setup_minutes, lr=tr.scheduler.get_last_lr()[0])
                st.history.append(res)
                _append(out / "log.jsonl", res)
                bar.write(f"step {st.step}: validation PSNR {res['psnr_linear']:.2f} dB "
                          f"(train loss {running:.3e})")
                if res["psnr_linear"] > st.best_psnr:
                    st.best_psnr = res["psnr_linear"]
                    st.minutes = minutes()
                    tr.save("best.pt", res, resumable=False)
            if main and (st.step % cfg.checkpoint_every == 0 or last):
                st.minutes = minutes()
                with deferred_stops():
                    tr.save("last.pt")
                saved_step = st.step
            if last:
                if main:
                    row = tr.bench(st.history[-1])
                    if row is not None:
                        row["minutes"] = minutes()
                        _append(out / "bench.jsonl", row)
                        bar.write(f"step {st.step}: sjdd {row['sjdd_psnr']:.2f} dB, "
                                  f"{row['best_classical']} {row['classical_psnr']:.2f} dB, "
                                  f"delta {row['delta_db']:+.2f} dB")
                break
    except (KeyboardInterrupt, Terminated):
        if main:  # a stop (Ctrl-C, SIGTERM): keep the steps done, say how to go on
            bar.leave = False
            bar.close()
            for _ in range(3):
                try:
                    if hasattr(batches, "close"):
                        batches.close()  # the loader's workers go (they may be dying)
                    if tr.state.step > max(saved_step, 0):
                        tr.state.minutes = minutes()
                        tr.save("last.pt")
                        saved_step = tr.state.step
                    break
                except RuntimeError:  # PyTorch reporting a loader worker the stop killed
                    continue
            if saved_step >= 0:
                print(f"kept {out / 'last.pt'} (step {saved_step}): --resume auto continues "
                      "from it", file=sys.stderr)
        raise
    if hasattr(batches, "close"):
        batches.close()
    bar.close()
    st = tr.state
    summary = dict(tr.run_info, steps_done=st.step, best_psnr=st.best_psnr, history=st.history,
                   minutes=minutes(), setup_minutes=setup_minutes(), resumed_at_step=start_step,
                   minutes_this_call=minutes() - start_minutes,
                   setup_minutes_this_call=setup_minutes() - start_setup)
    if main:
        (out / "run.json").write_text(json.dumps(summary, indent=1, default=str))
    tr.close()
    return summary
