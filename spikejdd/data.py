"""Torch datasets over spikesim files: training windows with their Bayer masks.

Each sample of :class:`SpikeWindowDataset` is a dict

* ``spikes`` — (window, h, w) float32 0/1, or (window, h, ceil(w/8)) uint8
  packed bits (little bit order) with ``packed=True``; unpack on the
  consumer's device with :func:`unpack_spikes`;
* ``mask`` — (4, h, w) float32 Bayer planes ``[R, G1, G2, B]`` of the sample
  *as delivered* (after crop and flips), G1 = green on the red row;
* ``gt`` — (3, h, w) float32 linear RGB for the centre readout;
* ``meta`` — sequence name, readout index, crop offsets, flips, the CFA name
  of the delivered sample, noise mode and level (``noise``, ``sigma_g``,
  ``sigma_p`` in 8-bit DN), ``rate`` (full_scale_rate) and ``width``.

The window of ``window`` readouts is ``[g - window//2, g - window//2 + window)``
for a ground-truth readout ``g`` (centred in time for odd windows); GT
readouts whose window would leave the stream are not sampled.

Training mode draws a crop at **any** offset (odd ones included; the mask
follows the crop's true CFA phase via :func:`spikesim.cfa.cfa_after_crop`)
and random horizontal/vertical flips (applied to spikes, GT and mask alike).
Randomness comes from ``numpy.random.default_rng([seed, epoch, index])``, so
a sample depends only on its index and epoch (:meth:`set_epoch`), never on
the worker that loads it.  Evaluation mode (``train=False``) is deterministic:
the centred crop (or the full frame) and no flips.

Files are opened lazily, once per process, through
:func:`spikesim.io.open_dataset`; the dataset pickles without open handles, so
``DataLoader(num_workers>0)`` works under the spawn start method.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch.utils.data import Dataset

from spikesim.cfa import cfa_after_crop, cfa_after_flip, mask_planes, normalize_cfa
from spikesim.errors import SpikeSimFormatError, SpikeSimTypeError, bad_value

__all__ = [
    "SpikeWindowDataset",
    "unpack_spikes",
    "noise_info",
    "SUPPORTED_FORMAT_VERSIONS",
    "make_sample",
]

#: HDF5 format versions this loader understands (docs/io.md).
SUPPORTED_FORMAT_VERSIONS: tuple[int, ...] = (1, 2)


def unpack_spikes(packed: torch.Tensor, width: int, dtype: torch.dtype = torch.float32):
    """Unpack (..., ceil(width/8)) uint8 little-bit-order spikes to (..., width) on their device."""
    if not isinstance(packed, torch.Tensor) or packed.dtype != torch.uint8:
        raise SpikeSimTypeError("packed must be a torch.uint8 tensor of packed spike bytes")
    nbytes = (int(width) + 7) // 8
    if width < 1 or packed.shape[-1] != nbytes:
        raise bad_value("width", width, f"a width whose ceil(width/8) = {packed.shape[-1]}")
    shifts = torch.arange(8, device=packed.device, dtype=torch.uint8)
    bits = (packed.unsqueeze(-1) >> shifts) & 1
    return bits.reshape(*packed.shape[:-1], nbytes * 8)[..., :width].to(dtype)


def noise_info(meta: dict) -> tuple[str, float, float]:
    """``(mode, sigma_g, sigma_p)`` from a sequence's metadata (mode "none" when off)."""
    sensor = meta.get("sensor") or {}
    noise = sensor.get("noise") if isinstance(sensor, dict) else None
    if not noise:
        return "none", 0.0, 0.0
    mode = str(noise.get("type", "unknown"))
    return mode, float(noise.get("sigma_g", 0.0) or 0.0), float(noise.get("sigma_p", 0.0) or 0.0)


def _size2(value, name: str) -> tuple[int, int] | None:
    if value is None:
        return None
    if isinstance(value, int | np.integer) and not isinstance(value, bool):
        value = (int(value), int(value))
    try:
        h, w = (int(v) for v in value)
    except (TypeError, ValueError):
        raise bad_value(name, value, "None, an int, or (height, width)") from None
    if h < 2 or w < 2:
        raise bad_value(name, value, "at least 2×2 pixels (one Bayer tile)")
    return h, w


