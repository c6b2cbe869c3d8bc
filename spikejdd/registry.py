"""Method registry and the ``reconstruct`` dispatcher.

A *method* is any callable ``fn(spikes, cfa, center, rate=0.6, **options)``
returning an (H, W, 3) linear-RGB float image, where ``spikes`` is a (T, H, W)
0/1 array, ``cfa`` a Bayer pattern name or ``None``, and ``center`` the readout
to reconstruct.  Built-in classical pipelines (:mod:`spikejdd.pipelines`) are
resolved from their names; anything else joins with :func:`register_method`.
Unknown names raise and never fall back silently.

If a name is not found, ``spikejdd.models`` is imported once (when it exists)
so that learned models registering themselves there (``"sjdd"``) are found.
"""

from __future__ import annotations

import importlib
import re
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from spikejdd.pipelines import PIPELINE_GRAMMAR, parse_pipeline, standard_pipelines
from spikesim.cfa import normalize_cfa
from spikesim.errors import SpikeSimTypeError, SpikeSimValueError, bad_value
from spikesim.estimate import window_bounds

__all__ = ["register_method", "unregister_method", "get_method", "list_methods", "reconstruct"]

_NAME_RE = re.compile(r"^[a-z0-9][a-z0-9_.\-+]*$")


@dataclass(frozen=True)
class _Entry:
    fn: Callable[..., np.ndarray]
    description: str


_METHODS: dict[str, _Entry] = {}
_plugins_loaded = False


def register_method(
    name: str, fn: Callable[..., np.ndarray], description: str = "", overwrite: bool = False
) -> None:
    """Register ``fn`` under ``name`` (lower case letters, digits, ``_.-+``).

    Raises if the name is malformed, ``fn`` is not callable, or the name is
    taken (a registered method or a built-in pipeline) and ``overwrite`` is false.
    """
    if not isinstance(name, str) or not _NAME_RE.match(name):
        raise bad_value("name", name, "a lower-case name of letters, digits and _ . - +")
    if not callable(fn):
        raise SpikeSimTypeError(f"fn must be callable, got {type(fn).__name__}")
    if not overwrite and (name in _METHODS or parse_pipeline(name) is not None):
        raise bad_value("name", name, "a name not already registered (or pass overwrite=True)")
    _METHODS[name] = _Entry(fn, description or (fn.__doc__ or "").strip().split("\n")[0])


def unregister_method(name: str) -> None:
    """Remove a registered method (built-in pipelines cannot be removed)."""
    if name not in _METHODS:
        raise bad_value("name", name, f"a registered method {tuple(sorted(_METHODS))}")
    del _METHODS[name]


def _load_plugins() -> None:
    global _plugins_loaded
    if _plugins_loaded:
        return
    _plugins_loaded = True
    try:
        importlib.import_module("spikejdd.models")
    except ModuleNotFoundError as exc:
        if exc.name not in ("spikejdd.models", "torch"):
            raise


def get_method(name: str) -> Callable[..., np.ndarray]:
    """The callable for ``name``; raises naming the choices if unknown."""
    if isinstance(name, str):
        key = name.strip().lower()
        if key in _METHODS:
            return _METHODS[key].fn
        pipe = parse_pipeline(key)
        if pipe is not None:
            return pipe
        _load_plugins()
        if key in _METHODS:
            return _METHODS[key].fn
    raise bad_value(
        "method",
        name,
        f"a registered method {tuple(sorted(_METHODS))} or a pipeline {PIPELINE_GRAMMAR}",
    )


def list_methods() -> dict[str, str]:
    """Registered methods and the standard pipelines, name → one-line description."""
    _load_plugins()
    out = {n: parse_pipeline(n).description for n in standard_pipelines()}
    out.update({n: e.description for n, e in sorted(_METHODS.items())})
    return out


def reconstruct(
    spikes: np.ndarray,
    cfa: str | None = "RGGB",
    method: str = "tfp+bilinear",
    center: int | None = None,
    rate: float = 0.6,
    **options,
) -> np.ndarray:
    """Reconstruct the (H, W, 3) linear-RGB frame at readout ``center``.

    Parameters
    ----------
    spikes : (T, H, W) array of 0/1 (bool or integer)
        Unpacked spike stream, row 0 = top; the CFA pattern names its top-left tile.
    cfa : {"RGGB", "BGGR", "GRBG", "GBRG"} or None
        Bayer pattern; ``None``/"mono" for a monochrome sensor.
    method : str
        A registered method or a pipeline name (:mod:`spikejdd.pipelines`).
    center : int or None
        Readout index (0-based within ``spikes``); ``None`` = ``T // 2``.
    rate : float
        Sensor ``full_scale_rate``: spikes per readout at intensity 1.0.
    **options
        Passed to the method (e.g. ``no_spike`` for TFI pipelines).
    """
    fn = get_method(method)
    arr = np.asarray(spikes)
    if arr.dtype != np.bool_ and arr.dtype.kind not in "iu":
        raise SpikeSimTypeError(f"spikes must be bool or integer 0/1 (T, H, W), got {arr.dtype}")
    if arr.ndim != 3 or 0 in arr.shape:
        raise bad_value("spikes.shape", arr.shape, "(T, H, W) with T, H, W >= 1")
    pattern = normalize_cfa(cfa)
    window_bounds(arr.shape[0], center, 1)  # validates center
    out = np.asarray(fn(arr, pattern, center, rate=rate, **options))
    if out.shape != arr.shape[1:] + (3,):
        raise SpikeSimValueError(
            f"method {method!r} returned shape {out.shape}, expected {arr.shape[1:] + (3,)}"
        )
    return out
