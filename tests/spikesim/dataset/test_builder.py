"""Dataset builder: manifests, determinism across executors, failures, resume, dry run."""

from __future__ import annotations

import sys
import textwrap
import warnings

import numpy as np
import pytest

from spikesim.dataset import (
    build_dataset,
    builtin_manifest_path,
    builtin_manifests,
    derive_seed,
    estimate_dataset,
    load_manifest,
    parse_manifest,
    plan_tasks,
)
from spikesim.errors import SpikeSimFileError, SpikeSimValueError
from spikesim.io import open_dataset
from tests.support.dataset_helpers import assert_same_files


def small_manifest(count=3, size=(24, 40), extra_sources=(), **dataset):
    return {
        "dataset": {"name": "t", "seed": 5, "size": list(size), "window": 9,
                    "samples_per_sequence": 2, **dataset},
        "sensor": {"preset": "ideal"},
        "noise": [
            {"mode": "paper", "label": "GN", "sigma_g": {"uniform": [0, 15]}},
            {"mode": "paper", "label": "GPN", "sigma_g": {"uniform": [0, 5]},
             "sigma_p": {"uniform": [0, 5]}},
        ],
        "sources": [{"kind": "procedural", "scenes": ["astronaut", "coffee"],
                     "motions": ["pan", "zoom"], "speed": {"uniform": [100, 2000]},
                     "count": count, "split": "train"},
                    *extra_sources],
    }


def test_builtin_manifests_validate_and_plan():
    names = builtin_manifests()
    assert {"demo", "sjdd-train-small", "sjdd-eval-object", "sjdd-eval-camera"} <= set(names)
    for name in names:
        if "${" in builtin_manifest_path(name).read_text():
            continue  # needs dataset roots: test_sjdd_paper.py makes them
        m = load_manifest(f"builtin:{name}")
        tasks = plan_tasks(m)
        assert tasks and len({t.file for t in tasks}) == len(tasks)
        assert all(t.n_readouts == m.window * m.samples_per_sequence for t in tasks)
        # GT at the centre of each window
        assert tasks[0].gt_readouts[0] == m.window // 2


def test_seeds_are_derived_from_global_seed_and_id():
    m = parse_manifest(small_manifest(count=4))
    tasks = plan_tasks(m)
    assert [t.seed for t in tasks] == [derive_seed(5, f"{t.split}/{t.id}") for t in tasks]
    # a sequence keeps its seed and parameters when the dataset grows
    bigger = plan_tasks(parse_manifest(small_manifest(count=9)))
    for t in tasks:
        same = next(b for b in bigger if b.id == t.id)
        assert same.seed == t.seed and same.sensor == t.sensor and same.scene == t.scene
    noise = {t.noise_label for t in bigger}
    assert noise == {"GN", "GPN"}


def test_serial_pool_and_dask_give_identical_files(tmp_path):
    m = parse_manifest(small_manifest(count=4))
    s1 = build_dataset(m, tmp_path / "serial", workers=1, progress=False)
    assert s1.done == 4 and s1.failed == 0
    s2 = build_dataset(m, tmp_path / "pool", workers=2, progress=False)
    assert s2.done == 4 and s2.failed == 0
    s3 = build_dataset(m, tmp_path / "dask", dask_local=2, progress=False)
    assert s3.done == 4 and s3.failed == 0 and "dask" in s3.executor
    assert_same_files(tmp_path / "serial", tmp_path / "pool")
    assert_same_files(tmp_path / "serial", tmp_path / "dask")
    ds = open_dataset(tmp_path / "serial" / "train")
    assert len(ds) == 4
    seq = ds.sequence(ds.names[0])
    assert seq.n_readouts == 18 and list(seq.gt_index) == [4, 13]
    assert seq.meta["dataset"]["manifest"] == "t"


