"""Fixtures of the fault suite (marker ``faults``).

The default run (``make test``) takes a fast subset: few hypothesis examples
and one case per kind of fault.  ``make test-faults`` sets
``SPIKESIM_FAULTS=full`` and runs every case.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.support.fault_helpers import small_stream


def pytest_collection_modifyitems(config, items):
    here = Path(__file__).parent
    for item in items:
        if here in Path(str(item.fspath)).parents:
            item.add_marker(pytest.mark.faults)


@pytest.fixture(scope="session")
def h5_original(tmp_path_factory):
    """A small checksummed HDF5 file (zstd or gzip, clean twin, 3 GT frames) and its content."""
    from spikesim.io import open_h5, write_h5

    folder = tmp_path_factory.mktemp("orig")
    path = folder / "orig.h5"
    write_h5(path, small_stream(clean_twin=True))
    with open_h5(path) as seq:
        content = {"packed": seq.read_packed(), "clean": seq.read_packed(clean=True),
                   "gt": seq.read_all_gt(), "gt_index": seq.gt_index.copy(),
                   "shape": seq.shape, "cfa": seq.cfa, "clock_hz": seq.clock_hz,
                   "meta": seq.meta}
    return path, content


@pytest.fixture(scope="session")
def dat_original(tmp_path_factory):
    from spikesim.io import write_dat

    folder = tmp_path_factory.mktemp("origdat")
    path = folder / "orig.dat"
    st = small_stream(height=250, width=400, n=8, noise=True, gt_readouts=[4])
    write_dat(path, st)
    return path, np.asarray(st.unpack())
