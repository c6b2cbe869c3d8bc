"""Dataset builder: manifests → many sequences, locally or on a Dask cluster.

See ``docs/dataset.md``.  Typical use::

    from spikesim.dataset import load_manifest, build_dataset
    summary = build_dataset(load_manifest("builtin:sjdd-train-small"), "data", workers=2)
"""

from spikesim.dataset.build import BuildFailedError, BuildSummary, build_dataset, estimate_dataset
from spikesim.dataset.manifest import (
    BUILTIN_PREFIX,
    Manifest,
    builtin_manifest_path,
    builtin_manifests,
    load_manifest,
    parse_manifest,
)
from spikesim.dataset.plan import SequenceTask, derive_seed, plan_tasks

__all__ = [
    "BUILTIN_PREFIX",
    "BuildFailedError",
    "BuildSummary",
    "Manifest",
    "SequenceTask",
    "build_dataset",
    "builtin_manifest_path",
    "builtin_manifests",
    "derive_seed",
    "estimate_dataset",
    "load_manifest",
    "parse_manifest",
    "plan_tasks",
]