def make_sample(
    read_window,
    cfa: str,
    height: int,
    width: int,
    start: int,
    window: int,
    crop: tuple[int, int, int, int],
    hflip: bool,
    vflip: bool,
    packed: bool,
    gt: np.ndarray | None = None,
) -> tuple[dict, str]:
    """Read, crop and flip one window; returns the tensors and the delivered CFA name.

    ``read_window(start, length, crop=...)`` is a sequence's (or a
    :class:`spikesim.io.dat.DatFile`'s) reader; ``gt`` is the full (H, W, 3) frame.
    """
    top, left, h, w = crop
    spikes = np.asarray(read_window(start, window, crop=crop))
    pattern = cfa_after_crop(cfa, top, left)
    mask = mask_planes(pattern, h, w)
    if gt is not None:
        gt = np.asarray(gt, np.float32)[top : top + h, left : left + w]
    if hflip:
        spikes, mask = spikes[..., ::-1], mask[..., ::-1]
        gt = None if gt is None else gt[:, ::-1]
    if vflip:
        spikes, mask = spikes[..., ::-1, :], mask[..., ::-1, :]
        gt = None if gt is None else gt[::-1]
    pattern = cfa_after_flip(pattern, h, w, horizontal=hflip, vertical=vflip)
    if packed:
        s = torch.from_numpy(np.packbits(spikes, axis=-1, bitorder="little"))
    else:
        s = torch.from_numpy(np.ascontiguousarray(spikes, dtype=np.float32))
    out = {"spikes": s, "mask": torch.from_numpy(np.ascontiguousarray(mask))}
    if gt is not None:
        out["gt"] = torch.from_numpy(np.ascontiguousarray(gt.transpose(2, 0, 1)))
    return out, pattern


@dataclass(frozen=True)
class _SeqInfo:
    name: str
    height: int
    width: int
    cfa: str
    n_readouts: int
    noise: tuple[str, float, float]
    rate: float


