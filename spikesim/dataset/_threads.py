"""Thread pools of spawned workers sized to their share of the cores.

A spawned worker process starts numpy's BLAS, numba's OpenMP layer and
OpenCV with one thread per core each.  With one worker per core that is
several busy-waiting threads per core; the kernel's and OpenCV's own pools are
resized in the worker (:func:`spikesim.dataset.worker.run_task`), but BLAS and
the OpenMP pool read their size from the environment when the process starts.
:func:`worker_thread_env` therefore sets those variables, for as long as the
pool may start processes, to the worker's share; a variable the user set
already is left as it is.  (Dask's nanny sets the BLAS and OpenMP ones to 1
for its workers itself.)  Results do not depend on thread counts.
"""

from __future__ import annotations

import contextlib
import os

__all__ = ["THREAD_VARIABLES", "worker_thread_env"]

#: Environment variables read by thread pools when a process starts.
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                    "NUMBA_NUM_THREADS")


@contextlib.contextmanager
def worker_thread_env(threads: int):
    """Within the block, processes started from here get ``threads`` threads per pool."""
    added = [name for name in THREAD_VARIABLES if name not in os.environ]
    for name in added:
        os.environ[name] = str(max(1, int(threads)))
    try:
        yield
    finally:
        for name in added:
            os.environ.pop(name, None)
