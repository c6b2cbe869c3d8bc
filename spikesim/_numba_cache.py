"""Keep numba's on-disk cache consistent with the package's sources.

numba validates a cached function against its own source file only (time
stamp and size).  The kernels inline functions of other modules
(``spikesim.rng``, ``spikesim._simd``), so when only such a module changes, as
after ``git pull`` in an editable install, numba would go on loading machine
code compiled from the old source: silently different bits.  At import the
package therefore hashes the sources compiled code can come from and, when the
hash differs from the one recorded beside the cache, removes its cache files so
that everything is compiled afresh.  Those sources are the modules that import
``numba`` or ``llvmlite`` (a jitted function can only call jitted functions and
intrinsics, which live in such modules) and the shipped ``.npy`` tables the
kernels load; an edit anywhere else (a docstring in ``analysis/``) keeps the
cache.  Under a user-set ``NUMBA_CACHE_DIR`` (a read-only install, a cluster's
shared cache) numba keeps the package's cache files there instead, in one
folder per source folder (its name and a hash of its path), and the same check
covers those folders; nothing else in that directory is touched.
"""

from __future__ import annotations

import hashlib
import os
import re
from pathlib import Path

STAMP_NAME = "spikesim-sources.sha256"
_CACHE_SUFFIXES = (".nbi", ".nbc")
#: The marks ``spikesim.families`` leaves beside the cache files of a compiled family.
FAMILY_MARK_PREFIX = "spikesim-compiled-"


_COMPILER_IMPORT = re.compile(rb"^(?:import|from)[ \t]+(?:numba|llvmlite)\b", re.MULTILINE)


def compiled_sources(package_dir: Path) -> list[Path]:
    """The files compiled code can come from: every ``.py`` module importing
    numba or llvmlite at its top level (a function-level import, e.g. to set the
    thread count, compiles nothing), and every ``.npy`` table, sorted."""
    modules = [p for p in package_dir.rglob("*.py") if _COMPILER_IMPORT.search(p.read_bytes())]
    return sorted(modules + list(package_dir.rglob("*.npy")))


def sources_digest(package_dir: Path) -> str:
    """SHA-256 over the relative paths and contents of :func:`compiled_sources`."""
    h = hashlib.sha256()
    for path in compiled_sources(package_dir):
        h.update(str(path.relative_to(package_dir)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def compiled_in_this_process() -> bool:
    """Whether a spikesim kernel was compiled in this process rather than loaded from
    numba's on-disk cache (a one-off cost of the first run after an install or edit)."""
    import sys

    for name, module in list(sys.modules.items()):
        if not name.startswith("spikesim") or module is None:
            continue
        for obj in vars(module).values():
            stats = getattr(obj, "stats", None)
            misses = getattr(stats, "cache_misses", None)
            if misses and sum(misses.values()):
                return True
    return False


def cache_folder(source_folder: Path) -> Path:
    """The folder where numba keeps the cache files of the modules in
    ``source_folder``: its ``__pycache__``, or under a user-set
    ``NUMBA_CACHE_DIR`` the folder numba names there after it: the source
    folder's name and the SHA-1 of its absolute path, joined by ``_`` (numba's
    rule in every version from 0.60 on, where its locator class is not public
    yet; tests/spikesim/test_numba_cache.py checks it against numba's own
    folder)."""
    user = os.environ.get("NUMBA_CACHE_DIR")
    if not user:
        return source_folder / "__pycache__"
    folder = os.path.abspath(os.fspath(source_folder))
    digest = hashlib.sha1(folder.encode()).hexdigest()
    return Path(user) / f"{os.path.basename(folder)}_{digest}"


def sync_cache(package_dir: Path) -> bool:
    """Remove the numba cache files of ``package_dir``'s modules (in each of its
    folders' :func:`cache_folder`) when its sources changed since the last
    call; returns True when it removed them.  Never raises for an unwritable
    install or cache (the cache is then numba's concern)."""
    stamp = cache_folder(package_dir) / STAMP_NAME
    try:
        digest = sources_digest(package_dir)
        if stamp.is_file() and stamp.read_text().strip() == digest:
            return False
        for folder in {p.parent for p in package_dir.rglob("*.py")}:
            for path in cache_folder(folder).glob("*"):
                if path.suffix in _CACHE_SUFFIXES or path.name.startswith(FAMILY_MARK_PREFIX):
                    path.unlink(missing_ok=True)
        stamp.parent.mkdir(parents=True, exist_ok=True)
        tmp = stamp.with_name(f"{STAMP_NAME}.{os.getpid()}.tmp")
        tmp.write_text(digest)
        tmp.replace(stamp)
        return True
    except OSError:
        return False
