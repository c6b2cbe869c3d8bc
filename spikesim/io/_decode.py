"""Numba kernel that turns PKU ``.dat`` bytes into 0/1 spike frames.

Private: no validation here (the public readers in ``dat.py`` check every
argument).  One kernel serves every case: windowed, cropped, flipped, with
head columns dropped, and rows that do not start on a byte boundary (frames
whose width is not a multiple of 8).  Rows that start on a byte boundary take
a fast path through a 256-entry lookup table (one byte -> eight 0/1 bytes);
the rest fall back to a shift-and-mask per pixel.  When every output row is
byte aligned and a whole number of bytes wide (the usual case: widths 400,
416, 1000), a uint64 table writes eight pixels with one store.  Small
requests run serially, large ones on numba's thread pool (see
``PARALLEL_MIN_PIXELS``).
"""

from __future__ import annotations

import types

import numba as nb
import numpy as np

__all__ = ["LUT", "LUT64", "decode_frames"]

#: Byte value -> its eight bits, LSB first, as 0/1 bytes.
LUT = np.unpackbits(np.arange(256, dtype=np.uint8)[:, None], axis=1, bitorder="little")
#: The same table with each row read as one little-endian uint64 (8 pixels per store).
LUT64 = LUT.astype("<u1").copy().view("<u8").ravel()


#: Requests of at least this many pixel-readouts use numba's thread pool; smaller
#: ones (training windows, previews) run on the calling thread, so that they
#: start no threads (safe to fork afterwards) and suffer no thread contention.
PARALLEL_MIN_PIXELS = 1 << 24


def _aligned(buf, frame_bytes, first, n, height, width, flip, offset, top, out, lut):
    h = out.shape[1]
    nbytes = out.shape[2]
    for job in nb.prange(n * h):
        t = job // h
        y = job - t * h
        row = top + y
        stored = height - 1 - row if flip else row
        p = (first + t) * frame_bytes + (stored * width + offset) // 8
        dst = out[t, y]
        for b in range(nbytes):
            dst[b] = lut[buf[p + b]]


def _generic(buf, frame_bytes, first, n, height, width, flip, head, top, left, out, lut):
    h = out.shape[1]
    w = out.shape[2]
    for job in nb.prange(n * h):
        t = job // h
        y = job - t * h
        row = top + y
        stored = height - 1 - row if flip else row
        bit0 = stored * width + head + left
        base = (first + t) * frame_bytes
        dst = out[t, y]
        if bit0 % 8 == 0:
            p = base + bit0 // 8
            full = w // 8
            for b in range(full):
                v = buf[p + b]
                x = 8 * b
                for k in range(8):
                    dst[x + k] = lut[v, k]
            for x in range(8 * full, w):
                dst[x] = (buf[p + x // 8] >> (x % 8)) & 1
        else:
            for x in range(w):
                k = bit0 + x
                dst[x] = (buf[base + k // 8] >> (k % 8)) & 1


def _jit(fn, name: str, parallel: bool):
    """Compile ``fn`` under its own name (numba's on-disk cache is keyed by name)."""
    clone = types.FunctionType(fn.__code__, fn.__globals__, name, fn.__defaults__)
    clone.__qualname__ = name
    return nb.njit(parallel=parallel, cache=True, nogil=True, boundscheck=False)(clone)


_aligned_serial = _jit(_aligned, "_aligned_serial", False)
_aligned_parallel = _jit(_aligned, "_aligned_parallel", True)
_generic_serial = _jit(_generic, "_generic_serial", False)
_generic_parallel = _jit(_generic, "_generic_parallel", True)


def decode_frames(
    buf: np.ndarray,
    frame_bytes: int,
    first: int,
    n: int,
    height: int,
    width: int,
    flip: bool,
    head: int,
    top: int,
    left: int,
    h: int,
    w: int,
) -> np.ndarray:
    """Decode frames ``first .. first+n-1`` of a flat byte buffer into (n, h, w) uint8.

    ``height``/``width`` are the stored frame size (head columns included);
    ``top``/``left`` locate the crop in the output orientation (after the flip
    and after dropping ``head`` columns).
    """
    parallel = n * h * w >= PARALLEL_MIN_PIXELS
    if width % 8 == 0 and (head + left) % 8 == 0 and w % 8 == 0 and np.little_endian:
        out64 = np.empty((n, h, w // 8), np.uint64)
        if n and h and w:
            kernel = _aligned_parallel if parallel else _aligned_serial
            kernel(buf, frame_bytes, first, n, height, width, flip, head + left, top, out64, LUT64)
        return out64.view(np.uint8)
    out = np.empty((n, h, w), np.uint8)
    if n and h and w:
        kernel = _generic_parallel if parallel else _generic_serial
        kernel(buf, frame_bytes, first, n, height, width, flip, head, top, left, out, LUT)
    return out
