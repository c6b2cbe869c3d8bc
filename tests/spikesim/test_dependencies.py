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


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _import_graph() -> dict[str, set[str]]:
    """Module → project modules it imports (any depth), package ``__init__`` files left
    out as targets: a package importing its own modules is how its public names work."""
    files = {_module_name(p): p for pkg in ("spikesim", "spikejdd")
             for p in (ROOT / pkg).rglob("*.py")}
    packages = {m for m, p in files.items() if p.name == "__init__.py"}
    graph = {}
    for mod, path in files.items():
        targets = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                targets.add(node.module)
                targets.update(f"{node.module}.{a.name}" for a in node.names)
            elif isinstance(node, ast.Import):
                targets.update(a.name for a in node.names)
        graph[mod] = {t for t in targets if t in files and t not in packages and t != mod}
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, found, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_no_import_circle_between_modules():
    assert _cycles(_import_graph()) == []
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def _private_imports(path: Path, module: str):
    """``(line, what)`` for each private name ``path`` imports from outside its own package:
    a private module (``_name`` anywhere in the dotted path) or a private attribute belongs
    to the package that holds it, and only that package's modules may import it."""
    own = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]

    def inside(owner: str) -> bool:
        return own == owner or own.startswith(owner + ".")

    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            targets = [(node.module, None)] + [(node.module, a.name) for a in node.names]
        elif isinstance(node, ast.Import):
            targets = [(a.name, None) for a in node.names]
        else:
            continue
        for mod, name in targets:
            parts = mod.split(".")
            if parts[0] not in ("spikesim", "spikejdd"):
                continue
            if name is None:
                private = [i for i, p in enumerate(parts) if p.startswith("_")]
                if private and not inside(".".join(parts[:private[0]])):
                    yield node.lineno, mod
            elif name.startswith("_") and not name.startswith("__"):
                is_pkg = (ROOT / mod.replace(".", "/")).is_dir()
                if not inside(mod if is_pkg else mod.rsplit(".", 1)[0]):
                    yield node.lineno, f"{mod}.{name}"


def test_no_private_name_is_imported_across_packages():
    found = [f"{p.relative_to(ROOT)}:{line} imports {what}"
             for pkg in ("spikesim", "spikejdd") for p in sorted((ROOT / pkg).rglob("*.py"))
             for line, what in _private_imports(p, _module_name(p))]
    assert not found, "\n".join(found)


def test_the_private_check_bites(tmp_path):
    f = tmp_path / "cli.py"
    f.write_text("from spikesim._validate import check_int\nfrom spikesim.io import _x\n"
                 "from spikesim.io._compression import C\n")
    assert [w for _, w in _private_imports(f, "spikejdd.cli")] == [
        "spikesim._validate", "spikesim.io._x", "spikesim.io._compression"]
    assert list(_private_imports(f, "spikesim.io.dat")) == []


def _setup_cfg():
    import configparser

    cfg = configparser.ConfigParser()
    cfg.read(ROOT / "setup.cfg", encoding="utf-8")
    return cfg


def _lines(value: str) -> list[str]:
    """The entries of a multi-line setup.cfg value, comment lines left out."""
    return [s.strip() for s in value.splitlines() if s.strip() and not s.strip().startswith("#")]


def test_numba_range_has_an_upper_bound_and_holds_the_installed_numba():
    """The kernels lean on numba's code generation, so a numba release may break them: the
    range is closed above, and the numba this suite runs with lies inside it."""
    import numba
    from packaging.requirements import Requirement

    requires = _lines(_setup_cfg()["options"]["install_requires"])
    reqs = {r.name: r for r in map(Requirement, requires)}
    spec = reqs["numba"].specifier
    assert any(s.operator in ("<", "<=", "==", "~=") for s in spec), f"numba{spec} is open above"
    assert any(s.operator in (">", ">=", "==", "~=") for s in spec), f"numba{spec} is open below"
    assert spec.contains(numba.__version__), f"numba {numba.__version__} is outside numba{spec}"


def test_every_shipped_file_is_in_a_declared_package():
    """Each data file under the packages (tables, weights, built-in manifests) lies in a
    package that setuptools finds and matches that package's ``package_data`` glob: a file
    left out installs fine in editable mode and goes missing from a wheel; a folder
    setuptools cannot place warns on every ``pip install``."""
    from fnmatch import fnmatch

    from setuptools import find_namespace_packages

    cfg = _setup_cfg()
    assert cfg["options"]["packages"].strip() == "find_namespace:"
    find = cfg["options.packages.find"]
    packages = set(find_namespace_packages(str(ROOT), include=_lines(find["include"]),
                                           exclude=_lines(find.get("exclude", ""))))
    assert {"spikesim", "spikesim.tables", "spikejdd.weights"} <= packages
    assert not [p for p in packages if "__pycache__" in p]
    package_data = {k: [g.strip() for g in v.split(",")] for k, v in
                    cfg["options.package_data"].items()}
    skip = (".py", ".pyc", ".nbi", ".nbc", ".sha256")
    data = [p for pkg in ("spikesim", "spikejdd") for p in (ROOT / pkg).rglob("*")
            if p.is_file() and "__pycache__" not in p.parts and not p.name.endswith(skip)]
    assert data, "no data files found: the check would pass vacuously"
    missing = []
    for path in data:
        package = ".".join(path.parent.relative_to(ROOT).parts)
        globs = package_data.get(package, [])
        if package not in packages or not any(fnmatch(path.name, g) for g in globs):
            missing.append(str(path.relative_to(ROOT)))
    assert not missing, "not shipped in a wheel: " + ", ".join(missing)
