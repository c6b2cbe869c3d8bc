"""Validation of readout windows and spatial crops, and cropping of packed rows."""

from __future__ import annotations

import numpy as np

from spikesim.errors import bad_value

__all__ = ["check_window", "check_crop", "crop_packed"]


def _is_int(v: object) -> bool:
    return isinstance(v, (int, np.integer)) and not isinstance(v, bool)


def check_window(start: int, length: int | None, n_readouts: int) -> tuple[int, int]:
    """Validate ``start``/``length`` against a stream of ``n_readouts``; ``None`` = to the end."""
    if not _is_int(start) or not 0 <= start < n_readouts:
        raise bad_value("start", start, f"an integer readout index in [0, {n_readouts - 1}]")
    start = int(start)
    if length is None:
        return start, n_readouts - start
    if not _is_int(length) or not 1 <= length <= n_readouts - start:
        raise bad_value(
            "length", length,
            f"an integer in [1, {n_readouts - start}] (the stream has {n_readouts} readouts, "
            f"start={start})",
        )
    return start, int(length)


def check_crop(crop: tuple | None, height: int, width: int) -> tuple[int, int, int, int]:
    """Validate ``crop = (top, left, h, w)`` inside an ``height × width`` frame."""
    if crop is None:
        return 0, 0, height, width
    try:
        top, left, h, w = crop
    except (TypeError, ValueError):
        raise bad_value("crop", crop, "None or (top, left, height, width)") from None
    if not all(_is_int(v) for v in (top, left, h, w)):
        raise bad_value("crop", crop, "four integers (top, left, height, width)")
    if not (0 <= top and 0 <= left and h >= 1 and w >= 1 and top + h <= height
            and left + w <= width):
        raise bad_value(
            "crop", tuple(int(v) for v in crop),
            f"(top, left, height, width) with top+height <= {height}, left+width <= {width}, "
            "all >= 0 and sizes >= 1",
        )
    return int(top), int(left), int(h), int(w)


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
