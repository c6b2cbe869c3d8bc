"""Kernel families: a run compiles only the noise code its model uses.

The noise-free kernel must not contain the paper-mode or event-driven code
(what a first run after an install pays for); which family a model needs is
decided in Python; the compile notice is printed once per process and only
when the family is not in numba's cache yet.
"""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys

import numpy as np
import pytest

import spikesim as ss
from spikesim import families
from spikesim.simulate import _kernel_inputs

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@pytest.mark.parametrize("noise, family", [
    (None, "noise-free"),
    (ss.noise.PaperNoise(sigma_g=5.0), "paper"),
    (ss.noise.PaperNoise(sigma_g=0.0, sigma_p=2.0), "paper"),
    (ss.noise.PhysicalNoise(), "physical"),
    (ss.noise.PhysicalNoise(charge_noise_electrons=1.0), "charge"),
    (ss.noise.PhysicalNoise(shot_noise=False, temporal_threshold_noise=0.01), "charge"),
])
def test_each_noise_model_maps_to_the_family_whose_code_it_runs(noise, family):
    sensor = ss.Sensor(height=4, width=8, noise=noise)
    model, _ = _kernel_inputs(sensor, 0, sensor.noise)
    assert families.family_of(model) == family
    assert families.family_of_noise(noise) == family


def test_the_readout_sampler_is_the_charge_family():
    assert families.family_of_noise(ss.noise.PhysicalNoise(), shot_sampler="readout") == "charge"
    sensor = ss.Sensor(height=4, width=8, noise=ss.noise.PhysicalNoise())
    model, _ = _kernel_inputs(sensor, 0, sensor.noise, event=False)
    assert families.family_of(model) == "charge"


def test_an_unknown_family_is_a_one_line_error():
    with pytest.raises(ValueError, match="family"):
        families.family_markers("fast")


COMPILED = """
import json
import numpy as np
import spikesim as ss
from spikesim import _event, _kernels, _poisson
img = np.random.default_rng(0).uniform(0, 1, (8, 70, 3)).astype(np.float32)
moving = ss.scenes.Keyframes([0.0, 0.001], [img, np.roll(img, 2, axis=1)])
seen = []
for noise in (None, ss.noise.PaperNoise(sigma_g=10.0)):
    ss.simulate(moving, ss.Sensor(height=8, width=70, noise=noise), 30)
    seen.append({name: len(f.overloads) for name, f in (
        ("paper", _kernels._fast_paper), ("event", _event.first_waits),
        ("shot", _poisson.poisson))})
    seen[-1]["kernel"] = sum(len(k.overloads) for k in _kernels._ROWS_KERNELS.values())
print(json.dumps(seen))
"""


def _last_json_line(code, cache):
    """The JSON of the last line ``code`` prints in a fresh interpreter with an
    empty numba cache ``cache`` (it must succeed)."""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=ROOT, timeout=900,
                          env=dict(os.environ, SPIKESIM_QUIET_COMPILE="1",
                                   NUMBA_CACHE_DIR=str(cache)))
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_a_noise_free_run_holds_no_noise_code_and_a_paper_run_no_physical_code(tmp_path):
    # in a fresh interpreter and an empty cache (a function loaded from the cache
    # leaves its callees untouched): ``overloads`` lists what was compiled, and
    # code a family leaves out is never typed
    clean, paper = _last_json_line(COMPILED, tmp_path)
    assert clean == {"paper": 0, "event": 0, "shot": 0, "kernel": 1}
    assert paper == {"paper": 1, "event": 0, "shot": 0, "kernel": 2}


def test_the_notice_is_printed_once_per_process_and_only_for_a_cold_family(monkeypatch):
    monkeypatch.delenv("SPIKESIM_QUIET_COMPILE", raising=False)
    monkeypatch.setattr(families, "_announced", set())
    monkeypatch.setattr(families, "is_compiled", lambda name: name == "paper")
    out = io.StringIO()
    assert families.announce_compile("physical", out)
    assert not families.announce_compile("physical", out)  # once per process
    assert not families.announce_compile("paper", out)  # in the cache already
    text = out.getvalue()
    assert text.count("\n") == 1
    assert "compiling the physical simulation kernels" in text
    assert f"about {families.COMPILE_SECONDS['physical']} s" in text
    assert "cached in" in text


