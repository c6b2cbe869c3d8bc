"""Fixtures shared by the spikesim tests (I/O and commands): small random streams shaped like
``SpikeStream``."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest


def fake_stream(n=50, height=6, width=13, cfa="RGGB", clean=False, seed=0, rate=0.3,
                gt_index=(5, 25), noise=None):
    """A ``SpikeStream``-like object from random bits (independent of the simulator)."""
    rng = np.random.default_rng(seed)
    bits = (rng.random((n, height, width)) < rate).astype(np.uint8)
    packed = np.packbits(bits, axis=-1, bitorder="little")
    clean_packed = None
    if clean:
        cbits = (rng.random((n, height, width)) < rate).astype(np.uint8)
        clean_packed = np.packbits(cbits, axis=-1, bitorder="little")
    gt_index = np.asarray(gt_index, np.int64)
    gt = rng.random((len(gt_index), height, width, 3)).astype(np.float32)
    meta = {
        "height": height, "width": width, "cfa": cfa, "clock_hz": 20000.0, "seed": seed,
        "n_readouts": n, "start_readout": 0, "clean_twin": clean, "bitorder": "little",
        "sensor": {"height": height, "width": width, "cfa": cfa, "full_scale_rate": 0.6,
                   "noise": noise},
        "scene": {"type": "random-bits", "rate": rate},
    }
    return SimpleNamespace(packed=packed, clean_packed=clean_packed, gt=gt, gt_index=gt_index,
                           meta=meta, height=height, width=width, n_readouts=n, bits=bits)


def fake_run(stream, chunk=16):
    """The stream as a ``simulate_chunks``-like run (an iterable of chunks with ``.meta``)."""

    class Run:
        meta = stream.meta

        def __iter__(self):
            for t in range(0, stream.packed.shape[0], chunk):
                sel = (stream.gt_index >= t) & (stream.gt_index < t + chunk)
                yield SimpleNamespace(
                    start=t, packed=stream.packed[t:t + chunk],
                    clean_packed=None if stream.clean_packed is None
                    else stream.clean_packed[t:t + chunk],
                    gt=stream.gt[sel], gt_index=stream.gt_index[sel],
                )

    return Run()


@pytest.fixture
def make_stream():
    return fake_stream


@pytest.fixture
def make_run():
    return fake_run