class SpikeWindowDataset(Dataset):
    """Windows of readouts centred on ground-truth readouts (see module doc).

    Parameters
    ----------
    source : path or dataset object
        A spikesim HDF5 file, split folder or dataset root (opened with
        ``spikesim.io.open_dataset``),
        or an already opened, picklable object with ``names`` and
        ``sequence(name)`` (as returned by ``open_dataset``).
    window : int, default 39
        Readouts per sample (SJDD-Net uses 39).
    crop : int or (h, w) or None
        Crop size in pixels; ``None`` = full frames (all sequences must then
        share one size to be batched).
    train : bool, default True
        Random crops and flips; ``False`` = deterministic centred crop, no flips.
    flips : bool or None
        Random flips in training mode (default: same as ``train``).
    packed : bool, default False
        Deliver packed bits (8× less to transfer); see :func:`unpack_spikes`.
    seed : int
        Base seed of the crop/flip draws.
    sequences : list of str, optional
        Restrict to these sequence names.
    split : str, optional
        Split folder of a dataset root (``spikesim.io.resolve_dataset``); may be
        left out for a split folder, a file, or a root with one split.
    """

    def __init__(
        self,
        source,
        window: int = 39,
        crop: int | tuple[int, int] | None = None,
        train: bool = True,
        flips: bool | None = None,
        packed: bool = False,
        seed: int = 0,
        sequences: list[str] | None = None,
        split: str | None = None,
    ):
        if isinstance(window, bool) or not isinstance(window, int | np.integer) or window < 1:
            raise bad_value("window", window, "an integer >= 1 readouts")
        self.window = int(window)
        self.crop = _size2(crop, "crop")
        self.train = bool(train)
        self.flips = self.train if flips is None else bool(flips)
        self.packed = bool(packed)
        self.seed = int(seed)
        self.epoch = 0
        if isinstance(source, str | os.PathLike):
            from spikesim.io import resolve_dataset

            self._path: Path | None = resolve_dataset(source, split)
            self._handle = None
        else:
            if not (hasattr(source, "names") and hasattr(source, "sequence")):
                raise SpikeSimTypeError(
                    "source must be a path or an object with .names and .sequence(name), "
                    f"got {type(source).__name__}"
                )
            self._path, self._handle = None, source
        self._pid = os.getpid()
        self._infos, self._samples = self._build_index(sequences)

    # --- index -------------------------------------------------------------
    def _open(self):
        if self._path is None:
            return self._handle
        if self._handle is None or self._pid != os.getpid():
            from spikesim.io import open_dataset

            self._handle = open_dataset(self._path)
            self._pid = os.getpid()
        return self._handle

    def _build_index(self, only):
        ds = self._open()
        names = list(ds.names)
        if only is not None:
            unknown = sorted(set(only) - set(names))
            if unknown:
                raise bad_value("sequences", unknown, f"names in the dataset {names[:10]}")
            names = [n for n in names if n in set(only)]
        infos, samples = {}, []
        half = self.window // 2
        for name in names:
            seq = ds.sequence(name)
            meta = dict(getattr(seq, "meta", {}) or {})
            version = getattr(seq, "format_version", meta.get("format_version"))
            if version is not None and int(version) not in SUPPORTED_FORMAT_VERSIONS:
                raise SpikeSimFormatError(
                    f"sequence {name!r} has format_version={version}; this loader reads "
                    f"{SUPPORTED_FORMAT_VERSIONS} — upgrade spikesim or rebuild the data"
                )
            cfa = normalize_cfa(seq.cfa)
            if cfa is None:
                raise bad_value(f"cfa of sequence {name!r}", seq.cfa, "a Bayer pattern (not mono)")
            if self.window > seq.n_readouts:
                raise bad_value(
                    "window", self.window, f"at most {seq.n_readouts} readouts of {name!r}"
                )
            if self.crop and (self.crop[0] > seq.height or self.crop[1] > seq.width):
                raise bad_value(
                    "crop", self.crop, f"at most the frame size {(seq.height, seq.width)}"
                )
            sensor = meta.get("sensor") or {}
            rate = float(sensor.get("full_scale_rate", 0.6)) if isinstance(sensor, dict) else 0.6
            infos[name] = _SeqInfo(
                name, int(seq.height), int(seq.width), cfa, int(seq.n_readouts),
                noise_info(meta), rate,
            )
            for k, g in enumerate(np.asarray(seq.gt_index, np.int64)):
                start = int(g) - half
                if start >= 0 and start + self.window <= seq.n_readouts:
                    samples.append((name, k, int(g)))
        if not samples:
            raise bad_value(
                "window", self.window, "a window that fits around at least one GT readout"
            )
        if self._path is not None and hasattr(ds, "close"):
            ds.close()
            self._handle = None
        return infos, samples

    # --- torch protocol ----------------------------------------------------
    def __getstate__(self):
        state = self.__dict__.copy()
        if self._path is not None:
            state["_handle"] = None
        return state

    def set_epoch(self, epoch: int) -> None:
        """Change the random crops/flips (training mode) for a new epoch."""
        self.epoch = int(epoch)

    def __len__(self) -> int:
        return len(self._samples)

    def __getitem__(self, index: int) -> dict:
        if not -len(self) <= index < len(self):
            raise IndexError(f"index {index} out of range for {len(self)} samples")
        name, k, g = self._samples[index % len(self)]
        info = self._infos[name]
        seq = self._open().sequence(name)
        h, w = self.crop or (info.height, info.width)
        hflip = vflip = False
        if self.train:
            rng = np.random.default_rng([self.seed, self.epoch, index % len(self)])
            top = int(rng.integers(0, info.height - h + 1))
            left = int(rng.integers(0, info.width - w + 1))
            if self.flips:
                hflip, vflip = bool(rng.integers(2)), bool(rng.integers(2))
        else:
            top, left = (info.height - h) // 2, (info.width - w) // 2
        start = g - self.window // 2
        sample, pattern = make_sample(
            seq.read_window, info.cfa, info.height, info.width, start, self.window,
            (top, left, h, w), hflip, vflip, self.packed, gt=seq.read_gt(k),
        )
        mode, sg, sp = info.noise
        sample["meta"] = {
            "sequence": name, "readout": g, "gt_position": k, "top": top, "left": left,
            "hflip": hflip, "vflip": vflip, "cfa": pattern, "noise": mode, "sigma_g": sg,
            "sigma_p": sp, "rate": info.rate, "width": w,
        }
        return sample
