"""Multi-file datasets: index build/load/staleness, open_dataset on a file or folder."""

from __future__ import annotations

import json
import os
import pickle
import warnings

import numpy as np
import pytest

from spikesim.errors import SpikeSimFileError, SpikeSimFormatError, SpikeSimValueError
from spikesim.io import build_index, load_index, open_dataset, write_h5
from spikesim.io.index import INDEX_NAME


@pytest.fixture
def folder(tmp_path, make_stream):
    streams = {}
    for i, name in enumerate(["seq_b", "seq_a", "seq_c"]):
        s = make_stream(n=30 + 10 * i, height=8, width=12, seed=i, gt_index=(4, 15 + i))
        write_h5(tmp_path / f"{name}.h5", s)
        streams[name] = s
    return tmp_path, streams


def test_folder_without_index_is_scanned(folder):
    path, streams = folder
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a missing index is normal: no warning
        ds = open_dataset(path)
    assert ds.names == ["seq_a", "seq_b", "seq_c"]
    assert len(ds) == 3 and ds.n_readouts == 30 + 40 + 50
    for seq in ds:
        s = streams[seq.name]
        assert np.array_equal(seq.read_window(0, None), s.bits)
        assert seq.gt_index.tolist() == s.gt_index.tolist()
    assert np.array_equal(ds.read_window("seq_c", 3, 7, (1, 2, 5, 9)),
                          streams["seq_c"].bits[3:10, 1:6, 2:11])
    assert ds[1].name == "seq_b" and ds.sequence(-1).name == "seq_c"


def test_index_is_written_used_and_rebuildable(folder):
    path, _ = folder
    index = build_index(path)
    on_disk = json.loads((path / INDEX_NAME).read_text())
    assert on_disk == json.loads(json.dumps(index))
    entry = on_disk["sequences"][0]
    for key in ("name", "file", "height", "width", "cfa", "n_readouts", "clock_hz",
                "gt_index", "meta", "has_clean"):
        assert key in entry
    assert load_index(path) is not None
    ds = open_dataset(path)
    assert ds.sequence("seq_a").meta == entry["meta"]
    # deleting the index and rebuilding it gives the same content
    (path / INDEX_NAME).unlink()
    assert build_index(path, write=False) == index


def test_stale_or_corrupt_index_is_rebuilt_with_a_warning(folder, make_stream):
    path, _ = folder
    build_index(path)
    write_h5(path / "seq_d.h5", make_stream(n=20, height=8, width=12, gt_index=(5,)))
    assert load_index(path) is None
    with pytest.warns(UserWarning, match="does not match"):
        ds = open_dataset(path)
    assert "seq_d" in ds.names
    (path / INDEX_NAME).write_text("{broken")
    with pytest.warns(UserWarning, match="does not match"):
        assert len(open_dataset(path)) == 4
    # rewriting a file (new size/mtime) also makes the index stale
    build_index(path)
    write_h5(path / "seq_a.h5", make_stream(n=21, height=8, width=12, gt_index=(5,)))
    st = os.stat(path / "seq_a.h5")
    os.utime(path / "seq_a.h5", ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    with pytest.warns(UserWarning):
        assert open_dataset(path).sequence("seq_a").n_readouts == 21


def test_single_file_and_pickling(folder):
    path, streams = folder
    ds = open_dataset(path / "seq_b.h5")
    assert ds.names == ["seq_b"]
    ds.read_window(0, 0, 5)  # opens the handle before pickling
    clone = pickle.loads(pickle.dumps(ds))
    assert np.array_equal(clone.read_window("seq_b", 2, 5), streams["seq_b"].bits[2:7])


def test_bad_folders_and_names(tmp_path, folder):
    path, _ = folder
    with pytest.raises(SpikeSimFileError, match="no such"):
        open_dataset(tmp_path / "nope")
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(SpikeSimFormatError, match="holds no spikesim sequence"):
        open_dataset(empty)
    ds = open_dataset(path)
    with pytest.raises(SpikeSimValueError, match="sequence"):
        ds.sequence("missing")
    with pytest.raises(SpikeSimValueError, match="sequence"):
        ds.sequence(3)
    (path / "junk.h5").write_bytes(b"not hdf5 at all" * 10)
    with pytest.raises(SpikeSimFormatError, match="junk.h5"):
        open_dataset(path)


def test_temporary_files_of_running_writers_are_ignored(folder):
    path, _ = folder
    (path / ".seq_z.h5.tmp-123-abcd").write_bytes(b"partial")
    (path / ".seq_z.h5.tmp-123-abcd").rename(path / ".seq_z.h5.tmp-123-abcd.h5")
    assert len(open_dataset(path)) == 3
