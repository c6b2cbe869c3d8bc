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
import threading
import weakref
from collections import OrderedDict
from collections.abc import Iterator, Sequence

import numpy as np

from spikesim import _kernels, _mosaic, families, rng
from spikesim._memory import ArrayPool, RecycledOutput
from spikesim._validate import check_flag, check_int
from spikesim._version import __version__
from spikesim.bits import packed_width
from spikesim.cfa import LUMA_WEIGHTS, channel_index
from spikesim.errors import SpikeSimTypeError, bad_value
from spikesim.noise import NO_NOISE_PARAMS, PhysicalNoise, fixed_pattern
from spikesim.scenes.static import validate_grey, validate_radiance
from spikesim.schedule import build_schedule, key_readout_times
from spikesim.sensor import Sensor
from spikesim.stream import SpikeChunk, SpikeStream
from spikesim.workload import check_key_frames, check_stream_memory

__all__ = ["SimulationRun", "simulate", "simulate_chunks"]

#: Budget for the packed output of one chunk (bytes) when the caller gives no size.
CHUNK_OUTPUT_BYTES = 32 << 20
#: Budget for the key frames held for one chunk (bytes).
CHUNK_KEYFRAME_BYTES = 256 << 20
if sys.byteorder != "little":  # pragma: no cover - every supported target is little-endian
    raise ImportError("spikesim's kernel writes packed bits as little-endian 64-bit words")
#: Shot-noise samplers: per spike (``spikesim._event``) or per readout (the
#: original sampler, kept as the statistical tests' reference).
_SHOT_SAMPLERS = ("event", "readout")
#: Arrays private to a run, kept for the next run of the same size (``spikesim._memory``).
_STATE_POOL = ArrayPool(96 << 20)
_KEY_POOL = ArrayPool(64 << 20)
_OUTPUT_POOL = ArrayPool(64 << 20)  # chunk outputs nobody held after the run
_RESET_CODES = {"modulo": _kernels.RESET_MODULO, "subtract": _kernels.RESET_SUBTRACT,
                "zero": _kernels.RESET_ZERO}