FACTORY = textwrap.dedent(
    """
    import multiprocessing
    import os
    from pathlib import Path
    import numpy as np
    from spikesim.scenes import Static

    MARKER = Path(__file__).with_name("killed.marker")

    class Killer(Static):
        def radiance(self, t):
            # only ever kill a worker process, never the process running the tests
            in_worker = multiprocessing.parent_process() is not None
            if in_worker and not MARKER.exists():
                MARKER.write_text("killed once")
                os._exit(3)   # the worker dies mid-sequence, its file half written
            return super().radiance(t)

    def make(index, size, seed, mode="ok"):
        img = np.full(tuple(size) + (3,), 0.1 + 0.1 * index, np.float32)
        if mode == "raise" and index == 1 or mode == "raise_all":
            raise RuntimeError("injected failure")
        if mode == "kill" and index == 2:
            return Killer(img)
        return Static(img)
    """
)


@pytest.fixture()
def factory_module(tmp_path, monkeypatch):
    mod = tmp_path / "mods"
    mod.mkdir()
    (mod / "inject_scenes.py").write_text(FACTORY)
    monkeypatch.syspath_prepend(str(mod))
    # a module imported by an earlier test (from its own tmp_path) must not be reused
    monkeypatch.delitem(sys.modules, "inject_scenes", raising=False)
    yield mod
    sys.modules.pop("inject_scenes", None)


def _py_source(mode, count=4):
    return {"kind": "python", "factory": "inject_scenes:make", "count": count,
            "options": {"mode": mode}, "split": "inj"}


def test_failing_sequence_is_reported_and_rerun_completes(tmp_path, factory_module):
    m = parse_manifest(small_manifest(count=1, extra_sources=[_py_source("raise")]))
    out = tmp_path / "out"
    s = build_dataset(m, out, workers=1, progress=False)
    assert s.failed == 1 and s.done == 4
    assert "injected failure" in s.failures[0]["error"]
    assert not (out / s.failures[0]["file"]).exists()
    # the next run (failure fixed) redoes only what is missing
    m2 = parse_manifest(small_manifest(count=1, extra_sources=[_py_source("ok")]))
    s2 = build_dataset(m2, out, workers=1, progress=False)
    assert s2.done == 4 and s2.skipped == 1 and s2.failed == 0


def test_build_whose_every_sequence_fails_raises(tmp_path, factory_module, capsys):
    """Every sequence failing used to return a summary (a script went on, exit status 0):
    it raises, with the summary attached and written; the command line still lists the
    failures and exits 1."""
    import json

    from spikesim.cli import main
    from spikesim.dataset import BuildFailedError

    data = small_manifest()
    data["sources"] = [_py_source("raise_all", count=2)]
    out = tmp_path / "out"
    with pytest.raises(BuildFailedError, match=r"every sequence this build ran failed \(2; the "
                       r"first, inj/.*: RuntimeError: injected failure\)") as err:
        build_dataset(parse_manifest(data), out, progress=False)
    assert err.value.summary.failed == 2 and err.value.summary.done == 0
    assert json.loads((out / "build_summary.json").read_text())["failed"] == 2
    capsys.readouterr()
    toml = tmp_path / "m.toml"
    toml.write_text('[dataset]\nname = "t"\nsize = [24, 40]\nwindow = 9\n'
                    '[[sources]]\nkind = "python"\nfactory = "inject_scenes:make"\ncount = 2\n'
                    'split = "inj"\noptions = {mode = "raise_all"}\n')
    assert main(["dataset", str(toml), "--out", str(tmp_path / "cli"), "--quiet"]) == 1
    cap = capsys.readouterr()
    assert "done 0, skipped 0, failed 2" in cap.out and "error" not in cap.err
    assert cap.out.count("injected failure") >= 2


def test_nothing_to_build_says_so(tmp_path, capsys):
    """A re-run that finds every sequence made starts no executor and says so (it said
    "serial" whatever --workers asked for), drawing no empty progress bar."""
    m = parse_manifest(small_manifest(count=2))
    build_dataset(m, tmp_path / "ds", progress=False)
    capsys.readouterr()
    assert build_dataset(m, tmp_path / "ds", progress=True).executor == "nothing to build"
    assert "seq" not in capsys.readouterr().err
    for kw in ({"workers": 2}, {"dask_local": 2}, {}):
        again = build_dataset(m, tmp_path / "ds", progress=False, **kw)
        assert (again.done, again.skipped, again.failed) == (0, 2, 0)
        assert again.executor == "nothing to build"
        assert again.line() == ("done 0, skipped 2, failed 0: nothing to build (every sequence "
                                "is already made)")
    est = estimate_dataset(m, workers=2, out_dir=tmp_path / "ds")
    assert est["to_make"] == 0 and est["executor"] == "nothing to build"


