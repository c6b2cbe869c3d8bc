"""Real captures (PKU ``.dat``): windows of readouts with their Bayer phase.

:class:`Capture` wraps :class:`spikesim.io.dat.DatFile` (memory-mapped, no
open descriptor, so it pickles into spawned workers) and adds what
reconstruction needs: the CFA pattern and a window centred on a readout.
:class:`CaptureWindows` is the matching torch ``Dataset`` (no ground truth).
"""

from __future__ import annotations

import os

import numpy as np
from torch.utils.data import Dataset

from spikejdd.data import make_sample
from spikesim.cfa import cfa_after_crop, normalize_cfa
from spikesim.errors import bad_value
from spikesim.estimate import window_bounds

__all__ = ["Capture", "CaptureWindows"]


class Capture:
    """A ``.dat`` capture with a CFA pattern.

    Parameters
    ----------
    path : path
        The ``.dat`` file.
    height, width : int
        Stored frame size (width including head columns).
    cfa : str or None
        Bayer pattern of the full frame (after the flip), e.g. ``"RGGB"``; None = mono.
    flip : bool
        Stored upside down (PKU convention, default True).
    head_columns : int
        Columns to drop at the start of each stored row (16 for raw 416-wide).
    """

    def __init__(self, path: str | os.PathLike, height: int, width: int, cfa: str | None = "RGGB",
                 flip: bool = True, head_columns: int = 0):
        from spikesim.io.dat import open_dat

        self.cfa = normalize_cfa(cfa)
        self.dat = open_dat(path, height, width, flip=flip, head_columns=head_columns)

    @property
    def height(self) -> int:
        return self.dat.height

    @property
    def width(self) -> int:
        return self.dat.width

    @property
    def n_readouts(self) -> int:
        return self.dat.n_readouts

    def window(
        self, center: int, length: int = 41, crop: tuple[int, int, int, int] | None = None
    ) -> tuple[np.ndarray, str | None]:
        """``(spikes, cfa)``: (length, h, w) uint8 0/1 around ``center`` and the crop's pattern.

        The window is placed as in :func:`spikesim.estimate.window_bounds`
        (shifted inside the stream near its ends).
        """
        start, _ = window_bounds(self.n_readouts, center, length)
        spikes = self.dat.read_window(start, length, crop=crop)
        top, left = (0, 0) if crop is None else (int(crop[0]), int(crop[1]))
        return spikes, cfa_after_crop(self.cfa, top, left)


class CaptureWindows(Dataset):
    """Torch dataset of windows from a capture (deterministic; no ground truth).

    Samples hold ``spikes`` (window, h, w) float32 (or packed uint8),
    ``mask`` (4, h, w) and ``meta`` (readout, cfa, crop offsets).
    """

    def __init__(self, capture: Capture, centers=None, window: int = 39,
                 crop: tuple[int, int, int, int] | None = None, packed: bool = False):
        if capture.cfa is None:
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
            self.capture.dat.read_window, self.capture.cfa, self.capture.height,
            self.capture.width, c - self.window // 2, self.window, self.crop, False, False,
            self.packed,
        )
        sample["meta"] = {"readout": c, "cfa": pattern, "top": self.crop[0],
                          "left": self.crop[1], "width": self.crop[3]}
        return sample