def test_a_run_marks_its_family_compiled(tmp_path, monkeypatch):
    monkeypatch.setattr(families, "_mark_path", lambda name: tmp_path / f"{name}.ok")
    ss.simulate(ss.scenes.Static(np.full((4, 8), 0.5)), ss.Sensor(height=4, width=8), 4)
    assert families.is_compiled("noise-free")
    assert not families.is_compiled("paper")


def test_spikesim_compile_fills_the_cache_and_reports_each_family(capsys):
    from spikesim.cli import main

    assert main(["compile", "noise-free"]) == 0
    err = capsys.readouterr().err
    assert "noise-free:" in err and "done" in err
    assert families.is_compiled("noise-free")


def test_spikesim_compile_rejects_an_unknown_family(capsys):
    from spikesim.cli import main

    assert main(["compile", "turbo"]) != 0
    err = capsys.readouterr().err
    assert "family" in err and "turbo" in err and len(err.strip().splitlines()) == 1


PHYSICAL = """
import json
import numpy as np
import spikesim as ss
from spikesim import _event, _kernels
img = np.random.default_rng(0).uniform(0, 1, (4, 70, 3)).astype(np.float32)
moving = ss.scenes.Keyframes([0.0, 0.001], [img, np.roll(img, 2, axis=1)])
ss.simulate(moving, ss.Sensor(height=4, width=70, noise=ss.noise.PhysicalNoise(), reset="zero"), 30)
print(json.dumps({name: len(getattr(mod, name).overloads) for mod, name in (
    (_event, "_SETTLE_MODULO"), (_event, "_SETTLE_SUBTRACT"),
    (_event, "_SETTLE_ZERO"), (_event, "_WALK_M"), (_event, "_WALK_S"),
    (_event, "_WALK_Z"), (_event, "_PACKED_M"), (_event, "_PACKED_Z"))}))
"""


@pytest.mark.slow
def test_a_physical_run_compiles_the_event_sampler_of_its_own_reset_mode_only(tmp_path):
    seen = _last_json_line(PHYSICAL, tmp_path)
    assert seen["_SETTLE_ZERO"] == 1 and seen["_WALK_Z"] >= 1
    assert seen["_PACKED_Z"] >= 1
    others = {k: v for k, v in seen.items() if not k.endswith(("ZERO", "_Z"))}
    assert set(others.values()) == {0}, others


def test_the_physical_family_is_compiled_per_reset_mode():
    assert families.kernel_name("physical", "subtract") == "physical-subtract"
    assert families.kernel_name("physical", 2) == "physical-zero"
    assert families.kernel_name("paper", "zero") == "paper"
    from spikesim import _kernels

    assert [getattr(_kernels, f"RESET_{r.upper()}") for r in families.RESETS] == [0, 1, 2]
    with pytest.raises(ValueError, match="reset"):
        families.kernel_name("physical", "wrap")


def test_a_dataset_build_compiles_the_kernels_its_sensors_need_once(monkeypatch):
    from spikesim.dataset import build

    calls = []
    monkeypatch.setattr(families, "is_compiled", lambda name: name == "paper")
    monkeypatch.setattr("spikesim.precompile.precompile",
                        lambda names, resets: calls.append((names, list(resets))))
    sensors = [ss.Sensor(height=4, width=8, noise=ss.noise.PhysicalNoise(), reset="subtract"),
               ss.Sensor(height=4, width=8, noise=ss.noise.PhysicalNoise(), reset="subtract"),
               ss.Sensor(height=4, width=8, noise=ss.noise.PaperNoise(sigma_g=5.0)),
               ss.Sensor(height=4, width=8)]
    cold = build.compile_first([{"sensor": s.to_dict()} for s in sensors])
    assert cold == ["noise-free", "physical-subtract"]
    assert sorted(calls) == [(["noise-free"], ["modulo"]), (["physical"], ["subtract"])]
