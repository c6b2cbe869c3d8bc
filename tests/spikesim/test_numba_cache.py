"""The numba cache is dropped when a source of compiled code changes (numba
itself only checks each function's own file, not the modules it inlines), and
kept when only other modules change."""

from __future__ import annotations

import os

from spikesim._numba_cache import STAMP_NAME, cache_folder, sync_cache


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


def test_a_user_cache_dir_is_kept_in_step_and_nothing_else_there_is_touched(tmp_path,
                                                                           monkeypatch):
    """Under a user-set ``NUMBA_CACHE_DIR`` numba keeps each source folder's cache in
    a folder of its own there (its name and a hash of its path): those are dropped
    after an edit like the package's own ``__pycache__`` would be; other projects'
    folders and files in that directory, and the package's ``__pycache__``, stay."""
    pkg = _package(tmp_path)
    beside = _cache_files(pkg)
    user = tmp_path / "elsewhere"
    monkeypatch.setenv("NUMBA_CACHE_DIR", os.fspath(user))
    found = {}

    def there(module):  # where numba itself puts a module's cache under the user dir
        if module.parent not in found:
            found[module.parent] = _numba_user_folder(module, user)
        return found[module.parent]

    assert cache_folder(pkg) == there(pkg / "kernels.py")
    assert cache_folder(pkg / "sub") == there(pkg / "sub" / "rng.py")
    assert there(pkg / "kernels.py") != there(pkg / "sub" / "rng.py")
    other = user / "otherproject_0123abcd" / "mod.f-1.py311.nbi"
    other.parent.mkdir(parents=True)
    other.write_bytes(b"theirs")

    def user_files():
        files = [there(pkg / "kernels.py") / "kernels.f-1.py311.nbi",
                 there(pkg / "kernels.py") / "kernels.f-1.py311.1.nbc",
                 there(pkg / "sub" / "rng.py") / "rng.g-3.py311.nbi"]
        for f in files:
            f.parent.mkdir(parents=True, exist_ok=True)
            f.write_bytes(b"cached")
        return files

    files = user_files()
    assert sync_cache(pkg)  # first run there: no stamp yet, so start clean
    assert not any(f.exists() for f in files)
    assert (cache_folder(pkg) / STAMP_NAME).is_file()
    files = user_files()
    assert not sync_cache(pkg)  # nothing changed: kept
    assert all(f.exists() for f in files)
    (pkg / "sub" / "rng.py").write_text("import numba\ny = 3\n")
    assert sync_cache(pkg)
    assert not any(f.exists() for f in files)
    assert other.read_bytes() == b"theirs" and all(f.exists() for f in beside)


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


def _numba_user_folder(module, user):
    """The folder numba itself makes under ``user`` (``NUMBA_CACHE_DIR``) for the
    cache of a cached function defined in ``module``'s folder: found by compiling
    one there in a fresh interpreter, whatever numba's version."""
    import subprocess
    import sys

    folder = module.parent
    folder.mkdir(parents=True, exist_ok=True)
    probe = folder / "spikesim_cache_probe.py"
    probe.write_text("from numba import njit\n\n@njit(cache=True)\ndef one():\n    return 1\n")
    scratch = user.parent / "probe-cache"
    code = ("import sys; sys.path.insert(0, sys.argv[1]); import spikesim_cache_probe as m; "
            "assert m.one() == 1")
    subprocess.run([sys.executable, "-c", code, os.fspath(folder)], check=True,
                   env=dict(os.environ, NUMBA_CACHE_DIR=os.fspath(scratch)))
    probe.unlink()
    (made,) = [p for p in scratch.iterdir() if p.is_dir()]
    import shutil

    shutil.rmtree(scratch)
    return user / made.name