class SimulationRun:
    """An iterable of :class:`SpikeChunk` for one configured simulation.

    Iterating starts from the initial state each time, so a run can be
    consumed more than once with identical results.  ``meta`` is known before
    the first chunk (writers use it to create their files).
    """

    def __init__(self, scene, sensor: Sensor, n_readouts: int, seed: int = 0,
                 clean_twin: bool = False, gt_readouts: Sequence[int] | None = None,
                 chunk_readouts: int | None = None, progress: bool = False, *,
                 shot_sampler: str = "event"):
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
        # readout times are float64 seconds and indices int64: exact up to 2**53 (as the CLI)
        self.n_readouts = check_int("n_readouts", n_readouts, 1, 2**53, unit="readouts")
        check_key_frames(scene, self.n_readouts / sensor.clock_hz)
        check_duration = getattr(scene, "check_duration", None)  # optional: a video's end
        if callable(check_duration):
            check_duration(self.n_readouts / sensor.clock_hz)
        self.seed = check_int("seed", seed, 0, 2**64 - 1)
        self.clean_twin = check_flag("clean_twin", clean_twin)
        if gt_readouts is None:
            gt = [self.n_readouts // 2]
        elif isinstance(gt_readouts, str) and gt_readouts == "all":
            gt = list(range(self.n_readouts))
        else:
            gt = [check_int("gt_readouts[i]", g, 0, self.n_readouts - 1) for g in gt_readouts]
        self.gt_readouts = np.array(sorted(set(gt)), dtype=np.int64)
        nbytes = packed_width(sensor.width)
        if chunk_readouts is None:
            per_readout = sensor.height * nbytes * (2 if self.clean_twin else 1)
            chunk_readouts = max(16, min(4096, CHUNK_OUTPUT_BYTES // max(per_readout, 1)))
        self.chunk_readouts = check_int("chunk_readouts", chunk_readouts, 1)
        self.progress = check_flag("progress", progress)
        if shot_sampler not in _SHOT_SAMPLERS:
            raise bad_value("shot_sampler", shot_sampler, f"one of {_SHOT_SAMPLERS}")
        self.shot_sampler = shot_sampler
        idx = channel_index(sensor.cfa, 2, 2)
        self._tile = np.full((2, 2), -1, np.int64) if idx is None else idx.astype(np.int64)
        self._checked: np.ndarray | None = None  # a read-only radiance array known valid
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
    def _grey_at(self, t: float) -> np.ndarray | None:
        """The scene's one-channel radiance at ``t`` (C-contiguous (H, W)
        float32) when it offers one (the optional ``grey`` of the scene
        protocol), else None."""
        grey = getattr(self.scene, "grey", None)
        g = grey(t) if callable(grey) else None
        if g is None:
            return None
        g = np.asarray(g)
        name = f"scene.grey(t={t:.6g})"
        if g.shape != self.sensor.shape:
            raise bad_value(f"{name}.shape", g.shape,
                            f"({self.sensor.height}, {self.sensor.width}), the sensor size")
        if g.dtype != np.float32 or not g.flags.c_contiguous:
            g = validate_grey(g, name)
        return g

    def _remember_if_frozen(self, rad: np.ndarray, out: np.ndarray, k: int) -> None:
        """Remember a read-only float32 frame that owns its data (a static
        scene's image) once it is known valid: the ground truth copies it
        without checking it again, and later runs reuse its sampled key
        frame (``out[:, :, k]``, see :data:`_FROZEN_FRAMES`)."""
        if _is_frozen(rad):
            self._checked = rad
            _remember_frame(rad, self._tile, out[:, :, k])

    def _key_source(self, t: float) -> tuple[np.ndarray | None, np.ndarray]:
        """The scene at ``t``: its grey channel (or None) and the array to sample."""
        grey = self._grey_at(t)
        return grey, (grey if grey is not None else np.asarray(self.scene.radiance(t)))

    def _sensor_frame_into(self, t: float, out: np.ndarray, k: int,
                           source: tuple[np.ndarray | None, np.ndarray] | None = None) -> None:
        """Radiance at ``t`` through the CFA into key ``k`` of ``out`` (the
        kernel's blocked key-frame layout), validated.  A grey frame is
        sampled directly (no three-channel copy); a frozen frame sampled by an
        earlier run is copied from it.  ``source``: :meth:`_key_source`'s
        result when the caller fetched it already."""
        grey, src = source if source is not None else self._key_source(t)
        if _is_frozen(src) and _recall_frame(src, self._tile, out[:, :, k]):
            self._checked = src
            return
        if grey is not None:
            if _mosaic.mosaic_grey_into(grey, out, k) > 0:
                validate_grey(grey, f"scene.grey(t={t:.6g})")  # raises with the offending value
            self._remember_if_frozen(grey, out, k)
            return
        rad = src
        name = f"scene.radiance(t={t:.6g})"
        if rad.shape != (*self.sensor.shape, 3) or rad.dtype.kind != "f":
            rad = validate_radiance(rad, name)  # converts (H, W) / integer input, or raises
            if rad.shape[:2] != self.sensor.shape:
                raise bad_value(f"{name}.shape", rad.shape,
                                f"({self.sensor.height}, {self.sensor.width}, 3)")
        if not rad.flags.c_contiguous:
            rad = np.ascontiguousarray(rad)
        if _mosaic.mosaic_into(rad, self._tile, LUMA_WEIGHTS, out, k) > 0:
            validate_radiance(rad, name)  # raises with the offending value
        self._remember_if_frozen(rad, out, k)

    def _chunk_keys(self, n0: int, max_keys: int) -> tuple[int, np.ndarray, np.ndarray]:
        """End of the chunk starting at readout ``n0``, its key times (s) and the
        same in readouts; the chunk is halved until its key frames fit ``max_keys``."""
        clock = self.sensor.clock_hz
        n1 = min(self.n_readouts, n0 + self.chunk_readouts)
        while True:
            times = np.asarray(self.scene.key_times(n0 / clock, n1 / clock), np.float64)
            tau = key_readout_times(times, clock)
            if len(tau) <= max_keys or n1 - n0 <= 1:
                return n1, times, tau
            n1 = n0 + max(1, (n1 - n0) // 2)

    def _fill_key_frames(self, times: np.ndarray, buffer: np.ndarray, cache: dict,
                         max_keys: int, last: bool = False) -> tuple[np.ndarray, dict]:
        """The chunk's key frames through the CFA into ``buffer`` (grown if
        needed); a frame shared with the previous chunk comes from ``cache``.
        Returns the buffer and the cache for the next chunk (its last frame;
        nothing when this chunk is the ``last``)."""
        h, wp = self.sensor.height, _padded_width(self.sensor.width)
        source = None
        if last and len(times) == 1 and not cache:
            # a run of one chunk and one key frame (a static scene): the frame an
            # earlier run kept is passed to the kernel as it is (it only reads
            # it), saving its copy (0.4 ms at 1000×1000); as a view it is never
            # pooled (ArrayPool keeps only arrays that own their memory)
            source = self._key_source(times[0].item())
            if _is_frozen(source[1]):
                kept = _kept_frame(source[1], self._tile, (h, wp // 64, 64))
                if kept is not None:
                    self._checked = source[1]
                    _KEY_POOL.give(buffer)
                    return kept[:, :, None, :], {}
        if buffer.shape[2] < len(times):
            # reused by later chunks (no new page faults), with a little room for
            # a chunk with more keys; padding lanes stay 0 (never written)
            room = len(times) if last else max(len(times),
                                               min(max_keys, len(times) + len(times) // 4 + 1))
            # padding lanes are 0 in a fresh buffer and in a pooled one (same shape,
            # same padding, never written)
            _KEY_POOL.give(buffer)
            buffer = _KEY_POOL.take((h, wp // 64, room, 64), np.float32, zeros=True)
        for i, t in enumerate(times.tolist()):
            if t in cache:
                buffer[:, :, i] = cache[t]
            else:
                self._sensor_frame_into(t, buffer, i, source)
        if last:
            return buffer, {}
        # the next chunk starts at this chunk's last key frame
        return buffer, {times[-1].item(): buffer[:, :, len(times) - 1].copy()}

    def _ground_truth(self, n0: int, n1: int) -> tuple[np.ndarray, np.ndarray]:
        """Ground-truth radiance (K, H, W, 3) at the requested readouts in ``[n0, n1)``."""
        clock = self.sensor.clock_hz
        sel = self.gt_readouts[(self.gt_readouts >= n0) & (self.gt_readouts < n1)]
        gt = np.empty((len(sel), self.sensor.height, self.sensor.width, 3), np.float32)
        for i, g in enumerate(sel.tolist()):  # (every frame is written)
            t = (g + 0.5) / clock
            grey = self._grey_at(t)
            if grey is not None:
                if grey is not self._checked:
                    validate_grey(grey, f"scene.grey(t={t:.6g})")
                _mosaic.grey_to_rgb_into(grey, gt[i])
                continue
            rad = self.scene.radiance(t)
            if rad is self._checked:  # the read-only frame the key frames just checked
                gt[i] = rad
            else:
                gt[i] = validate_radiance(rad, f"scene.radiance(t={t:.6g})")
        return gt, sel.copy()

    def __iter__(self) -> Iterator[SpikeChunk]:
        return self._chunks()

    def _chunks(self, into: tuple[np.ndarray, np.ndarray | None] | None = None,
                ) -> Iterator[SpikeChunk]:
        """The chunks; with ``into`` (the (T, H, ⌈W/8⌉) uint8 arrays of the whole
        stream and its clean twin) the kernel writes straight into them and each
        chunk's bits are views of them, else into recycled chunk arrays."""
        sensor = self.sensor
        h, w = sensor.shape
        wp = _padded_width(w)
        nbytes = packed_width(w)
        noisy, noisy_state = _kernel_inputs(sensor, self.seed, sensor.noise,
                                            self.shot_sampler == "event", _STATE_POOL)
        clean, clean_state = (_kernel_inputs(sensor, self.seed, None, pool=_STATE_POOL)
                              if self.clean_twin else _unused_inputs())
        family = families.family_of(noisy)  # the noise code the kernel compiles
        paper, event, readout = families.family_markers(family)
        event = noisy.reset if event else None  # the event sampler is compiled per reset mode
        kernel = families.kernel_name(family, noisy.reset)
        families.announce_compile(kernel)
        dummy_out = np.zeros((1, 1, 1), np.uint8)
        init = 1 if sensor.init == "uniform" else 0  # the kernel's first call initialises
        bar = None
        if self.progress:
            from tqdm.auto import tqdm

            bar = tqdm(total=self.n_readouts, unit="readout", desc="simulate")
        max_keys = max(2, CHUNK_KEYFRAME_BYTES // (h * wp * 4))
        key_buffer = np.zeros((h, wp // 64, 0, 64), np.float32)
        cache: dict[float, np.ndarray] = {}
        buffers = RecycledOutput(pool=_OUTPUT_POOL)
        try:
            n0 = 0
            while n0 < self.n_readouts:
                n1, times, tau = self._chunk_keys(n0, max_keys)
                key_buffer, cache = self._fill_key_frames(times, key_buffer, cache, max_keys,
                                                          last=n1 >= self.n_readouts)
                sched = build_schedule(tau, n0, n1)
                # the kernel writes every byte
                if into is not None:
                    out = into[0][n0:n1]
                    c_out = into[1][n0:n1] if self.clean_twin else dummy_out
                else:
                    out = buffers.get((n1 - n0, h, nbytes))
                    c_out = buffers.get(out.shape) if self.clean_twin else dummy_out
                _kernels.simulate_chunk(key_buffer, w, n0, sched, noisy, noisy_state, out, init,
                                        n1 < self.n_readouts,  # keep the state for a next chunk
                                        self.clean_twin, clean, clean_state, c_out, paper,
                                        event, readout)
                if init != -1:
                    families.mark_compiled(kernel)
                init = -1  # later chunks carry the state on
                gt, sel = self._ground_truth(n0, n1)
                yield SpikeChunk(n0, out, c_out if self.clean_twin else None, gt, sel)
                out = c_out = None  # only the consumer may hold them now
                if bar is not None:
                    bar.update(n1 - n0)
                n0 = n1
        finally:
            if bar is not None:
                bar.close()
            _STATE_POOL.give(*noisy_state, *(clean_state if self.clean_twin else ()))
            _KEY_POOL.give(key_buffer)  # never a lent kept frame: it is a view
            buffers.release(_OUTPUT_POOL)


def _kernel_inputs(sensor: Sensor, seed: int, noise, event: bool = True,
                   pool: ArrayPool | None = None,
                   ) -> tuple[_kernels.PixelModel, _kernels.PixelState]:
    """The kernel's model and (uninitialised) state of one accumulator set:
    the stream with ``noise`` (None: the clean twin).  The noise model encodes
    itself (``noise.kernel_params()``, ``fixed_pattern``).  ``event``: draw shot
    noise per spike where the model allows it (``noise.event_driven``), else per
    readout (the reference sampler of the statistical tests).  The state's
    arrays come from ``pool`` when given (their content is never read)."""
    h, w = sensor.shape
    wp = _padded_width(w)
    gain, offset, electrons, charge_sd = _charge_constants(noise, h, w, sensor.full_scale_rate)
    params = NO_NOISE_PARAMS if noise is None else noise.kernel_params()
    per_readout = noise is not None and noise.per_readout
    event = bool(event and isinstance(noise, PhysicalNoise) and noise.event_driven)
    loss = float(params["loss"])
    model = _kernels.PixelModel(
        gain=gain, offset=offset, electrons=electrons, charge_sd=charge_sd,
        reset=_RESET_CODES[sensor.reset],
        fast_ok=not per_readout,  # charge loss makes per_readout true
        paper_fast_ok=bool(params["paper_only"]),
        paper_sg2=float(params["paper_sg2"]),
        paper_sp2=float(params["paper_sp2"]),
        jitter=float(params["jitter"]),
        loss=loss,
        event=event,
        key_paper=rng.stream_key(seed, rng.STREAM_PAPER),
        key_shot=rng.stream_key(seed, rng.STREAM_SHOT),
        key_jitter=rng.stream_key(seed, rng.STREAM_JITTER),
        key_charge=rng.stream_key(seed, rng.STREAM_CHARGE),
        key_init=rng.stream_key(seed, rng.STREAM_INIT),
        ev_keys=np.array([rng.stream_key(seed, s) for s in (
            rng.STREAM_WAIT, rng.STREAM_RESIDUAL, rng.STREAM_REFILL)],
            np.uint64),
    )
    pool = pool if pool is not None else ArrayPool(0)  # an empty pool: fresh arrays
    state = _kernels.PixelState(  # initialised by the kernel's first call
        frac=pool.take((h, wp), np.uint64),
        whole=pool.take((h, wp), np.int64),
        aux=pool.take((4, h, wp), np.float64) if event or loss > 0 else np.zeros((4, 1, 64)),
    )
    return model, state


def _unused_inputs() -> tuple[_kernels.PixelModel, _kernels.PixelState]:
    """Placeholders of the clean twin's model and state when there is none
    (the same types, so the kernel compiles once)."""
    z = np.zeros((1, 64))
    key = np.uint64(0)
    model = _kernels.PixelModel(z, z, z, z, _kernels.RESET_MODULO, True, False, 0.0, 0.0, 0.0,
                                0.0, False, key, key, key, key, key, np.zeros(4, np.uint64))
    return model, _kernels.PixelState(np.zeros((1, 64), np.uint64), np.zeros((1, 64), np.int64),
                                      np.zeros((4, 1, 64)))


def _charge_constants(noise, h: int, w: int, full_scale_rate: float):
    """The kernel's per-pixel ``gain``, ``offset``, ``electrons``,
    ``charge_sd`` (padded to whole 64-pixel blocks; padding lanes never fire;
    ``electrons`` and ``charge_sd`` −1 where the source is off).  Without a physical
    fixed pattern every row is the same, so each is a single (1, Wp) row the
    kernel shares between rows (nothing of size H·W built per call).  A chip's
    fixed pattern depends on the noise model and the size only (not on the run's
    seed), so the last few are kept (:data:`_PATTERNS`): drawing one costs more
    than a short run of a large sensor (70 ms at 1000×1000 on the 2-core VM).
    The kernel only reads these arrays."""
    if not isinstance(noise, PhysicalNoise):
        return _build_charge_constants(noise, h, w, full_scale_rate)
    key = (noise, h, w, float(full_scale_rate))
    with _PATTERNS_LOCK:
        if key in _PATTERNS:
            _PATTERNS.move_to_end(key)
            return _PATTERNS[key]
    built = _build_charge_constants(noise, h, w, full_scale_rate)
    if sum(a.nbytes for a in built) <= _PATTERNS_BYTES:
        with _PATTERNS_LOCK:
            _PATTERNS[key] = built
            while len(_PATTERNS) > _PATTERNS_KEPT:
                _PATTERNS.popitem(last=False)
    return built


#: Charge constants of the last physical-noise chips (see ``_charge_constants``).
_PATTERNS: OrderedDict = OrderedDict()
_PATTERNS_KEPT = 2
_PATTERNS_BYTES = 128 << 20
_PATTERNS_LOCK = threading.Lock()


def _build_charge_constants(noise, h: int, w: int, full_scale_rate: float):
    wp = _padded_width(w)
    if not isinstance(noise, PhysicalNoise):
        gain = np.zeros((1, wp))
        gain[:, :w] = full_scale_rate
        off = np.full((1, wp), -1.0)
        return gain, np.zeros((1, wp)), off, off
    pattern = fixed_pattern(noise, h, w, full_scale_rate)
    gain = np.zeros((h, wp))
    gain[:, :w] = pattern.gain
    offset = np.zeros((h, wp))
    offset[:, :w] = pattern.offset
    electrons = charge_sd = np.full((1, wp), -1.0)
    if pattern.electrons is not None:
        electrons = np.ones((h, wp))
        electrons[:, :w] = pattern.electrons
    if pattern.charge_sd is not None:
        charge_sd = np.zeros((h, wp))
        charge_sd[:, :w] = pattern.charge_sd
    return gain, offset, electrons, charge_sd


#: Sampled key frames of the last few frozen scene images (read-only float32
#: arrays that own their data: a ``Static`` scene's), kept across runs: sampling
#: a 1000×1000 RGB frame through the CFA costs 1.4 ms, a fifth of a 1-readout
#: call.  Keyed by the image's identity (checked through a weak reference, so a
#: new array at a recycled address never matches) and the CFA tile.
_FROZEN_FRAMES: OrderedDict = OrderedDict()
_FROZEN_KEPT = 2
_FROZEN_LOCK = threading.Lock()


def _is_frozen(a: np.ndarray) -> bool:
    return (a.dtype == np.float32 and not a.flags.writeable and a.base is None
            and a.flags.owndata)


def _kept_frame(image: np.ndarray, tile: np.ndarray, shape: tuple) -> np.ndarray | None:
    """``image``'s sampled key frame ((H, Wp/64, 64) float32) if an earlier run
    kept it (same tile and padded width), else None.  Shared: only read it."""
    with _FROZEN_LOCK:
        hit = _FROZEN_FRAMES.get((id(image), tile.tobytes(), shape))
    if hit is None or hit[0]() is not image:
        return None
    return hit[1]


def _recall_frame(image: np.ndarray, tile: np.ndarray, dest: np.ndarray) -> bool:
    """Copy ``image``'s kept key frame (:func:`_kept_frame`) into ``dest``;
    True when there was one."""
    kept = _kept_frame(image, tile, dest.shape)
    if kept is None:
        return False
    dest[...] = kept
    return True


def _remember_frame(image: np.ndarray, tile: np.ndarray, frame: np.ndarray) -> None:
    with _FROZEN_LOCK:
        _FROZEN_FRAMES[(id(image), tile.tobytes(), frame.shape)] = (weakref.ref(image),
                                                                    frame.copy())
        while len(_FROZEN_FRAMES) > _FROZEN_KEPT:
            _FROZEN_FRAMES.popitem(last=False)


def _padded_width(width: int) -> int:
    return _kernels.BLOCK * math.ceil(width / _kernels.BLOCK)


def _check_backend(backend, device) -> str:
    """``backend`` checked: "numba" (the kernel) or "torch" (``spikesim.torch_backend``)."""
    if backend not in ("numba", "torch"):
        raise bad_value("backend", backend, "'numba' or 'torch'")
    if backend == "numba" and device is not None:
        raise bad_value("device", device, "None with backend='numba' (a device is a "
                        "backend='torch' setting)")
    return backend


def simulate_chunks(scene, sensor: Sensor, n_readouts: int, seed: int = 0,
                    clean_twin: bool = False, gt_readouts: Sequence[int] | str | None = None,
                    chunk_readouts: int | None = 256, progress: bool = False, *,
                    shot_sampler: str = "event", backend: str = "numba",
                    device=None) -> SimulationRun:
    """Configure a simulation whose chunks are produced lazily (see :class:`SimulationRun`;
    ``backend``, ``device``: as :func:`simulate`)."""
    if _check_backend(backend, device) == "torch":
        from spikesim.torch_backend import TorchRun

        return TorchRun(scene, sensor, n_readouts, seed, clean_twin, gt_readouts,
                        chunk_readouts, progress, shot_sampler=shot_sampler, device=device)
    return SimulationRun(scene, sensor, n_readouts, seed, clean_twin, gt_readouts,
                         chunk_readouts, progress, shot_sampler=shot_sampler)


def simulate(scene, sensor: Sensor, n_readouts: int, seed: int = 0, clean_twin: bool = False,
             gt_readouts: Sequence[int] | str | None = None, chunk_readouts: int | None = None,
             progress: bool = False, *, shot_sampler: str = "event", backend: str = "numba",
             device=None) -> SpikeStream:
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
        middle readout ``n_readouts // 2``; ``[]``: none).  They are kept
        sorted and once each: ``stream.gt[k]`` is the frame at
        ``stream.gt_index[k]``, whatever order they were given in.
    chunk_readouts : int, optional
        Readouts per chunk (memory bound); results do not depend on it.
    progress : bool
        Show a progress bar.
    shot_sampler : {"event", "readout"}
        How physical-mode shot noise is drawn: ``"event"`` (default) the
        readout of each threshold crossing per firing cycle (work per spike,
        ``spikesim._event``), ``"readout"`` a Poisson count per pixel and
        readout (work per readout).  Same law, different bits; a model with
        ``charge_noise_electrons`` > 0 always draws per readout.
    backend : {"numba", "torch"}
        ``"torch"``: the same model, with the same bits, in PyTorch tensor code
        (:mod:`spikesim.torch_backend`, docs/torch.md; no noise and paper noise;
        needs the ``[torch]`` extra).
    device : torch device, optional
        With ``backend="torch"``: where to simulate (default CUDA when available,
        else the CPU).

    Returns
    -------
    SpikeStream

    Examples
    --------
    Half of full scale on an ideal monochrome sensor fires 0.3 spikes per readout
    (``full_scale_rate`` 0.6), exactly:

    >>> import numpy as np, spikesim as ss
    >>> sensor = ss.Sensor(height=4, width=8, cfa=None)
    >>> stream = ss.simulate(ss.scenes.Static(np.full((4, 8), 0.5)), sensor, 100, seed=0)
    >>> stream.packed.shape  # (T, H, ceil(W / 8)) bytes
    (100, 4, 1)
    >>> float(stream.unpack().mean()), stream.gt.shape, stream.gt_index.tolist()
    (0.3, (1, 4, 8, 3), [50])
    """
    if _check_backend(backend, device) == "torch":
        from spikesim.torch_backend import TorchRun

        run = TorchRun(scene, sensor, n_readouts, seed, clean_twin, gt_readouts,
                       chunk_readouts, progress, shot_sampler=shot_sampler, device=device)
    else:
        run = SimulationRun(scene, sensor, n_readouts, seed, clean_twin, gt_readouts,
                            chunk_readouts, progress, shot_sampler=shot_sampler)
    check_stream_memory(run.n_readouts, sensor.height, sensor.width, run.clean_twin,
                        len(run.gt_readouts))  # the whole stream is held: refuse what cannot fit
    h, nb = sensor.height, packed_width(sensor.width)
    packed = np.empty((run.n_readouts, h, nb), np.uint8)
    clean = np.empty_like(packed) if run.clean_twin else None
    gts, idx = [], []
    for chunk in run._chunks(into=(packed, clean)):  # the kernel writes into packed, clean
        gts.append(chunk.gt)
        idx.append(chunk.gt_index)
    gts = [g for g in gts if len(g)] or [np.zeros((0, h, sensor.width, 3), np.float32)]
    gt = gts[0] if len(gts) == 1 else np.concatenate(gts)  # (each chunk's is its own array)
    return SpikeStream(packed, run.meta, clean, gt, np.concatenate(idx).astype(np.int64))
