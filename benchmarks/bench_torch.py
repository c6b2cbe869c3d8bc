"""The torch backend against the numba kernel: throughput, bits, training on the device.

Simulation (every device): pixel-readouts per second of ``spikesim.simulate``
with ``backend="torch"`` on ``--device`` and with the numba kernel, in the same
run, alternating, on the same input — RGGB, paper GN σ = 10, a moving scene
(``bench_kernel``'s: 1 px of motion per 16 readouts, key frames from a small
cycle, so that the simulator is measured, not the making of images) at
1000 × 1000 and smaller sizes — median and range of ``--repeats`` runs, and
whether the two streams are bit-identical.  On a GPU the goal is 2·10¹⁰
pixel-readouts/s (a 1000 × 1000 colour sensor at 20 kHz in real time).

Training (``--train``, meant for a GPU): SJDD-Net steps per second with every
batch rendered and simulated on the device (``--online --device-sim``) against
simulation in ``--workers`` spawned loader processes (``--online``), same
model and batch; and the seconds from launching ``spikejdd train --online
--device-sim --steps 1`` to the end of its first step (a fresh process; the
machine's own start is not counted).

Run::

    .venv/bin/python benchmarks/bench_torch.py                 # CPU: torch vs numba
    .venv/bin/python benchmarks/bench_torch.py --device cuda --train --workers 14

Writes ``benchmarks/results/torch.json`` and ``torch.md`` (``--device cuda``:
``torch_cuda.json``/``.md``; ``--quick``: a smoke run, nothing written).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import machine
import numpy as np
import torch
from bench_kernel import make_scene

import spikesim as ss

RESULTS = Path(__file__).parent / "results"
CLOCK = 20_000.0
#: (side, readouts) of the simulation cases: about 4·10⁷ pixel-readouts each.
SIZES = ((1000, 40), (256, 600), (64, 10_000))
QUICK_SIZES = ((128, 40), (32, 400))
REAL_TIME = 2e10  # pixel-readouts/s of a 1000 × 1000 sensor at 20 kHz


def _sync(device: str) -> None:
    if device.startswith("cuda"):
        torch.cuda.synchronize()


def _median_range(values) -> tuple[float, float, float]:
    v = sorted(values)
    return v[len(v) // 2], v[0], v[-1]


def simulation_case(side: int, n: int, device: str, repeats: int) -> dict:
    scene = make_scene("moving", side, n, CLOCK)
    sensor = ss.Sensor(height=side, width=side, cfa="RGGB", clock_hz=CLOCK,
                       noise=ss.noise.PaperNoise(sigma_g=10.0))
    kw = dict(seed=1, gt_readouts=[])
    want = ss.simulate(scene, sensor, n, **kw)  # warm: compiled or loaded kernels
    got = ss.simulate(scene, sensor, n, backend="torch", device=device, **kw)
    times = {"numba": [], "torch": []}
    for _ in range(repeats):  # alternating, so that the load of the machine hits both
        t0 = time.perf_counter()
        ss.simulate(scene, sensor, n, **kw)
        times["numba"].append(time.perf_counter() - t0)
        _sync(device)
        t0 = time.perf_counter()
        ss.simulate(scene, sensor, n, backend="torch", device=device, **kw)
        _sync(device)
        times["torch"].append(time.perf_counter() - t0)
    work = side * side * n
    row = {"size": f"{side}x{side}", "readouts": n, "device": device,
           "bit_identical": bool(np.array_equal(got.packed, want.packed)), "repeats": repeats}
    for name, ts in times.items():
        rates = [work / t for t in ts]
        row[f"{name}_px_readouts_s"] = _median_range(rates)
    row["torch_over_numba"] = _median_range(
        [t_n / t_t for t_n, t_t in zip(times["numba"], times["torch"], strict=True)])
    return row


#: The trainer's settings timed: SJDD-Net (default widths), batch 8, 64 × 64 crops;
#: ``--quick``: the lite model on 16 × 16 crops, batch 2 (a smoke run on a CPU).
TRAIN = {"model": "default", "batch_size": 8, "crop": 64}
QUICK_TRAIN = {"model": "lite", "batch_size": 2, "crop": 16}


def training_steps(device: str, device_sim: bool, workers: int, steps: int, warm: int,
                   quick: bool = False) -> dict:
    """Steps per second of the trainer (``warm`` steps first, not timed)."""
    from spikejdd.train import TrainConfig
    from spikejdd.train.trainer import Trainer

    with tempfile.TemporaryDirectory() as tmp:
        cfg = {"online": True, "device_sim": device_sim, "workers": 0 if device_sim else workers,
               "out": tmp, "device": device, "steps": warm + steps, "eval_every": 10**9,
               "checkpoint_every": 10**9, "progress": False, **(QUICK_TRAIN if quick else TRAIN)}
        tr = Trainer(TrainConfig.from_dict(cfg))
        batches = tr.batches()
        for _ in range(warm):
            tr.step(next(batches))
        _sync(device)
        t0 = time.perf_counter()
        for _ in range(steps):
            tr.step(next(batches))
        _sync(device)
        dt = time.perf_counter() - t0
        if hasattr(batches, "close"):
            batches.close()
    return {"device_sim": device_sim, "workers": 0 if device_sim else workers, "steps": steps,
            "steps_s": steps / dt}


def first_step_seconds(device: str, quick: bool = False) -> dict:
    """A fresh ``spikejdd train --online --device-sim --steps 1``: wall seconds to its
    exit (the end-of-run validation included), and the set-up it records (from the
    call of ``train`` to the first batch: model, validation sweep, first batch).
    ``quick``: the lite model and a small sweep."""
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-m", "spikejdd.cli", "train", "--online", "--device-sim",
               "--steps", "1", "--device", device, "--out", f"{tmp}/run", "--quiet",
               "--eval-every", "1000000", "--checkpoint-every", "1000000"]
        if quick:
            cfg = dict(QUICK_TRAIN, val_size=[12, 12], val_speeds=[0.0, 3000.0],
                       val_levels=["GN10"], bench_methods=["tfp+bilinear"])
            Path(f"{tmp}/cfg.json").write_text(json.dumps(cfg))
            cmd += ["--config", f"{tmp}/cfg.json"]
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        run = json.loads(Path(f"{tmp}/run/run.json").read_text())
    return {"wall_s_to_exit": wall, "setup_s": 60 * run["setup_minutes"],
            "command": " ".join(cmd[1:]).replace(tmp, "TMP")}


def _fmt(mrr, digits=3) -> str:
    m, lo, hi = mrr
    return f"{m:.{digits}g} | {lo:.{digits}g}–{hi:.{digits}g}"


def report(res: dict) -> str:
    lines = [f"# Torch backend against the numba kernel ({res['device']})", "",
             f"Machine: {res['machine']}. Command: `{res['command']}`.", "",
             "`spikesim.simulate`, RGGB, paper GN σ = 10, moving scene (1 px per 16 readouts), "
             f"pixel-readouts/s, median and range of {res['repeats']} alternating runs; "
             "bits compared on the same input, same run.", "",
             "| size | readouts | torch px·readouts/s | range | numba px·readouts/s | range "
             "| torch / numba | range | bit-identical |",
             "|---|---:|---:|---|---:|---|---:|---|---|"]
    for r in res["simulation"]:
        lines.append(f"| {r['size']} | {r['readouts']} | {_fmt(r['torch_px_readouts_s'])} | "
                     f"{_fmt(r['numba_px_readouts_s'])} | {_fmt(r['torch_over_numba'])} | "
                     f"{'yes' if r['bit_identical'] else 'NO'} |")
    big = [r for r in res["simulation"] if r["size"] == "1000x1000"]
    if big:
        rate = big[0]["torch_px_readouts_s"][0]
        lines += ["", f"1000 × 1000 at 20 kHz needs {REAL_TIME:.0e} pixel-readouts/s: the torch "
                  f"backend on {res['device']} runs at {rate / REAL_TIME:.3g} × real time."]
    if res.get("training"):
        t = res["training_settings"]
        lines += ["", f"Training (SJDD-Net {t['model']}, batch {t['batch_size']}, "
                  f"{t['crop']} × {t['crop']} crops), steps/s:", "",
                  "| data | loader processes | steps/s |", "|---|---:|---:|"]
        for t in res["training"]:
            kind = "device simulation" if t["device_sim"] else "simulation in the loader"
            lines.append(f"| {kind} | {t['workers']} | {t['steps_s']:.3g} |")
    if res.get("first_step"):
        f = res["first_step"]
        lines += ["", f"Fresh process to the first training step with device simulation: "
                  f"{f['setup_s']:.1f} s of set-up in `train`, {f['wall_s_to_exit']:.1f} s from "
                  f"launch to exit (`{f['command']}`)."]
    if not res["device"].startswith("cuda"):
        lines += ["", "No GPU was lent for this run: the GPU table (`--device cuda --train`) "
                  "is still to be measured."]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--device", default="cpu", help="torch device of the torch backend")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--quick", action="store_true", help="small sizes, nothing written")
    p.add_argument("--train", action="store_true",
                   help="also time training with device simulation and with loader processes")
    p.add_argument("--workers", type=int, default=14, help="loader processes to compare with")
    p.add_argument("--train-steps", type=int, default=30)
    args = p.parse_args(argv)
    res = {"device": args.device, "repeats": args.repeats, "machine": machine.describe(),
           "command": machine.command_line(__file__, argv), "simulation": []}
    for side, n in (QUICK_SIZES if args.quick else SIZES):
        row = simulation_case(side, n, args.device, args.repeats)
        res["simulation"].append(row)
        print(json.dumps(row), flush=True)
    if args.train:
        steps = 3 if args.quick else args.train_steps
        res["training"] = [training_steps(args.device, True, 0, steps, 2, args.quick),
                           training_steps(args.device, False, args.workers, steps, 2, args.quick)]
        res["training_settings"] = QUICK_TRAIN if args.quick else TRAIN
        res["first_step"] = first_step_seconds(args.device, args.quick)
    res["machine"] = machine.describe()  # with the load at the end
    text = report(res)
    print(text)
    if not args.quick:
        name = "torch" if not args.device.startswith("cuda") else "torch_cuda"
        RESULTS.mkdir(exist_ok=True)
        (RESULTS / f"{name}.json").write_text(json.dumps(res, indent=1))
        (RESULTS / f"{name}.md").write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
