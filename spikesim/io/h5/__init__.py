"""spikesim HDF5 files, format version 1 (docs/io.md): :mod:`~spikesim.io.h5.format` (the
layout, constants and checks), :mod:`~spikesim.io.h5.writer` (streaming writer) and
:mod:`~spikesim.io.h5.reader` (lazy reader)."""

from spikesim.io.h5.format import FORMAT_NAME, FORMAT_VERSION, spike_chunks
from spikesim.io.h5.reader import Sequence, open_h5, read_h5, read_header
from spikesim.io.h5.writer import H5Writer, write_h5

__all__ = [
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "H5Writer",
    "Sequence",
    "open_h5",
    "read_h5",
    "read_header",
    "spike_chunks",
    "write_h5",
]
