"""The numba cache is dropped when a source of compiled code changes (numba
itself only checks each function's own file, not the modules it inlines), and
kept when only other modules change."""

from __future__ import annotations

import os

from spikesim._numba_cache import STAMP_NAME, sync_cache


def _package(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "__pycache__").mkdir(parents=True)
    (pkg / "sub" / "__pycache__").mkdir(parents=True)
    (pkg / "kernels.py").write_text("from numba import njit\nx = 1\n")
    (pkg / "sub" / "rng.py").write_text("import numba\ny = 2\n")
    (pkg / "sub" / "report.py").write_text('def f():\n    import numba\n')  # compiles nothing
    (pkg / "table.npy").write_bytes(b"table")
    return pkg


def _cache_files(pkg):
    files = [pkg / "__pycache__" / "kernels.f-1.py311.nbi",
             pkg / "__pycache__" / "kernels.f-1.py311.1.nbc",
             pkg / "sub" / "__pycache__" / "rng.g-3.py311.nbi"]
    for f in files:
        f.write_bytes(b"cached")
    (pkg / "__pycache__" / "kernels.cpython-311.pyc").write_bytes(b"bytecode")
    return files


def test_cache_survives_unchanged_sources_and_is_dropped_after_any_edit(tmp_path, monkeypatch):
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    pkg = _package(tmp_path)
    files = _cache_files(pkg)
    assert sync_cache(pkg)  # first run: no stamp yet, so start clean
    assert not any(f.exists() for f in files)
    assert (pkg / "__pycache__" / "kernels.cpython-311.pyc").exists()  # only numba's files go
    assert (pkg / "__pycache__" / STAMP_NAME).is_file()
    files = _cache_files(pkg)
    assert not sync_cache(pkg)  # nothing changed: the cache is kept
    assert all(f.exists() for f in files)
    (pkg / "sub" / "report.py").write_text('def f():\n    import numba  # edited\n')
    assert not sync_cache(pkg)  # a module without compiled code: the cache is kept
    assert all(f.exists() for f in files)
    (pkg / "sub" / "rng.py").write_text("import numba\ny = 3\n")  # an inlined module changes
    assert sync_cache(pkg)
    assert not any(f.exists() for f in files)
    files = _cache_files(pkg)
    (pkg / "table.npy").write_bytes(b"other table")  # a shipped table changes
    assert sync_cache(pkg)
    assert not any(f.exists() for f in files)
    assert not [p for p in (pkg / "__pycache__").iterdir() if p.name.endswith(".tmp")]


def test_a_user_cache_dir_is_left_alone(tmp_path, monkeypatch):
    pkg = _package(tmp_path)
    files = _cache_files(pkg)
    monkeypatch.setenv("NUMBA_CACHE_DIR", os.fspath(tmp_path / "elsewhere"))
    assert not sync_cache(pkg)
    assert all(f.exists() for f in files)


def test_a_compiled_kernel_is_told_from_a_cached_one(tmp_path, monkeypatch):
    import subprocess
    import sys

    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    (tmp_path / "spikesim_probe_kernel.py").write_text(
        "from numba import njit\n\n@njit(cache=True)\ndef twice(x):\n    return 2 * x\n")
    code = ("import sys; sys.path.insert(0, sys.argv[1]); import spikesim_probe_kernel as m; "
            "from spikesim._numba_cache import compiled_in_this_process as c; "
            "assert m.twice(3) == 6; print(c())")
    runs = [subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True,
                           text=True, check=True).stdout.strip() for _ in range(2)]
    assert runs == ["True", "False"]  # compiled (cold cache), then loaded from the cache
