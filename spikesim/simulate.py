"""Drive the kernel over chunks of readouts: ``simulate`` and ``simulate_chunks``.

The driver asks the scene for radiance at its key times, samples it through the
colour filter, builds the readout schedule (``spikesim.schedule``), and runs
``spikesim._kernels.simulate_chunk`` chunk by chunk, carrying the accumulator
from one chunk to the next.  Memory is bounded by one chunk of packed bits plus
the key frames it needs, so streams of any length run in bounded memory.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np

from spikesim import _kernels, rng
from spikesim._version import __version__
from spikesim.bits import packed_width, unpack
from spikesim.cfa import LUMA_WEIGHTS, channel_index
from spikesim.errors import SpikeSimTypeError, bad_value
from spikesim.noise import PaperNoise, PhysicalNoise, fixed_pattern
from spikesim.scenes.static import validate_radiance
from spikesim.schedule import build_schedule, key_readout_times
from spikesim.sensor import Sensor
from spikesim.workload import check_key_frames

__all__ = ["SpikeStream", "SpikeChunk", "SimulationRun", "simulate", "simulate_chunks"]

#: Budget for the packed output of one chunk (bytes) when the caller gives no size.
CHUNK_OUTPUT_BYTES = 32 << 20
#: Budget for the key frames held for one chunk (bytes).
CHUNK_KEYFRAME_BYTES = 256 << 20
if sys.byteorder != "little":  # pragma: no cover - every supported target is little-endian
    raise ImportError("spikesim's kernel writes packed bits as little-endian 64-bit words")
_RESET_CODES = {"modulo": _kernels.RESET_MODULO, "subtract": _kernels.RESET_SUBTRACT,
                "zero": _kernels.RESET_ZERO}


@dataclass
class SpikeChunk:
    """Consecutive readouts ``[start, start + len(packed))`` of a simulation."""

    start: int
    packed: np.ndarray
    clean_packed: np.ndarray | None
    gt: np.ndarray
    gt_index: np.ndarray


@dataclass
class SpikeStream:
    """A simulated (or loaded) spike stream with its ground truth and metadata.

    Attributes
    ----------
    packed : (T, H, ceil(W/8)) uint8
        Spike bits, packed along W, little bit order (DESIGN.md §3).
    meta : dict
        JSON-able description: sensor, scene, seed, clock_hz, cfa, height,
        width, n_readouts, start_readout, clean_twin, spikesim_version, bitorder.
    clean_packed : same shape as ``packed`` or None
        The noise-free twin (same seed and initial state, every noise source off).
    gt : (K, H, W, 3) float32
        Linear RGB radiance at the middle of readouts ``gt_index``.
    gt_index : (K,) int64
        Readout index of each ground-truth frame.
    """

    packed: np.ndarray
    meta: dict
    clean_packed: np.ndarray | None = None
    gt: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0, 3), np.float32))
    gt_index: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    @property
    def n_readouts(self) -> int:
        return int(self.packed.shape[0])

    @property
    def height(self) -> int:
        return int(self.meta["height"])

    @property
    def width(self) -> int:
        return int(self.meta["width"])

    @property
    def cfa(self) -> str | None:
        return self.meta.get("cfa")

    @property
    def clock_hz(self) -> float:
        return float(self.meta["clock_hz"])

    @property
    def seed(self) -> int:
        return int(self.meta["seed"])

    @property
    def sensor(self) -> Sensor:
        return Sensor.from_dict(self.meta["sensor"])

    def unpack(self, clean: bool = False, start: int = 0, stop: int | None = None) -> np.ndarray:
        """(T, H, W) uint8 0/1 spikes of readouts ``[start, stop)``."""
        src = self.clean_packed if clean else self.packed
        if src is None:
            raise bad_value("clean", clean, "False: this stream has no clean twin")
        return unpack(src[start:stop], self.width)

    def firing_rate(self, clean: bool = False) -> np.ndarray:
        """(H, W) mean spikes per readout of each pixel."""
        counts = np.zeros((self.height, self.width), np.int64)
        for s in range(0, self.n_readouts, 256):
            counts += self.unpack(clean, s, s + 256).sum(axis=0, dtype=np.int64)
        return counts / max(self.n_readouts, 1)


def _check_int(name: str, value, low: int, high: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise bad_value(name, value, f"an integer >= {low}")
    v = int(value)
    if v < low or (high is not None and v > high):
        rng_text = f"an integer in [{low}, {high}]" if high is not None else f"an integer >= {low}"
        raise bad_value(name, value, rng_text)
    return v


class SimulationRun:
    """An iterable of :class:`SpikeChunk` for one configured simulation.

    Iterating starts from the initial state each time, so a run can be
    consumed more than once with identical results.  ``meta`` is known before
    the first chunk (writers use it to create their files).
    """

    def __init__(self, scene, sensor: Sensor, n_readouts: int, seed: int = 0,
                 clean_twin: bool = False, gt_readouts: Sequence[int] | None = None,
                 chunk_readouts: int | None = None, progress: bool = False):
        if not isinstance(sensor, Sensor):
            raise SpikeSimTypeError(
                f"sensor must be a spikesim.Sensor, got {type(sensor).__name__}")
        for attr in ("radiance", "key_times", "height", "width", "describe"):
            if not hasattr(scene, attr):
                raise SpikeSimTypeError(
                    f"scene must implement the scene protocol (missing {attr!r}); "
                    "wrap an image with spikesim.scenes.Static(image)"
                )
        if (scene.height, scene.width) != sensor.shape:
            raise bad_value("scene size", (scene.height, scene.width),
                            f"the sensor size (height, width) = {sensor.shape}")
        self.scene = scene
        self.sensor = sensor
        self.n_readouts = _check_int("n_readouts", n_readouts, 1)
        check_key_frames(scene, self.n_readouts / sensor.clock_hz)
        self.seed = _check_int("seed", seed, 0, 2**64 - 1)
        self.clean_twin = bool(clean_twin)
        if gt_readouts is None:
            gt = [self.n_readouts // 2]
        elif isinstance(gt_readouts, str) and gt_readouts == "all":
            gt = list(range(self.n_readouts))
        else:
            gt = [_check_int("gt_readouts[i]", g, 0, self.n_readouts - 1) for g in gt_readouts]
        self.gt_readouts = np.array(sorted(set(gt)), dtype=np.int64)
        nbytes = packed_width(sensor.width)
        if chunk_readouts is None:
            per_readout = sensor.height * nbytes * (2 if self.clean_twin else 1)
            chunk_readouts = max(16, min(4096, CHUNK_OUTPUT_BYTES // max(per_readout, 1)))
        self.chunk_readouts = _check_int("chunk_readouts", chunk_readouts, 1)
        self.progress = bool(progress)
        idx = channel_index(sensor.cfa, 2, 2)
        self._tile = np.full((2, 2), -1, np.int64) if idx is None else idx.astype(np.int64)
        self.meta = {
            "sensor": sensor.to_dict(),
            "scene": scene.describe(),
            "seed": self.seed,
            "clock_hz": sensor.clock_hz,
            "cfa": sensor.cfa,
            "height": sensor.height,
            "width": sensor.width,
            "n_readouts": self.n_readouts,
            "start_readout": 0,
            "clean_twin": self.clean_twin,
            "gt_index": self.gt_readouts.tolist(),
            "spikesim_version": __version__,
            "bitorder": "little",
        }

    def __len__(self) -> int:
        """Number of readouts (not chunks)."""
        return self.n_readouts

    # -- helpers -----------------------------------------------------------
    def _sensor_frame_into(self, t: float, out: np.ndarray, k: int) -> None:
        """Radiance at ``t`` through the CFA into key ``k`` of ``out`` (the
        kernel's blocked key-frame layout), validated."""
        rad = np.asarray(self.scene.radiance(t))
        name = f"scene.radiance(t={t:.6g})"
        if rad.shape != (*self.sensor.shape, 3) or rad.dtype.kind != "f":
            rad = validate_radiance(rad, name)  # converts (H, W) / integer input, or raises
            if rad.shape[:2] != self.sensor.shape:
                raise bad_value(f"{name}.shape", rad.shape,
                                f"({self.sensor.height}, {self.sensor.width}, 3)")
        if not rad.flags.c_contiguous:
            rad = np.ascontiguousarray(rad)
        if _kernels.mosaic_into(rad, self._tile, LUMA_WEIGHTS, out, k) > 0:
            validate_radiance(rad, name)  # raises with the offending value

    def _padded(self, arr: np.ndarray, fill: float, dtype) -> np.ndarray:
        h, w = arr.shape
        wp = _padded_width(w)
        out = np.full((h, wp), fill, dtype=dtype)
        out[:, :w] = arr
        return out

    def __iter__(self) -> Iterator[SpikeChunk]:
        sensor = self.sensor
        h, w = sensor.shape
        wp = _padded_width(w)
        nbytes = packed_width(w)
        noise = sensor.noise
        clock = sensor.clock_hz

        pattern = fixed_pattern(noise, h, w, sensor.full_scale_rate)
        gain = self._padded(pattern.gain, 0.0, np.float64)
        offset = self._padded(pattern.offset, 0.0, np.float64)
        if pattern.electrons is not None:
            electrons = self._padded(pattern.electrons, 1.0, np.float64)
        else:
            electrons = np.full((h, wp), -1.0)
        sg2 = sp2 = jitter = 0.0
        if isinstance(noise, PaperNoise):
            sg2, sp2 = noise.sigma_g**2, noise.sigma_p**2
        if isinstance(noise, PhysicalNoise):
            jitter = noise.temporal_threshold_noise
        per_readout = noise is not None and noise.per_readout
        reset = _RESET_CODES[sensor.reset]
        fast_ok = reset == _kernels.RESET_MODULO and not per_readout
        paper_fast_ok = (reset == _kernels.RESET_MODULO and isinstance(noise, PaperNoise)
                         and pattern.electrons is None and jitter == 0.0)

        key = lambda stream: rng.stream_key(self.seed, stream)  # noqa: E731
        frac = _kernels.init_state(key(rng.STREAM_INIT), h, w, wp, sensor.init == "uniform")
        whole = np.zeros((h, wp), np.int64)
        if self.clean_twin:
            c_frac, c_whole = frac.copy(), whole.copy()
            c_gain = self._padded(np.full((h, w), sensor.full_scale_rate), 0.0, np.float64)
            c_offset = np.zeros((h, wp))
            c_electrons = np.full((h, wp), -1.0)
        else:
            c_frac = np.zeros((1, 64), np.uint64)
            c_whole = np.zeros((1, 64), np.int64)
            c_gain = c_offset = c_electrons = np.zeros((1, 64))
        dummy_out = np.zeros((1, 1, 1), np.uint64)

        cache: dict[float, np.ndarray] = {}
        bar = None
        if self.progress:
            from tqdm.auto import tqdm

            bar = tqdm(total=self.n_readouts, unit="readout", desc="simulate")
        frame_bytes = h * wp * 4
        max_keys = max(2, CHUNK_KEYFRAME_BYTES // frame_bytes)
        key_buffer = np.zeros((h, wp // 64, 0, 64), np.float32)
        buffers = _RecycledOutput()
        try:
            n0 = 0
            while n0 < self.n_readouts:
                n1 = min(self.n_readouts, n0 + self.chunk_readouts)
                times = np.asarray(self.scene.key_times(n0 / clock, n1 / clock), np.float64)
                tau = key_readout_times(times, clock)
                while len(tau) > max_keys and n1 - n0 > 1:
                    n1 = n0 + max(1, (n1 - n0) // 2)
                    times = np.asarray(self.scene.key_times(n0 / clock, n1 / clock), np.float64)
                    tau = key_readout_times(times, clock)
                if key_buffer.shape[2] < len(times):
                    # reused by later chunks (no new page faults), with a little room for
                    # a chunk with more keys; padding lanes stay 0 (never written)
                    room = max(len(times), min(max_keys, len(times) + len(times) // 4 + 1))
                    key_buffer = np.zeros((h, wp // 64, room, 64), np.float32)
                for i, t in enumerate(times.tolist()):
                    if t in cache:
                        key_buffer[:, :, i] = cache[t]
                    else:
                        self._sensor_frame_into(t, key_buffer, i)
                # the next chunk starts at this chunk's last key frame
                cache = {times[-1].item(): key_buffer[:, :, len(times) - 1].copy()}
                sched = build_schedule(tau, n0, n1)
                # rows padded to whole 64-bit words; the kernel writes every word
                out = buffers.get((n1 - n0, h, wp // 64))
                c_out = buffers.get(out.shape) if self.clean_twin else dummy_out
                _kernels.simulate_chunk(
                    key_buffer, w, n0, *sched.kernel_args(), gain, offset, electrons, frac, whole,
                    out, reset, fast_ok, paper_fast_ok, sg2, sp2, key(rng.STREAM_PAPER),
                    key(rng.STREAM_SHOT), jitter, key(rng.STREAM_JITTER), self.clean_twin,
                    c_frac, c_whole, c_out,
                    c_gain, c_offset, c_electrons,
                )
                sel = self.gt_readouts[(self.gt_readouts >= n0) & (self.gt_readouts < n1)]
                gt = np.zeros((len(sel), h, w, 3), np.float32)
                for i, g in enumerate(sel.tolist()):
                    gt[i] = validate_radiance(self.scene.radiance((g + 0.5) / clock),
                                              f"scene.radiance(t={(g + 0.5) / clock:.6g})")
                packed = out.view(np.uint8)[:, :, :nbytes]
                c_packed = c_out.view(np.uint8)[:, :, :nbytes] if self.clean_twin else None
                yield SpikeChunk(n0, packed, c_packed, gt, sel.copy())
                out = c_out = packed = c_packed = None  # only the consumer may hold them now
                if bar is not None:
                    bar.update(n1 - n0)
                n0 = n1
        finally:
            if bar is not None:
                bar.close()


class _RecycledOutput:
    """Output arrays for successive chunks, reused once the consumer lets go.

    A fresh array of tens of MB costs about 10 ms of page faults on first
    touch (measured on the 2-core VM), a sizeable share of a chunk's kernel
    time.  A consumer that drops each chunk before asking for the next (the
    streaming case: writing to a file, reducing) gets the same memory back;
    an array still referenced anywhere else (a kept chunk, or any view of
    it) is never handed out again.  At most ``keep`` arrays are remembered
    (four: a stream and its clean twin, for the chunk a `for` loop still
    holds and the one before).
    """

    def __init__(self, keep: int = 4):
        self.keep = keep
        self._arrays: list[np.ndarray] = []

    def get(self, shape: tuple[int, ...]) -> np.ndarray:
        for i in range(len(self._arrays)):
            # references: the list entry and getrefcount's argument, nothing else
            if self._arrays[i].shape == shape and sys.getrefcount(self._arrays[i]) == 2:
                return self._arrays[i]
        fresh = np.empty(shape, np.uint64)
        self._arrays = [*self._arrays[-(self.keep - 1):], fresh] if self.keep > 1 else [fresh]
        return fresh


def _padded_width(width: int) -> int:
    return _kernels.BLOCK * math.ceil(width / _kernels.BLOCK)


def simulate_chunks(scene, sensor: Sensor, n_readouts: int, seed: int = 0,
                    clean_twin: bool = False, gt_readouts: Sequence[int] | str | None = None,
                    chunk_readouts: int | None = 256, progress: bool = False) -> SimulationRun:
    """Configure a simulation whose chunks are produced lazily (see :class:`SimulationRun`)."""
    return SimulationRun(scene, sensor, n_readouts, seed, clean_twin, gt_readouts,
                         chunk_readouts, progress)


def simulate(scene, sensor: Sensor, n_readouts: int, seed: int = 0, clean_twin: bool = False,
             gt_readouts: Sequence[int] | str | None = None, chunk_readouts: int | None = None,
             progress: bool = False) -> SpikeStream:
    """Simulate ``n_readouts`` readouts of ``sensor`` looking at ``scene``.

    Parameters
    ----------
    scene : scene object
        Anything with the scene protocol (``spikesim.scenes``); an image can
        be wrapped with ``spikesim.scenes.Static(image)``.
    sensor : Sensor
        Geometry, clock, reset mode and noise.
    n_readouts : int
        Number of readouts (the stream lasts ``n_readouts / clock_hz`` seconds).
    seed : int
        Seed of every random draw (initial accumulator and temporal noise).
    clean_twin : bool
        Also produce the noise-free twin in the same pass.
    gt_readouts : sequence of int, "all", or None
        Readouts at which ground-truth radiance is recorded (default: the
        middle readout ``n_readouts // 2``).
    chunk_readouts : int, optional
        Readouts per chunk (memory bound); results do not depend on it.
    progress : bool
        Show a progress bar.

    Returns
    -------
    SpikeStream
    """
    run = SimulationRun(scene, sensor, n_readouts, seed, clean_twin, gt_readouts,
                        chunk_readouts, progress)
    h, nb = sensor.height, packed_width(sensor.width)
    packed = np.empty((run.n_readouts, h, nb), np.uint8)
    clean = np.empty_like(packed) if run.clean_twin else None
    gts, idx = [], []
    for chunk in run:
        sl = slice(chunk.start, chunk.start + chunk.packed.shape[0])
        packed[sl] = chunk.packed
        if clean is not None:
            clean[sl] = chunk.clean_packed
        gts.append(chunk.gt)
        idx.append(chunk.gt_index)
    gt = np.concatenate(gts) if gts else np.zeros((0, h, sensor.width, 3), np.float32)
    return SpikeStream(packed, run.meta, clean, gt, np.concatenate(idx).astype(np.int64))
