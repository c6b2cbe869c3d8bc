"""Estimates that catch runaway work before it starts.

A scene renders one *key frame* per ``key_interval_s`` of scene time (the
simulator interpolates between them).  A very fast motion or a fine flicker
tolerance makes that interval tiny, so a short stream can ask for hundreds of
thousands of full-frame renders, minutes of work the user rarely expects.
:func:`estimate_key_frames` counts them from the scene's interval without
rendering anything; :class:`~spikesim.simulate.SimulationRun` warns with a
:class:`RunawayWorkWarning` above :data:`KEY_FRAME_WARN`, and ``spikesim
simulate`` stops there unless given ``--force``.  :func:`check_free_space`
compares an output's size with the free space of its folder, and
:func:`check_memory` a frame size with the memory the machine has free.
"""

from __future__ import annotations

import math
import os
import shutil
import warnings
from pathlib import Path

from spikesim.errors import SpikeSimFileError, SpikeSimValueError

__all__ = ["KEY_FRAME_WARN", "RunawayWorkWarning", "check_free_space", "check_key_frames",
           "check_memory", "check_stream_memory", "estimate_key_frames",
           "require_reasonable_key_frames"]

#: Key frames above which a simulation is flagged (about a minute of rendering at 256 x 256).
KEY_FRAME_WARN = 20_000


class RunawayWorkWarning(UserWarning):
    """A request will do far more work than its size suggests."""


def estimate_key_frames(scene, duration_s: float) -> int | None:
    """Key frames a scene renders over ``duration_s`` seconds (None: unknown or static)."""
    interval = getattr(scene, "key_interval_s", None)
    try:
        interval = float(interval)
    except (TypeError, ValueError):
        return None
    if not (math.isfinite(interval) and interval > 0):
        return None
    count = float(duration_s) / interval + 2
    return int(min(count, 2**62))


def check_key_frames(scene, duration_s: float, limit: int | None = KEY_FRAME_WARN,
                     force: bool = False) -> int | None:
    """Warn when the scene needs more than ``limit`` key frames (``force``: never).

    Returns the estimate (None when the scene does not say).
    """
    est = estimate_key_frames(scene, duration_s)
    if est is not None and limit is not None and est > limit and not force:
        warnings.warn(runaway_message(scene, est, limit), RunawayWorkWarning, stacklevel=3)
    return est


def runaway_message(scene, est: int, limit: int) -> str:
    what = getattr(scene, "describe", lambda: {})()
    name = what.get("name") or what.get("type") or type(scene).__name__
    return (f"scene {name!r} needs about {est:,} key frames (one every "
            f"{float(scene.key_interval_s):.3g} s of scene time; more than {limit:,}): "
            "this can take very long; lower the motion speed or the number of readouts")


def require_reasonable_key_frames(scene, duration_s: float, limit: int = KEY_FRAME_WARN) -> None:
    """Raise :class:`SpikeSimValueError` above ``limit`` key frames (the CLI's check)."""
    est = estimate_key_frames(scene, duration_s)
    if est is not None and est > limit:
        raise SpikeSimValueError(runaway_message(scene, est, limit) +
                                 ", or pass --force to run anyway")


def check_free_space(path: str | os.PathLike, nbytes: int) -> None:
    """Raise :class:`SpikeSimFileError` when ``path``'s folder has less than ``nbytes`` free."""
    folder = Path(path).parent if str(Path(path).parent) else Path(".")
    try:
        free = shutil.disk_usage(folder).free
    except OSError:
        return  # the writer reports a missing folder with its own message
    if nbytes > free:
        raise SpikeSimFileError(
            f"writing {str(path)!r} needs about {nbytes / 2**30:.3g} GiB but its folder has "
            f"{free / 2**30:.3g} GiB free: free space, write elsewhere, ask for fewer readouts, "
            "or pass --force (compression may make it fit)"
        )


#: Peak memory of a ``spikesim simulate`` run per sensor pixel, bytes, beyond the
#: interpreter's own (an envelope: 230–320 measured for the built-in scenes at
#: 1000², 2000² and 4000² pixels, 360 with ``--clean-twin``, on the 2-core VM).
MEMORY_PER_PIXEL = 400


def available_memory() -> int | None:
    """Bytes this machine can still give a process: ``MemAvailable`` plus
    ``SwapFree`` of ``/proc/meminfo`` (Linux); None where that cannot be read."""
    try:
        with open("/proc/meminfo") as f:
            fields = dict(line.split(":", 1) for line in f)
        return sum(int(fields[k].split()[0]) * 1024 for k in ("MemAvailable", "SwapFree"))
    except (OSError, KeyError, ValueError):
        return None


def check_memory(height: int, width: int, option: str = "--size") -> None:
    """Raise :class:`SpikeSimValueError` naming ``option`` when simulating a
    ``height`` × ``width`` sensor would need more memory than the machine has free
    (:data:`MEMORY_PER_PIXEL` per pixel against :func:`available_memory`), before
    anything is allocated: such a run would otherwise end with the system killing
    it after minutes of swapping."""
    free = available_memory()
    need = height * width * MEMORY_PER_PIXEL
    if free is not None and need > free:
        raise SpikeSimValueError(
            f"{option} {height}x{width} needs about {need / 2**30:.3g} GiB of memory but "
            f"{free / 2**30:.3g} GiB is free: ask for a smaller {option}, or pass --force "
            "to try anyway")


def check_stream_memory(n_readouts: int, height: int, width: int, clean_twin: bool = False,
                        n_gt: int = 0) -> None:
    """Raise :class:`SpikeSimValueError` naming ``n_readouts`` when a stream held
    whole in memory (:func:`spikesim.simulate`) would not fit: its packed bits
    (``n_readouts·height·⌈width/8⌉`` bytes, twice with a clean twin) and its
    ``n_gt`` ground-truth frames (12 bytes a pixel) against
    :func:`available_memory`, before anything is allocated."""
    need = n_readouts * height * -(-width // 8) * (2 if clean_twin else 1) \
        + n_gt * height * width * 12
    free = available_memory()
    if free is not None and need > free:
        raise SpikeSimValueError(
            f"n_readouts={n_readouts} of a {height}x{width} sensor needs about "
            f"{need / 2**30:.3g} GiB held in memory but {free / 2**30:.3g} GiB is free: ask "
            "for fewer readouts or fewer ground-truth frames, or stream the chunks with "
            "spikesim.simulate_chunks (or spikesim.io.write_h5) instead")
