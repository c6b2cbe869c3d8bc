"""Bit packing of spike frames (docs/architecture.md, Conventions).

Spikes are packed along the width axis with *little* bit order: pixel ``x`` of a
row lives in byte ``x // 8``, bit ``x % 8`` (LSB first), ``ceil(W/8)`` bytes per
row, padding bits zero.  This is ``np.packbits(..., axis=-1, bitorder="little")``.
"""

from __future__ import annotations

import numpy as np

from spikesim.errors import SpikeSimTypeError, bad_value

__all__ = ["packed_width", "pack", "unpack", "crop_packed"]


def packed_width(width: int) -> int:
    """Bytes per packed row for ``width`` pixels: ``ceil(width / 8)``."""
    return (int(width) + 7) // 8


def pack(spikes: np.ndarray) -> np.ndarray:
    """Pack a (..., W) array of 0/1 values into (..., ceil(W/8)) uint8, little bit order."""
    spikes = np.asarray(spikes)
    if spikes.ndim < 1:
        raise SpikeSimTypeError("spikes must have at least one dimension (..., W)")
    if spikes.dtype != np.bool_ and spikes.size and (spikes.min() < 0 or spikes.max() > 1):
        raise bad_value("spikes", f"values in [{spikes.min()}, {spikes.max()}]", "0/1 values")
    return np.packbits(spikes.astype(bool, copy=False), axis=-1, bitorder="little")


def unpack(packed: np.ndarray, width: int) -> np.ndarray:
    """Unpack (..., ceil(W/8)) uint8 into (..., W) uint8 0/1 (little bit order)."""
    packed = np.asarray(packed)
    if packed.dtype != np.uint8:
        raise SpikeSimTypeError(f"packed must be uint8, got {packed.dtype}")
    if packed.shape[-1] != packed_width(width):
        raise bad_value(
            "packed.shape[-1]", packed.shape[-1], f"ceil(width/8) = {packed_width(width)}"
        )
    return np.unpackbits(packed, axis=-1, count=int(width), bitorder="little")


def crop_packed(packed: np.ndarray, bit_offset: int, width: int, unpack: bool) -> np.ndarray:
    """Cut ``width`` pixels starting at bit ``bit_offset`` out of packed rows.

    ``packed`` is (..., nbytes) little bit order, already sliced to the bytes
    that hold the crop.  Returns 0/1 bytes (``unpack=True``) or re-packed bits
    with zero padding.
    """
    if bit_offset == 0 and not unpack:
        out = np.ascontiguousarray(packed[..., : (width + 7) // 8])
        if width % 8:
            out[..., -1] &= np.uint8((1 << (width % 8)) - 1)
        return out
    bits = np.unpackbits(packed, axis=-1, count=bit_offset + width, bitorder="little")
    bits = bits[..., bit_offset:]
    if unpack:
        return np.ascontiguousarray(bits)
    return np.packbits(bits, axis=-1, bitorder="little")
