"""File input and output: spikesim HDF5 datasets, PKU ``.dat`` captures, SJDD-Net export.

See ``docs/io.md`` for the formats, the chunking and compression choices and
their measured trade-offs.
"""

from spikesim.io._compression import COMPRESSIONS, DEFAULT_COMPRESSION, compression_kwargs
from spikesim.io.atomic import atomic_path
from spikesim.io.dat import (
    KNOWN_SENSOR_SIZES,
    RAW_HEAD_COLUMNS,
    DatFile,
    DatWriter,
    guess_dat_shape,
    open_dat,
    read_dat,
    write_dat,
)
from spikesim.io.export import export_sjdd
from spikesim.io.h5 import (
    FORMAT_VERSION,
    H5Writer,
    Sequence,
    open_h5,
    read_h5,
    read_header,
    write_h5,
)
from spikesim.io.index import (
    Dataset,
    build_index,
    dataset_splits,
    load_index,
    open_dataset,
    resolve_dataset,
)
from spikesim.io.labels import sequence_labels
from spikesim.io.source import open_source
from spikesim.io.verify import verify, verify_file

__all__ = [
    "COMPRESSIONS",
    "DEFAULT_COMPRESSION",
    "compression_kwargs",
    "FORMAT_VERSION",
    "KNOWN_SENSOR_SIZES",
    "RAW_HEAD_COLUMNS",
    "DatFile",
    "DatWriter",
    "Dataset",
    "H5Writer",
    "Sequence",
    "atomic_path",
    "build_index",
    "dataset_splits",
    "export_sjdd",
    "guess_dat_shape",
    "load_index",
    "open_dat",
    "open_dataset",
    "open_h5",
    "open_source",
    "read_dat",
    "read_h5",
    "read_header",
    "verify",
    "verify_file",
    "resolve_dataset",
    "sequence_labels",
    "write_dat",
    "write_h5",
]
