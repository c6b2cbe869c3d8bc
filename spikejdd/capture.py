"""Windows of real captures (no ground truth) with their Bayer phase.

Any :class:`spikesim.SpikeSource` works: a PKU ``.dat`` opened with
``spikesim.io.open_dat(path, height, width, cfa=...)`` (memory-mapped, no open
descriptor, so it pickles into spawned workers), an HDF5 sequence or an
in-memory stream.  :func:`centred_window` cuts the window reconstruction
needs; :class:`CaptureWindows` is the matching torch ``Dataset``.
"""

from __future__ import annotations

import numpy as np
from torch.utils.data import Dataset

from spikejdd.data import make_sample
from spikesim.cfa import cfa_after_crop, normalize_cfa
from spikesim.errors import bad_value
from spikesim.estimate import window_bounds

__all__ = ["centred_window", "CaptureWindows"]


def centred_window(source, center: int, length: int = 41,
                   crop: tuple[int, int, int, int] | None = None) -> tuple[np.ndarray, str | None]:
    """``(spikes, cfa)``: (length, h, w) uint8 0/1 around ``center`` and the crop's pattern.

    ``source`` is a :class:`spikesim.SpikeSource` whose ``read_window`` takes a
    ``crop`` (``.dat`` captures and HDF5 sequences).  The window is placed as
    in :func:`spikesim.estimate.window_bounds` (shifted inside the stream
    near its ends).
    """
    start, _ = window_bounds(source.n_readouts, center, length)
    spikes = source.read_window(start, length, crop=crop)
    top, left = (0, 0) if crop is None else (int(crop[0]), int(crop[1]))
    return spikes, cfa_after_crop(normalize_cfa(source.cfa), top, left)


class CaptureWindows(Dataset):
    """Torch dataset of windows from a capture (deterministic; no ground truth).

    Samples hold ``spikes`` (window, h, w) float32 (or packed uint8),
    ``mask`` (4, h, w) and ``meta`` (readout, cfa, crop offsets).
    """

    def __init__(self, capture, centers=None, window: int = 39,
                 crop: tuple[int, int, int, int] | None = None, packed: bool = False):
        if normalize_cfa(capture.cfa) is None:
            raise bad_value("capture.cfa", None, "a Bayer pattern for a JDD dataset")
        self.capture, self.window, self.packed = capture, int(window), bool(packed)
        n = capture.n_readouts
        half = self.window // 2
        if centers is None:
            centers = range(half, n - (self.window - half) + 1)
        self.centers = [int(c) for c in centers]
        for c in self.centers:
            if c - half < 0 or c - half + self.window > n:
                raise bad_value("centers", c, f"readouts in [{half}, {n - self.window + half}]")
        if not self.centers:
            raise bad_value("window", window, f"at most the capture length {n}")
        if crop is None:
            crop = (0, 0, capture.height, capture.width)
        self.crop = tuple(int(v) for v in crop)

    def __len__(self) -> int:
        return len(self.centers)

    def __getitem__(self, index: int) -> dict:
        c = self.centers[index]
        sample, pattern = make_sample(
            self.capture.read_window, normalize_cfa(self.capture.cfa), self.capture.height,
            self.capture.width, c - self.window // 2, self.window, self.crop, False, False,
            self.packed,
        )
        sample["meta"] = {"readout": c, "cfa": pattern, "top": self.crop[0],
                          "left": self.crop[1], "width": self.crop[3]}
        return sample


