"""The benchmark scripts say their defaults and record the command line as given."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[2] / "benchmarks"


@pytest.fixture
def bench_kernel(monkeypatch):
    monkeypatch.syspath_prepend(str(BENCH))  # the scripts import their sibling `machine`
    monkeypatch.delitem(sys.modules, "machine", raising=False)
    spec = importlib.util.spec_from_file_location("bench_kernel_under_test",
                                                  BENCH / "bench_kernel.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop("machine", None)


def test_help_shows_the_default_results_folder(bench_kernel):
    assert "default benchmarks/results" in " ".join(bench_kernel.build_parser().format_help()
                                                    .split())


def test_command_line_keeps_every_argument_quoted(bench_kernel):
    line = bench_kernel.machine.command_line(
        "bench_kernel.py", ["--quick", "--out", "my results", "--rss-readouts", "50"])
    assert line == "python benchmarks/bench_kernel.py --quick --out 'my results' --rss-readouts 50"


def test_results_record_the_full_command(bench_kernel, tmp_path, capsys):
    argv = ["--ratios-only", "--quick", "--size", "16", "--out", str(tmp_path)]
    bench_kernel.main(argv)
    want = "python benchmarks/bench_kernel.py " + " ".join(argv)
    assert f"Command: `{want}`" in (tmp_path / "kernel_ratios.md").read_text()
