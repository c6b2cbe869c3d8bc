"""Compression choices for the HDF5 spike datasets.

A choice is a string ``NAME`` or ``NAME:LEVEL``:

* ``none``: no filter (fastest; packed bits of a noisy stream barely compress);
* ``gzip[:1-9]``: deflate, built into every HDF5, readable by any tool
  (default level 1: higher levels cost much time for a few percent);
* ``lz4``: very fast, needs ``hdf5plugin`` (``pip install spikesim[fast]``)
  to write *and* to read;
* ``zstd[:1-22]``: better ratio than gzip at a higher speed, needs
  ``hdf5plugin`` likewise (default level 3).

The measured trade-off behind :data:`DEFAULT_COMPRESSION` is in ``docs/io.md``
and ``benchmarks/results/io.md`` (``benchmarks/bench_io.py``): on a
1000x1000 Bayer stream Zstd level 1 stores the packed bits 1.66-1.74x smaller
at 0.7-1.4e9 pixel-readouts/s, far faster than the simulator makes moving
scenes, while gzip reaches 1.54-1.61x at only 0.11-0.22e9/s, and higher
levels of either buy ~1% for half the speed.  So the default is ``zstd:1`` where
hdf5plugin is installed and ``gzip:1`` (readable everywhere) where it is not.
"""

from __future__ import annotations

from spikesim.errors import bad_value

__all__ = ["COMPRESSIONS", "DEFAULT_COMPRESSION", "compression_kwargs", "have_hdf5plugin"]

COMPRESSIONS: tuple[str, ...] = ("none", "gzip", "lz4", "zstd")

_LEVELS = {"gzip": (1, 9, 1), "zstd": (1, 22, 3)}


def have_hdf5plugin() -> bool:
    """True when ``hdf5plugin`` imports (it registers the LZ4/Zstd filters)."""
    try:
        import hdf5plugin  # noqa: F401
    except ImportError:
        return False
    return True


#: ``zstd:1`` with hdf5plugin, else ``gzip:1`` (see the module docstring).
DEFAULT_COMPRESSION = "zstd:1" if have_hdf5plugin() else "gzip:1"


def compression_kwargs(spec: str | None) -> dict:
    """h5py ``create_dataset`` keyword arguments for a compression choice."""
    if spec is None:
        spec = "none"
    if not isinstance(spec, str):
        raise bad_value("compression", spec, f"one of {COMPRESSIONS}, optionally 'name:level'")
    name, _, level_text = spec.strip().lower().partition(":")
    if name not in COMPRESSIONS:
        raise bad_value("compression", spec, f"one of {COMPRESSIONS}, optionally 'name:level'")
    level = None
    if level_text:
        if name not in _LEVELS:
            raise bad_value("compression", spec, f"'{name}' without a level")
        low, high, _ = _LEVELS[name]
        if not level_text.isdigit() or not low <= int(level_text) <= high:
            raise bad_value("compression level", level_text, f"an integer in [{low}, {high}]")
        level = int(level_text)
    elif name in _LEVELS:
        level = _LEVELS[name][2]
    if name == "none":
        return {}
    if name == "gzip":
        return {"compression": "gzip", "compression_opts": level}
    if not have_hdf5plugin():
        raise bad_value(
            "compression", spec,
            "'none' or 'gzip' (LZ4 and Zstd need hdf5plugin: pip install 'spikesim[fast]')",
        )
    import hdf5plugin

    if name == "lz4":
        return dict(hdf5plugin.LZ4())
    return dict(hdf5plugin.Zstd(clevel=level))
