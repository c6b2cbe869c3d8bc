"""The packages depend one way: spikejdd imports spikesim, never the reverse."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _imports(path: Path):
    """(line, module) of every import in ``path``, at any depth (function-level too)."""
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            yield from ((node.lineno, a.name) for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node.lineno, node.module


def test_spikesim_never_imports_spikejdd():
    found = [f"{p.relative_to(ROOT)}:{line} imports {mod}"
             for p in sorted((ROOT / "spikesim").rglob("*.py"))
             for line, mod in _imports(p) if mod.split(".")[0] == "spikejdd"]
    assert not found, "\n".join(found)


def test_the_check_sees_function_level_imports(tmp_path):
    f = tmp_path / "m.py"
    f.write_text("def f():\n    import spikejdd.models\n    from spikejdd import x\n")
    assert [m for _, m in _imports(f)] == ["spikejdd.models", "spikejdd"]
