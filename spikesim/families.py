"""Kernel families: each run compiles only the noise code it uses.

numba compiles a function with everything it may call, so one kernel holding
every noise model made the first noise-free run after an install compile the
physical-noise samplers too (minutes).  The kernel instead takes three
markers, ``paper``, ``event`` and ``readout``, constants of its compiled entry
point (``spikesim._kernels.simulate_rows``): ``None`` leaves that code out of
the machine code, otherwise it is compiled.  A *family* is one choice of
markers, picked in Python from the noise model before the call, and numba
caches each family's machine code on its own:

============  ==================================================================
family        what it compiles beyond the noise-free paths
============  ==================================================================
noise-free    nothing (no noise, or a chip's fixed pattern only)
paper         paper-mode Gaussian / Poisson-Gaussian noise (Dong et al., eq. 5)
physical      Poisson shot noise drawn per spike, threshold jitter, dark current
              (:class:`~spikesim.noise.PhysicalNoise` defaults)
charge        physical noise drawn per readout: charge noise, or shot noise
              from the per-readout reference sampler
============  ==================================================================

The physical family's event sampler is compiled for the sensor's reset mode
only (``event`` is the reset's code; :func:`kernel_name` names the three
kernels ``physical-modulo``, ``physical-subtract`` and ``physical-zero``).

The first run of a family after an install (or after the package's compiled
sources change) compiles it and says so once per process on stderr, with the
time it took on the reference machine (:data:`COMPILE_SECONDS`) and where
numba's cache lives; :func:`spikesim.precompile.precompile` (``spikesim compile``) fills the cache
ahead, e.g. for a cluster's shared ``NUMBA_CACHE_DIR``.
"""

from __future__ import annotations

import os
import sys
import threading
from pathlib import Path

from spikesim._numba_cache import FAMILY_MARK_PREFIX, cache_folder
from spikesim.errors import bad_value

__all__ = ["COMPILE_SECONDS", "FAMILIES", "RESETS", "announce_compile", "family_of",
           "family_markers", "family_of_noise", "is_compiled", "kernel_name", "mark_compiled"]

#: The families and their markers ``(paper, event, readout)`` for the kernel.
FAMILIES: dict[str, tuple[bool | None, bool | None, bool | None]] = {
    "noise-free": (None, None, None),
    "paper": (True, None, None),
    "physical": (None, True, None),
    "charge": (None, None, True),
}

#: The reset modes, in the order of the kernel's codes (``spikesim._kernels.RESET_*``).
RESETS = ("modulo", "subtract", "zero")

#: Seconds to compile each family into an empty cache (CPU seconds of one
#: process, its start and imports included, on the project's 2-core VM; the
#: physical family per reset mode, 60–77 s;
#: compilation runs on one core, so an idle machine takes about as long;
#: ``spikesim compile --measure`` re-measures, docs/performance.md has the table).
COMPILE_SECONDS = {"noise-free": 20, "paper": 25, "physical": 70, "charge": 50}

_MARK = FAMILY_MARK_PREFIX + "{}.ok"  # beside numba's cache files: this family is in the cache
_announced: set[str] = set()
_lock = threading.Lock()


def family_of(model) -> str:
    """The family a kernel model (``spikesim._kernels.PixelModel``) needs."""
    if model.event:
        return "physical"
    if (model.electrons[0, 0] >= 0.0 or model.charge_sd[0, 0] >= 0.0 or model.jitter > 0.0
            or model.loss > 0.0):
        return "charge"
    if model.paper_sg2 > 0.0 or model.paper_sp2 > 0.0:
        return "paper"
    return "noise-free"


def family_of_noise(noise, shot_sampler: str = "event") -> str:
    """The family a noise model (None, :class:`~spikesim.noise.PaperNoise` or
    :class:`~spikesim.noise.PhysicalNoise`) needs, without building the kernel's
    inputs (the dataset builder's and :func:`precompile`'s question)."""
    from spikesim.noise import PhysicalNoise

    if noise is None or not noise.per_readout:
        return "noise-free"
    if isinstance(noise, PhysicalNoise):
        return "physical" if noise.event_driven and shot_sampler == "event" else "charge"
    return "paper"


def family_markers(name: str) -> tuple[bool | None, bool | None, bool | None]:
    """The kernel's ``(paper, event, readout)`` arguments of family ``name``."""
    if name not in FAMILIES:
        raise bad_value("family", name, f"one of {', '.join(FAMILIES)}")
    return FAMILIES[name]


def kernel_name(family: str, reset: int | str = 0) -> str:
    """The name of the compiled kernel a run of ``family`` with reset mode
    ``reset`` (a name of :data:`RESETS` or its code) loads: the family's own,
    except that the physical family is compiled per reset mode
    (``physical-zero``)."""
    family_markers(family)  # validates
    if family != "physical":
        return family
    name = RESETS[reset] if isinstance(reset, int) else reset
    if name not in RESETS:
        raise bad_value("reset", reset, f"one of {', '.join(RESETS)}")
    return f"physical-{name}"


def _family(name: str) -> str:
    return "physical" if name.startswith("physical") else name


def _mark_path(name: str) -> Path:
    return cache_folder(Path(__file__).parent) / _MARK.format(name)


def is_compiled(name: str) -> bool:
    """Whether kernel ``name`` (:func:`kernel_name`) was compiled into this install's numba cache (a
    mark written after its first compilation; removed with the cache files when
    the package's compiled sources change, ``spikesim._numba_cache.sync_cache``)."""
    return _mark_path(name).is_file()


def announce_compile(name: str, stream=None) -> bool:
    """Before the first call of kernel ``name`` (:func:`kernel_name`) in this process: when its
    machine code is not in the cache yet, say on ``stream`` (stderr) that it is
    being compiled, for about how long and where the cache lives.  Returns True
    when it printed.  Set ``SPIKESIM_QUIET_COMPILE=1`` to silence it."""
    with _lock:
        if name in _announced:
            return False
        _announced.add(name)
    if is_compiled(name) or os.environ.get("SPIKESIM_QUIET_COMPILE"):
        return False
    folder = cache_folder(Path(__file__).parent)
    print(f"spikesim: compiling the {name} simulation kernels for this machine, once "
          f"(about {COMPILE_SECONDS[_family(name)]} s on 2 cores); the machine code is cached in "
          f"{folder} and later runs load it in about a second "
          "(`spikesim compile` does this ahead)", file=stream or sys.stderr, flush=True)
    return True


def mark_compiled(name: str) -> None:
    """Record that kernel ``name`` (:func:`kernel_name`) is in the cache (after a
    kernel call)."""
    path = _mark_path(name)
    if path.is_file():
        return
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("compiled\n")
    except OSError:  # a read-only install: numba's cache is read-only too
        pass