@pytest.mark.parametrize("inside", ["train", "train/deeper", "other"])
def test_out_inside_an_existing_dataset_is_refused(tmp_path, inside, capsys):
    """``--out ds/train`` nested a new dataset in a split folder: a folder inside an
    existing dataset is refused, naming the root to give, before anything is written."""
    from spikesim.cli import main

    m = parse_manifest(small_manifest(count=1))
    build_dataset(m, tmp_path / "ds", progress=False)
    before = sorted(tmp_path.rglob("*"))
    with pytest.raises(SpikeSimValueError, match=r"out_dir='.*' is invalid: expected a folder "
                       r"outside the dataset at '.*ds' \(it lies inside it\): give that root"):
        build_dataset(m, tmp_path / "ds" / inside, progress=False)
    with pytest.raises(SpikeSimValueError, match="outside the dataset"):
        estimate_dataset(m, out_dir=tmp_path / "ds" / inside)
    assert sorted(tmp_path.rglob("*")) == before
    capsys.readouterr()
    target = tmp_path / "ds" / inside
    assert main(["dataset", "builtin:demo", "--out", str(target), "--limit", "1"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"spikesim dataset: error: --out={str(target)!r} is invalid")
    assert "\n" not in err
    assert sorted(tmp_path.rglob("*")) == before


def test_out_holding_sequence_files_is_refused(tmp_path):
    """A folder of sequence files that is not a dataset root (a split folder copied
    elsewhere, say) is refused too; the dataset root itself is taken as it is."""
    import shutil

    m = parse_manifest(small_manifest(count=1))
    build_dataset(m, tmp_path / "ds", progress=False)
    shutil.copytree(tmp_path / "ds" / "train", tmp_path / "copy")
    with pytest.raises(SpikeSimValueError, match=r"out_dir=.* not a folder of sequence files"):
        build_dataset(m, tmp_path / "copy", progress=False)
    assert build_dataset(m, tmp_path / "ds", progress=False).skipped == 1


def test_killed_worker_loses_nothing(tmp_path, factory_module):
    """A worker dies once mid-sequence: the tasks its pool held run again, alone, and
    every sequence completes (a worker that always dies: tests/faults/test_kill.py)."""
    m = parse_manifest(small_manifest(count=2, extra_sources=[_py_source("kill")]))
    out = tmp_path / "out"
    s = build_dataset(m, out, workers=2, progress=False)
    assert (factory_module / "killed.marker").exists()  # a worker did die
    assert s.failed == 0 and s.done == 6
    assert not [p for p in (out / "inj").iterdir() if p.name.startswith(".")]  # temps gone
    assert len(open_dataset(out / "inj")) == 4
    s2 = build_dataset(m, out, workers=2, progress=False)
    assert s2.failed == 0 and s2.skipped == 6


def test_result_lost_with_the_pool_but_file_complete_counts_as_done(tmp_path):
    """A sequence can finish in a surviving worker just as the pool breaks; its
    file is then complete although its result is lost: it must not be reported failed."""
    from concurrent.futures.process import BrokenProcessPool

    from spikesim.dataset.build import _lost
    from spikesim.dataset.worker import run_task

    task = plan_tasks(parse_manifest(small_manifest(count=1)))[0].to_dict()
    lost = _lost(task, BrokenProcessPool("worker process died"), tmp_path)
    assert lost["status"] == "failed" and "BrokenProcessPool" in lost["error"]
    assert run_task(task, str(tmp_path))["status"] == "done"
    rec = _lost(task, BrokenProcessPool("worker process died"), tmp_path)
    assert rec["status"] == "done" and rec["error"] is None
    assert rec["bytes"] == (tmp_path / task["file"]).stat().st_size
    h, w = task["sensor"]["height"], task["sensor"]["width"]
    assert rec["px_readouts"] == task["n_readouts"] * h * w
    (tmp_path / task["file"]).write_bytes(b"truncated")  # a damaged file is not "done"
    assert _lost(task, BrokenProcessPool("x"), tmp_path)["status"] == "failed"


def test_interrupted_build_counts_and_indexes_files_finished_unreported(tmp_path, monkeypatch):
    """Stopped (Ctrl-C, SIGTERM) after a worker finished a file it had not reported
    yet (a pool batch reports when all of it is made): the summary counts the
    file as done and the split's index lists it, as a re-run would find it."""
    import json

    from spikesim.dataset import build

    real = build.run_task
    made = []

    def finish_then_stop(task, out, *args):
        record = real(task, out, *args)
        made.append(task["file"])
        if len(made) == 2:
            raise KeyboardInterrupt  # the second file is complete, its record lost
        return record

    monkeypatch.setattr(build, "run_task", finish_then_stop)
    manifest = parse_manifest(small_manifest(count=4))
    with pytest.raises(KeyboardInterrupt):
        build_dataset(manifest, tmp_path / "ds", workers=1, progress=False)
    summary = json.loads((tmp_path / "ds" / "build_summary.json").read_text())
    assert "interrupted" in summary["executor"] and summary["done"] == 2
    assert {r["file"] for r in summary["records"]} == set(made)
    index = json.loads((tmp_path / "ds" / "train" / "index.json").read_text())
    assert len(index["sequences"]) == 2


def test_interrupted_build_says_what_it_kept(tmp_path, monkeypatch, capsys):
    """With progress shown, a stopped build says on stderr how many sequences
    it kept and that the same build makes the rest."""
    from spikesim.dataset import build

    real = build.run_task
    made = []

    def stop_at_third(task, out, *args):
        if len(made) == 2:
            raise KeyboardInterrupt
        made.append(task["file"])
        return real(task, out, *args)

    monkeypatch.setattr(build, "run_task", stop_at_third)
    manifest = parse_manifest(small_manifest(count=5))
    with pytest.raises(KeyboardInterrupt):
        build_dataset(manifest, tmp_path / "ds", workers=1, progress=True)
    err = capsys.readouterr().err
    assert f"stopped: 2 of 5 sequences to make were finished and kept in {tmp_path / 'ds'}" in err
    assert err.rstrip().endswith("makes the other 3")  # no bar drawn again after it


@pytest.mark.parametrize(
    "mutate,where",
    [
        (lambda d: d["dataset"].update(size=[0, 10]), "dataset.size[0]"),
        (lambda d: d["dataset"].update(windw=3), "dataset.windw"),
        (lambda d: d["noise"][0].update(sigma_g={"uniform": [0, 300]}), "noise[0].sigma_g"),
        (lambda d: d["noise"][0].update(sigma_g={"gauss": [0, 3]}), "noise[0].sigma_g"),
        (lambda d: d["noise"][1].update(mode="pink"), "noise[1].mode"),
        (lambda d: d["sources"][0].update(scenes=["marsrover"]), "sources[0].scenes"),
        (lambda d: d["sources"][0].update(motions=["wobble"]), "sources[0].motions"),
        (lambda d: d["sources"][0].update(count=0), "sources[0].count"),
        (lambda d: d["sources"][0].update(kind="reds", path="/no/such/reds"), "sources[0]"),
        (lambda d: d["sensor"].update(clock_hz=-5), "clock_hz"),
        (lambda d: d["sensor"].update(preset="vidar-9000"), "preset"),
    ],
)
def test_manifest_errors_name_the_key(mutate, where):
    d = small_manifest()
    mutate(d)
    with pytest.raises(SpikeSimValueError) as info:
        parse_manifest(d)
    assert where in str(info.value)


def test_missing_manifest_file_and_bad_toml(tmp_path):
    with pytest.raises(SpikeSimFileError):
        load_manifest(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[dataset\nname=")
    with pytest.raises(SpikeSimValueError, match="TOML"):
        load_manifest(bad)
    with pytest.raises(SpikeSimValueError, match="builtin"):
        load_manifest("builtin:nothing")


def test_dry_run_estimates_disk_within_25_percent(tmp_path):
    m = parse_manifest(small_manifest(count=6, size=(48, 64)))
    est = estimate_dataset(m, calibration_tasks=2)
    s = build_dataset(m, tmp_path / "out", progress=False)
    assert est["sequences"] == 6 and s.done == 6
    assert abs(est["estimated_bytes"] / s.bytes - 1) < 0.25


def test_video_sources_are_listed_from_a_reds_root(tmp_path):
    import cv2

    root = tmp_path / "reds"
    for seq in ("000", "001"):
        (root / seq).mkdir(parents=True)
        for k in range(3):
            img = np.full((20, 30, 3), 40 * (k + 1), np.uint8)
            cv2.imwrite(str(root / seq / f"{k:08d}.png"), img)
    d = small_manifest()
    d["sources"] = [{"kind": "reds", "path": str(root), "fps": 120, "split": "v"}]
    m = parse_manifest(d)
    tasks = plan_tasks(m)
    assert [t.scene["sequence"] for t in tasks] == ["000", "001"]
    s = build_dataset(m, tmp_path / "out", progress=False)
    assert s.done == 2, s.failures


def test_cli_dry_run_prints_json_alone_on_stdout(tmp_path, capsys):
    """`spikesim dataset --dry-run` writes only the JSON estimate to stdout (a script can
    json.load it); the one-line plan for people goes to stderr."""
    import json

    from spikesim.cli import main

    toml = tmp_path / "m.toml"
    toml.write_text('[dataset]\nname = "t"\nseed = 5\nsize = [24, 40]\nwindow = 9\n'
                    'samples_per_sequence = 2\n[sensor]\npreset = "ideal"\n'
                    '[[noise]]\nmode = "paper"\nlabel = "GN"\nsigma_g = 5\n'
                    '[[sources]]\nkind = "procedural"\nscenes = ["astronaut"]\n'
                    'motions = ["pan"]\ncount = 2\nsplit = "train"\n')
    assert main(["dataset", str(toml), "--dry-run"]) == 0
    cap = capsys.readouterr()
    assert json.loads(cap.out)["sequences"] == 2
    assert cap.err.startswith("plan: 2 sequences")
    assert main(["dataset", str(toml), "--dry-run", "--scheduler", "tcp://127.0.0.1:1"]) == 0
    assert "does not contact the scheduler" in capsys.readouterr().err


def test_files_the_plan_no_longer_makes_are_warned_about(tmp_path):
    """A manifest edited to make fewer sequences leaves the earlier build's extra files
    in the split folder, where they are indexed: the build says so."""
    out = tmp_path / "ds"
    build_dataset(parse_manifest(small_manifest(count=3)), out, progress=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        build_dataset(parse_manifest(small_manifest(count=3)), out, progress=False)  # same
    with pytest.warns(UserWarning, match=r"1 sequence file\(s\) in .* not in this manifest's "
                                         r"plan \(train/.*\.h5\).*--prune"):
        build_dataset(parse_manifest(small_manifest(count=2)), out, progress=False)
    import json

    from spikesim.io import verify_file

    planned = {t["file"] for t in json.loads((out / "plan.json").read_text())["tasks"]}
    leftover, = [p for p in (out / "train").glob("*.h5") if f"train/{p.name}" not in planned]

    leftover.write_bytes(leftover.read_bytes()[:100])  # damaged: verify says how to be rid of it
    report = verify_file(leftover)
    assert "not in the plan of its last build" in report["advice"]
    with pytest.raises(SpikeSimValueError, match="prune=True is invalid.*limit"):
        build_dataset(parse_manifest(small_manifest(count=2)), out, progress=False,
                      prune=True, limit=1)
    build_dataset(parse_manifest(small_manifest(count=2)), out, progress=False, prune=True)
    assert len(list((out / "train").glob("*.h5"))) == 2
    assert len(open_dataset(out / "train")) == 2
