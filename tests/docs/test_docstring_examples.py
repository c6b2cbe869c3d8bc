"""Every ``Examples`` section in the docstrings of spikesim and spikejdd runs and prints
what it shows (doctest), so the API reference cannot drift from the code."""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

import spikejdd
import spikesim

SKIP = ("__main__",)  # modules that run a program when imported


def _modules() -> list[str]:
    names = []
    for pkg in (spikesim, spikejdd):
        names.append(pkg.__name__)
        for info in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + "."):
            if info.name.rsplit(".", 1)[-1] not in SKIP:
                names.append(info.name)
    return sorted(names)


def _examples(name: str) -> list[doctest.DocTest]:
    module = importlib.import_module(name)
    finder = doctest.DocTestFinder(exclude_empty=True)
    return [t for t in finder.find(module, name) if t.examples
            and getattr(t, "filename", None) == getattr(module, "__file__", None)]


MODULES = [m for m in _modules() if _examples(m)]


def test_the_public_entry_points_have_examples():
    documented = {t.name for m in MODULES for t in _examples(m)}
    for name in ("spikesim.simulate.simulate", "spikesim.sensor.Sensor.preset",
                 "spikesim.io.h5.writer.write_h5", "spikesim.estimate.tfp",
                 "spikejdd.registry.reconstruct"):
        assert name in documented, f"{name} has no Examples section"


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples_run(name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # examples that write files write them here
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    for test in _examples(name):
        runner.run(test)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples failed in {name}"
