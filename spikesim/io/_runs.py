"""The chunks of a run (``ss.simulate_chunks``) as the file writers consume them."""

from __future__ import annotations

from collections.abc import Iterable, Iterator

import numpy as np

from spikesim.errors import bad_value

__all__ = ["contiguous_chunks"]


def contiguous_chunks(run: Iterable) -> Iterator:
    """The chunks of ``run`` in order, each checked to start where the previous
    one ended (its ``start`` readout, where it has one)."""
    at = 0
    for chunk in run:
        start = getattr(chunk, "start", at)
        if start != at:
            raise bad_value("chunk.start", start, f"{at} (chunks must be contiguous)")
        yield chunk
        at += int(np.shape(chunk.packed)[0])
