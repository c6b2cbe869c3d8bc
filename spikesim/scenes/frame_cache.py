"""A per-process cache of decoded image files, bounded in bytes.

Many clips of one video read the same frames (a dataset cuts several clips
from each video, and consecutive clips overlap), and decoding a 720p PNG costs
tens of milliseconds.  :func:`read_image` keeps the most recently decoded
files of this process, keyed by path, modification time and size (a file
rewritten in place is decoded again), and hands out read-only arrays: a hit
returns exactly the array a decode would (same values, shape and dtype).
"""

from __future__ import annotations

import os
import threading
from collections import OrderedDict
from collections.abc import Callable

import numpy as np

__all__ = ["CACHE_BYTES", "read_image", "clear", "cached_bytes", "decodes"]

#: Largest total size of the decoded frames kept per process (about 45 720p RGB frames).
CACHE_BYTES = 128 * 2**20

_lock = threading.Lock()
_images: OrderedDict[tuple, np.ndarray] = OrderedDict()
_total = 0
_decodes = 0


def read_image(path: str, decode: Callable[[str], np.ndarray]) -> np.ndarray:
    """``decode(path)`` made read-only, or the array kept from an earlier decode of it."""
    global _total, _decodes
    st = os.stat(path)
    key = (path, st.st_mtime_ns, st.st_size)
    with _lock:
        hit = _images.get(key)
        if hit is not None:
            _images.move_to_end(key)
            return hit
    img = decode(path)
    img.setflags(write=False)
    with _lock:
        _decodes += 1
    if img.nbytes > CACHE_BYTES:
        return img
    with _lock:
        if key not in _images:
            _images[key] = img
            _total += img.nbytes
        while _total > CACHE_BYTES:
            _, old = _images.popitem(last=False)
            _total -= old.nbytes
    return img


def decodes() -> int:
    """Files this process has decoded so far (cache misses; never reset)."""
    return _decodes


def cached_bytes() -> int:
    """Bytes of decoded frames held now."""
    return _total


def clear() -> None:
    """Forget every decoded frame."""
    global _total
    with _lock:
        _images.clear()
        _total = 0
