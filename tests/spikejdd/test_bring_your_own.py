"""Bring your own method: module:function, entry points, torch modules and sjdd@checkpoint,
benchmarked from the CLI next to built-ins on a 39-readout dataset; windows that never trip."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import numpy as np
import pytest

import spikejdd as sj
import spikesim as ss
from spikejdd.cli import main
from spikejdd.registry import METHODS, MethodError, Registry
from spikesim.errors import SpikeSimValueError
from spikesim.io import write_h5

USER_MODULE = '''
import numpy as np

def grey_tfp(spikes, cfa, center):
    """Mean firing rate of the whole window as grey (test method)."""
    level = spikes.mean(axis=0, dtype=np.float64) / 0.6
    return np.repeat(level[..., None], 3, axis=-1)
'''

PLUGIN_MODULE = '''
import numpy as np

def half_grey(spikes, cfa, center, rate=0.6):
    """Half grey everywhere (entry-point test method)."""
    return np.full(spikes.shape[1:] + (3,), 0.5)
'''


@pytest.fixture(scope="module")
def data39(tmp_path_factory):
    """Three 39-readout sequences (GT at readout 19): GN5 pan, GPN zoom, noise-free fan."""
    d = tmp_path_factory.mktemp("d39")
    specs = [("astronaut", "pan", ss.noise.PaperNoise(sigma_g=5.0, sigma_p=0.0)),
             ("coffee", "zoom", ss.noise.PaperNoise(sigma_g=2.0, sigma_p=1.0)),
             ("fan", None, None)]
    for i, (name, motion, noise) in enumerate(specs):
        sensor = ss.Sensor(height=16, width=24, cfa="RGGB", noise=noise)
        scene = ss.scenes.procedural(name, motion=motion, size=(16, 24))
        write_h5(d / f"{name}.h5", ss.simulate(scene, sensor, n_readouts=39, seed=i,
                                               gt_readouts=[19]))
    return d


@pytest.fixture
def user_package(tmp_path, monkeypatch):
    pkg = tmp_path / "usermeth"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "recon.py").write_text(USER_MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    yield "usermeth.recon:grey_tfp"
    for name in ("usermeth", "usermeth.recon"):
        sys.modules.pop(name, None)


@pytest.fixture
def entry_point(tmp_path, monkeypatch):
    """A distribution declaring ``spikejdd.methods`` found by importlib.metadata (no pip)."""
    root = tmp_path / "site"
    root.mkdir()
    (root / "plugmod.py").write_text(PLUGIN_MODULE)
    info = root / "spikejdd_testplug-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: spikejdd-testplug\n"
                                   "Version: 1.0\n")
    (info / "entry_points.txt").write_text("[spikejdd.methods]\nplug-half = plugmod:half_grey\n")
    monkeypatch.syspath_prepend(str(root))
    METHODS.reload_entry_points()
    yield "plug-half"
    monkeypatch.undo()
    sys.modules.pop("plugmod", None)
    METHODS.reload_entry_points()


@pytest.fixture(scope="module")
def checkpoint(data39, tmp_path_factory):
    """best.pt of a 2-step training run of a tiny SJDD-Net on the 39-readout data."""
    from spikejdd.train import TrainConfig, train
    from tests.support.sjdd_helpers import TINY

    out = tmp_path_factory.mktemp("run")
    summary = train(TrainConfig.from_dict(dict(
        data=str(data39), out=str(out), model="lite", model_overrides=TINY.to_dict(), steps=2,
        batch_size=2, crop=12, eval_every=100, eval_frames=2, checkpoint_every=100,
        progress=False, seed=3, threads=1)))
    assert summary["steps_done"] == 2
    return out / "best.pt"


def test_readme_example_uses_the_largest_window_that_fits():
    sensor = ss.Sensor(height=16, width=16, cfa="RGGB")
    stream = ss.simulate(ss.scenes.procedural("astronaut", motion="pan", size=(16, 16)),
                         sensor, n_readouts=520, seed=0)
    spikes = stream.unpack()[480:519]
    img = sj.reconstruct(spikes, cfa="RGGB", method="tfp+malvar2004", center=19)
    same = sj.reconstruct(spikes, cfa="RGGB", method="tfp39+malvar2004", center=19)
    np.testing.assert_array_equal(img, same)
    assert sj.get_method("tfp+malvar2004").window_for(39) == 39
    assert sj.get_method("tfp+malvar2004").window_for(100) == 41
    with pytest.raises(SpikeSimValueError, match="window=41.*39 readouts"):
        sj.reconstruct(spikes, cfa="RGGB", method="tfp41+malvar2004", center=19)
    # a centre near the end: the 39-readout window is shifted inside, not shortened
    np.testing.assert_array_equal(sj.baselines.tfp(spikes, 38), sj.baselines.tfp(spikes, 0))


def test_registry_object_register_get_names():
    reg = Registry("test")

    @reg.register(name="zeros")
    def zeros(spikes, cfa, center):
        """All black."""
        return np.zeros(spikes.shape[1:] + (3,))

    assert reg.names() == ["zeros"] and reg.describe()["zeros"] == "All black."
    m = reg.get("zeros")
    spikes = np.zeros((5, 4, 6), np.uint8)
    # rate/device/threads reach a method only if it declares them
    assert m(spikes, "RGGB", 2, rate=0.5, device="cpu").shape == (4, 6, 3)
    with pytest.raises(SpikeSimValueError, match="options"):
        m(spikes, "RGGB", 2, level=3)
    assert reg.get("tfp+bilinear").window_for(10) == 10
    with pytest.raises(SpikeSimValueError, match="already registered"):
        reg.register(zeros, name="zeros")
    with pytest.raises(SpikeSimValueError, match="package.module:function"):
        reg.get("nope")
    with pytest.raises(SpikeSimValueError, match="importable.*on the import path.*PYTHONPATH"):
        reg.get("no_such_pkg.mod:fn")
    with pytest.raises(SpikeSimValueError, match="takes weights"):
        reg.get("zeros@w.pt")


def test_no_import_circle_between_registry_and_models():
    import ast
    from pathlib import Path

    root = Path(sj.__file__).parent
    for path in (root / "models").glob("*.py"):
        tree = ast.parse(path.read_text())
        mods = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
        mods |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
        assert "spikejdd.registry" not in mods and "spikejdd" not in mods, path.name
    reg_tree = ast.parse((root / "registry.py").read_text())
    assert not any(isinstance(n, ast.ImportFrom) and (n.module or "").startswith(
        "spikejdd.models") and n.col_offset == 0 for n in reg_tree.body)


def test_user_function_and_torch_module(user_package, data39):
    import torch

    from spikejdd.models import TorchMethod, model_inputs

    spikes = ss.io.open_h5(data39 / "fan.h5").read_window(0, 39)
    out = sj.reconstruct(spikes, "RGGB", user_package, center=19)
    np.testing.assert_allclose(out[..., 0], spikes.mean(0) / 0.6)

    class Mean(torch.nn.Module):
        def forward(self, spikes, mask):
            assert spikes.shape == (1, 9, 16, 24) and mask.shape == (1, 4, 16, 24)
            assert torch.equal(mask.sum(1), torch.ones(1, 16, 24))
            return spikes.mean(1, keepdim=True).expand(-1, 3, -1, -1) / 0.6

    method = TorchMethod(Mean(), window=9)
    sj.register_method("test-mean-net", method)
    try:
        got = sj.reconstruct(spikes, "RGGB", "test-mean-net", center=19)
        x, m = model_inputs(spikes, "RGGB", 19, 9)
        np.testing.assert_array_equal(x[0].numpy(), spikes[15:24])
        np.testing.assert_allclose(got[..., 1], np.clip(spikes[15:24].mean(0) / 0.6, 0, 1),
                                   atol=1e-6)
        assert sj.get_method("test-mean-net").window_for(39) == 9
        with pytest.raises(SpikeSimValueError, match="at least 9 readouts"):
            sj.reconstruct(spikes[:5], "RGGB", "test-mean-net")
        with pytest.raises(SpikeSimValueError, match="cfa"):
            sj.reconstruct(spikes, None, "test-mean-net")
    finally:
        sj.unregister_method("test-mean-net")


def test_cli_benchmarks_user_entry_point_and_checkpoint_beside_builtins(
        data39, user_package, entry_point, checkpoint, tmp_path, capsys):
    methods = ["tfp+malvar2004", "tfi+bilinear", user_package, entry_point,
               f"sjdd@{checkpoint}"]
    out = tmp_path / "rep"
    rc = main(["evaluate", "--data", str(data39), "--methods", ",".join(methods),
               "--repeats", "1", "--out", str(out), "--quiet", "--threads", "1"])
    assert rc == 0, capsys.readouterr().err
    res = json.loads(out.with_suffix(".json").read_text())
    assert list(res["summary"]) == methods
    for m in methods:
        assert res["summary"][m]["all"]["frames"] == 3
    # the entry point's constant half grey and the user's mean are what was scored
    assert res["summary"][entry_point]["all"]["windows"] == []
    assert res["summary"]["tfp+malvar2004"]["all"]["windows"] == [39]
    assert res["summary"][f"sjdd@{checkpoint}"]["all"]["windows"] == [9]  # from the checkpoint
    md = out.with_suffix(".md").read_text()
    assert "2-core AMD EPYC VM" not in md
    from spikejdd.runtime import machine_info

    info = machine_info()
    assert f"Machine: {info['cpu_model']}; {info['logical_cpus']} logical CPUs" in md
    assert "GPU:" in md and "torch threads per process: 1" in md
    assert "## By noise label" in md and "| method | GN5 | GPN | none |" in md
    assert "## By motion" in md and "pan" in md and "zoom" in md
    panels = sorted((tmp_path / "rep_panels").glob("*.png"))
    assert len(panels) == 3 and all(f"rep_panels/{p.name}" in md for p in panels)
    import cv2

    img = cv2.imread(str(panels[0]))
    assert img.shape[1] > 6 * 96  # GT + 5 methods, each enlarged to >= 96 px
    assert out.with_suffix(".png").read_bytes()[:4] == b"\x89PNG"
    # per method, PSNR against time in the JSON behind the plot
    for m in methods:
        e = res["summary"][m]["all"]
        assert e["ms_per_frame"] > 0 and np.isfinite(e["PSNR[linear]"])


def test_cli_one_line_errors(data39, tmp_path, capsys):
    args = ["evaluate", "--data", str(data39), "--out", str(tmp_path / "x"), "--quiet"]
    assert main(args + ["--methods", "sjdd", "--device", "cuda:7"]) == 1
    err = capsys.readouterr().err.strip()
    assert "cuda:7" in err and "use cpu" in err and len(err.splitlines()) == 1
    assert main(args + ["--methods", "sjdd@no/such/best.pt"]) == 1
    assert "no/such/best.pt" in capsys.readouterr().err
    assert main(args + ["--methods", "tfp41+bilinear"]) == 1
    assert "window=41" in capsys.readouterr().err
    assert main(args + ["--methods", "nosuchmod.x:fn"]) == 1
    assert "nosuchmod" in capsys.readouterr().err
    assert main(args + ["--methods", "tfp+bilinear", "--panels", "-1"]) == 1
    assert "--panels=-1 is invalid" in capsys.readouterr().err
    assert not (tmp_path / "x.md").exists()


def test_reconstruct_dat_capture_writes_side_by_side_panels(tmp_path, capsys):

    import cv2

    from tests.support.fixture_paths import PEER_REDS

    dat = PEER_REDS / "203_part2_key_id151.dat"
    if not dat.is_file():
        pytest.skip("peer fixture not available")
    out = tmp_path / "frames"
    rc = main(["reconstruct", str(dat), "--cfa", "mono", "--methods",
               "tfp+bilinear,tfp21+bilinear", "--centers", "150", "--out", str(out), "--quiet"])
    assert rc == 0, capsys.readouterr().err
    text = capsys.readouterr().out
    assert "tfp+bilinear: 41 readouts used" in text and "tfp21+bilinear: 21 readouts" in text
    panel = cv2.imread(str(out / "203_part2_key_id151_panel_000150.png"))
    single = cv2.imread(str(out / "203_part2_key_id151_tfp_bilinear_000150.png"))
    assert single.shape == (250, 400, 3)
    assert panel.shape[1] == 2 * 400 + 2 and panel.shape[0] > 250
    np.testing.assert_array_equal(panel[-250:, :400], single)
    # a .dat records no colour filter: mono by default, as spikesim reads it; a colour
    # method then says how to give the pattern
    mono = tmp_path / "mono"
    assert main(["reconstruct", str(dat), "--methods", "tfp+bilinear", "--centers", "150",
                 "--out", str(mono), "--quiet"]) == 0
    grey = cv2.imread(str(mono / "203_part2_key_id151_tfp_bilinear_000150.png"))
    assert (grey[..., 0] == grey[..., 1]).all() and (grey[..., 1] == grey[..., 2]).all()
    assert "records no colour filter: read as monochrome" in capsys.readouterr().err
    assert main(["reconstruct", str(dat), "--methods", "sjdd", "--centers", "150",
                 "--out", str(tmp_path / "no"), "--quiet"]) == 1
    assert "give --cfa RGGB" in capsys.readouterr().err


def test_demo_checks_the_device_before_any_work(tmp_path, capsys):
    from spikejdd.cli import main as spikejdd_main

    out = tmp_path / "demo"
    assert spikejdd_main(["demo", "--out", str(out), "--size", "32", "--limit", "1",
                          "--device", "cuda:7"]) != 0
    err = capsys.readouterr().err.strip()
    assert "cuda:7" in err and len(err.splitlines()) == 1
    assert not (out / "demo").exists()


FAILING_MODULE = '''
import numpy as np

def boom(spikes, cfa, center):
    raise RuntimeError("boom inside my method")

def needs_gain(spikes, cfa, center, gain):
    return np.zeros(spikes.shape[1:] + (3,))

def nan_out(spikes, cfa, center):
    return np.full(spikes.shape[1:] + (3,), np.nan)

CALLS = []

def third_call_fails(spikes, cfa, center):
    CALLS.append(1)
    if len(CALLS) == 3:
        raise ValueError("bad frame")
    return np.full(spikes.shape[1:] + (3,), 0.5)

def third_call_wrong_shape(spikes, cfa, center):
    CALLS.append(1)
    return np.zeros((2, 2, 3) if len(CALLS) == 3 else spikes.shape[1:] + (3,))
'''


def test_a_failing_user_method_is_named_not_reported_as_a_bug(data39, tmp_path, capsys,
                                                              monkeypatch):
    (tmp_path / "failing_meth.py").write_text(FAILING_MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    args = ["evaluate", "--data", str(data39), "--out", str(tmp_path / "x"), "--quiet"]
    for fn, words in (("boom", "boom inside my method"), ("needs_gain", "gain")):
        assert main(args + ["--methods", f"tfp+bilinear,failing_meth:{fn}"]) == 1  # not 70
        err = capsys.readouterr().err.strip()
        assert f"method 'failing_meth:{fn}' failed" in err and words in err, err
        assert len(err.splitlines()) == 1 and "--debug" in err
    # the library's error names no command-line flag; the command line's adds the hint once
    with pytest.raises(MethodError, match="boom inside my method") as caught:
        sj.reconstruct(np.zeros((9, 16, 16), np.uint8), cfa="RGGB", method="failing_meth:boom")
    assert "--debug" not in str(caught.value)
    seq = str(data39 / "fan.h5")
    assert main(["reconstruct", seq, "--methods", "failing_meth:boom", "--out",
                 str(tmp_path / "frames"), "--quiet"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.endswith("boom inside my method (--debug shows the traceback)"), err
    assert err.count("--debug") == 1
    sys.modules.pop("failing_meth", None)


def test_torch_threads_set_for_methods_survive_a_later_simulation():
    """numba's OpenMP layer, started by the first simulation in a process, sets the
    OpenMP thread count torch shares: ``set_threads`` must start it first, or a sweep
    simulated after ``spikejdd evaluate`` set one thread runs SJDD-Net on all cores."""
    import subprocess

    code = ("import torch\n"
            "from spikejdd.runtime import configure\n"
            "configure('cpu', 1)\n"
            "import spikesim as ss\n"
            "ss.simulate(ss.scenes.procedural('coffee', size=(16, 16)),\n"
            "            ss.Sensor(height=16, width=16, cfa='RGGB'), n_readouts=9, seed=0)\n"
            "print(torch.get_num_threads())\n")
    env = dict(os.environ, NUMBA_NUM_THREADS="2")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=env, timeout=600, check=True).stdout
    assert out.split()[-1] == "1"


def test_unknown_weights_are_refused_before_any_method_runs(data39, tmp_path, capsys):
    from spikejdd.registry import get_method

    with pytest.raises(SpikeSimValueError, match=r"weights='sjdd-xl' is invalid: expected a "
                                                  r"shipped name \['sjdd-full', 'sjdd-lite'\]"):
        get_method("sjdd@sjdd-xl")
    with pytest.raises(SpikeSimValueError, match=r"\(shipped weights are named as "
                                                  r"sjdd@sjdd-lite\)"):
        get_method("sjdd-lite")
    assert get_method("sjdd@sjdd-lite").options == {"weights": "sjdd-lite"}
    out = tmp_path / "x"
    assert main(["evaluate", "--data", str(data39), "--out", str(out), "--quiet",
                 "--methods", "tfp+bilinear,sjdd@sjdd-xl"]) == 1
    cap = capsys.readouterr()
    assert "sjdd-xl" in cap.err and len(cap.err.strip().splitlines()) == 1
    assert "tfp+bilinear" not in cap.out and not out.with_suffix(".md").exists()


def test_evaluate_keeps_the_results_of_methods_beside_a_failing_one(data39, tmp_path, capsys,
                                                                    monkeypatch):
    """One failing method among several: the others are scored and reported, the
    failure is listed in the report and on stderr, and the exit status is 1."""
    (tmp_path / "failing_meth.py").write_text(FAILING_MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    out = tmp_path / "r" / "report"
    methods = "failing_meth:boom,tfp+bilinear,failing_meth:nan_out,tfi+bilinear"
    args = ["evaluate", "--data", str(data39), "--out", str(out), "--quiet", "--repeats", "1"]
    assert main(args + ["--methods", methods]) == 1
    cap = capsys.readouterr()
    err = cap.err.strip().splitlines()
    assert len(err) == 2 and "boom inside my method" in err[0] and "non-finite" in err[1], err
    assert all(str(out.with_suffix(".md")) in line for line in err)
    assert "tfp+bilinear" in cap.out and "tfi+bilinear" in cap.out and "boom" not in cap.out
    result = json.loads(out.with_suffix(".json").read_text())
    assert sorted(result["failed"]) == ["failing_meth:boom", "failing_meth:nan_out"]
    assert sorted(result["summary"]) == ["tfi+bilinear", "tfp+bilinear"]
    assert {r["method"] for r in result["rows"]} == {"tfi+bilinear", "tfp+bilinear"}
    md = out.with_suffix(".md").read_text()
    assert "## Methods that failed" in md and "`failing_meth:boom`: method" in md
    assert "| failing_meth:boom |" not in md and "| tfp+bilinear |" in md
    # every method failing is one error and no report
    out2 = tmp_path / "r2" / "report"
    args2 = ["evaluate", "--data", str(data39), "--out", str(out2), "--quiet"]
    assert main(args2 + ["--methods", "failing_meth:boom,failing_meth:nan_out"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("spikejdd evaluate: error: every method failed:") and "nan_out" in err
    assert len(err.splitlines()) == 1 and not out2.parent.exists()
    # --debug stops at the first failure, with its traceback
    with pytest.raises(Exception, match="boom inside my method"):
        main(args + ["--methods", methods, "--debug"])
    sys.modules.pop("failing_meth", None)


def test_reconstruct_refuses_what_it_would_ignore_or_cannot_do(data39, tmp_path, capsys):
    seq = str(data39 / "fan.h5")
    out = str(tmp_path / "frames")
    assert main(["reconstruct", seq, "--methods", "tfp+bilinear", "--weights", "w.pt",
                 "--out", out, "--quiet"]) == 1
    assert "--weights" in capsys.readouterr().err
    assert main(["reconstruct", seq, "--methods", "tfp+bilinear", "--centers", "10:5",
                 "--out", out, "--quiet"]) == 1
    assert "--centers" in capsys.readouterr().err
    # a --cfa that contradicts the file's recorded pattern is refused
    assert main(["reconstruct", seq, "--cfa", "BGGR", "--methods", "tfp+bilinear",
                 "--out", out, "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "--cfa='BGGR'" in err and "RGGB, the pattern fan.h5 records" in err
    assert main(["reconstruct", seq, "--cfa", "rggb", "--methods", "tfp+bilinear",
                 "--out", str(tmp_path / "same"), "--quiet"]) == 0  # the same pattern is fine
    capsys.readouterr()
    # a method that cannot run on the input: nothing is left written, even the PNGs of
    # the methods before it, and the folder this run made is gone
    mono = tmp_path / "mono.h5"
    write_h5(mono, ss.simulate(ss.scenes.procedural("fan", size=(16, 24)),
                               ss.Sensor(height=16, width=24, cfa=None), n_readouts=39))
    assert main(["reconstruct", str(mono), "--methods", "tfp+bilinear,sjdd", "--centers",
                 "9,19", "--out", out, "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "'sjdd'" in err and "monochrome" in err and "None" not in err
    assert not Path(out).exists()
    Path(out).mkdir()
    (Path(out) / "mine.txt").write_text("kept")
    assert main(["reconstruct", str(mono), "--methods", "tfp+bilinear,sjdd", "--centers",
                 "9,19", "--out", out, "--quiet"]) == 1
    assert [f.name for f in Path(out).iterdir()] == ["mine.txt"]  # the user's folder stays
    capsys.readouterr()
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"not a checkpoint")
    assert main(["reconstruct", seq, "--methods", "sjdd", "--weights", str(bad), "--centers",
                 "19", "--out", out, "--quiet"]) == 1
    err = capsys.readouterr().err.strip()
    assert "bad.pt" in err and len(err.splitlines()) == 1 and "weights_only" not in err


def test_reconstruct_centers_mix_readouts_and_ranges(data39, tmp_path, capsys):
    """--centers takes readouts and start:stop[:step] ranges together, each once; a
    split's sequences report each method's window once."""
    from spikejdd.cli import _centers

    assert _centers("30,100:180:40,30", [], 200) == [30, 100, 140]
    assert _centers("5:8", [], 200) == [5, 6, 7]
    for bad in ("a", "1:2:3:4", "1:9:0", "30,200"):
        with pytest.raises(Exception, match="--centers"):
            _centers(bad, [], 200)
    out = tmp_path / "f"
    assert main(["reconstruct", str(data39), "--methods", "tfp+bilinear", "--centers",
                 "15,19:24:4", "--out", str(out), "--quiet"]) == 0
    text = capsys.readouterr().out
    assert text.count("tfp+bilinear: 39 readouts used") == 1
    assert "wrote 9 sRGB PNG(s)" in text  # 3 sequences × readouts 15, 19, 23


def test_a_method_failing_on_one_frame_names_its_file_and_window(data39, tmp_path, capsys,
                                                                 monkeypatch):
    """The failure line names the file, the window (GT frame) and readout it failed on."""
    from spikejdd import evaluate

    (tmp_path / "failing_meth.py").write_text(FAILING_MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    args = ["evaluate", "--data", str(data39), "--out", str(tmp_path / "r"), "--quiet",
            "--repeats", "1"]
    # calls: warm-up (astronaut), astronaut, coffee: the third is on coffee.h5
    for fn, what in (("third_call_fails", "ValueError: bad frame"),
                     ("third_call_wrong_shape", "returned shape (2, 2, 3)")):
        sys.modules.pop("failing_meth", None)
        assert main(args + ["--methods", f"tfp+bilinear,failing_meth:{fn}"]) == 1
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1, err
        assert (f"error: method 'failing_meth:{fn}' failed on {data39 / 'coffee.h5'} window 1 "
                f"of 1 (readout 19): {what}") in err, err
    sys.modules.pop("failing_meth", None)
    frames = evaluate.frames_from_dataset(data39)
    with pytest.raises(MethodError, match=r"failed on .*coffee\.h5 window 1 of 1 \(readout 19\)"):
        evaluate.run(frames, ["failing_meth:third_call_fails"], repeats=1, progress=False)
    sys.modules.pop("failing_meth", None)
