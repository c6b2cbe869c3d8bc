"""README.md stays short and its speed and quality tables are those that
benchmarks/readme_tables.py makes from benchmarks/results/*.json."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "benchmarks" / "readme_tables.py"
README = ROOT / "README.md"


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SCRIPT), *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)


def test_readme_is_at_most_200_lines():
    n = len(README.read_text(encoding="utf-8").splitlines())
    assert n <= 200, f"README.md has {n} lines; move detail to docs/ (at most 200)"


def test_readme_tables_match_the_results():
    run = _run("--check")
    assert run.returncode == 0, run.stderr


def test_a_tampered_table_is_detected_and_rewritten(tmp_path):
    text = README.read_text(encoding="utf-8")
    row = next(line for line in text.splitlines() if line.startswith("| `tfp+malvar2004` |"))
    cells = row.split(" | ")
    cells[1] = "99.99"   # the PSNR a reader would believe
    tampered = tmp_path / "README.md"
    tampered.write_text(text.replace(row, " | ".join(cells)), encoding="utf-8")

    run = _run("--check", "--readme", str(tampered))
    assert run.returncode == 1
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and "quality table differs" in lines[0] and "99.99" in lines[0]

    assert _run("--write", "--readme", str(tampered)).returncode == 0
    assert tampered.read_text(encoding="utf-8") == text
    assert _run("--check", "--readme", str(tampered)).returncode == 0


def test_missing_markers_and_results_give_one_line_errors(tmp_path):
    bare = tmp_path / "README.md"
    bare.write_text("# no tables here\n", encoding="utf-8")
    run = _run("--check", "--readme", str(bare))
    assert run.returncode == 2
    assert run.stderr.count("\n") == 1 and "<!-- tables:speed:start -->" in run.stderr

    run = _run("--check", "--results", str(tmp_path))
    assert run.returncode == 2
    assert run.stderr.count("\n") == 1 and "peers.json is missing" in run.stderr
