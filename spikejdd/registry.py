"""One registry of reconstruction methods, and the ``reconstruct`` dispatcher.

The method protocol
-------------------
A *method* is a callable ``fn(spikes, cfa, center) -> (H, W, 3)``:

* ``spikes``: (T, H, W) ``uint8`` 0/1 (row 0 = top; the CFA pattern names the
  top-left tile);
* ``cfa``: ``"RGGB"``, ``"BGGR"``, ``"GRBG"``, ``"GBRG"`` or ``None`` (monochrome);
* ``center``: the readout (index into ``spikes``) to reconstruct;
* returns float linear RGB, scene units (1.0 = the light at which the sensor
  fires ``rate`` spikes per readout), shape (H, W, 3).

Optional keyword arguments a method may declare are passed when it does:
``rate`` (the sensor's ``full_scale_rate``), ``device``, ``threads`` and
``ensemble`` (for torch methods: the views of
:func:`spikejdd.models.run_ensemble`); any other option must be declared to
be accepted.  A method
may also offer ``fn.window_for(n_readouts, **options) -> int``, the readouts it
uses, which results report.

Names :meth:`Registry.get` resolves, in this order:

1. ``base@weights`` — a registered method with its ``weights`` option bound,
   e.g. ``sjdd@runs/x/best.pt`` or ``sjdd@sjdd-lite``;
2. ``package.module:function`` — any importable callable following the
   protocol (a torch ``nn.Module`` instance is wrapped by
   :class:`spikejdd.models.TorchMethod`);
3. registered names (``register``; the built-in ``sjdd`` is registered lazily,
   so torch loads on first use only);
4. classical pipelines from their names (:mod:`spikejdd.pipelines`);
5. methods that installed packages declare in the entry-point group
   ``spikejdd.methods`` (``name = "package.module:function"``).

Unknown names raise naming the choices; nothing falls back silently.
"""

from __future__ import annotations

import importlib
import inspect
import re
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from spikejdd.pipelines import PIPELINE_GRAMMAR, parse_pipeline, standard_pipelines
from spikejdd.runtime import check_ensemble
from spikesim.cfa import normalize_cfa
from spikesim.errors import SpikeSimError, SpikeSimTypeError, SpikeSimValueError, bad_value
from spikesim.estimate import window_bounds

__all__ = ["Registry", "Method", "MethodError", "METHODS", "ENTRY_POINT_GROUP", "register_method",
           "unregister_method", "get_method", "list_methods", "reconstruct", "call_method"]

#: Entry-point group through which installed packages add methods.
ENTRY_POINT_GROUP = "spikejdd.methods"
#: Options a method receives only when its signature declares them (runtime settings).
AMBIENT_OPTIONS = ("rate", "device", "threads", "ensemble")

_NAME_RE = re.compile(r"^[a-z0-9][a-z0-9_.\-+]*$")
_TARGET_RE = re.compile(r"^[A-Za-z_][\w.]*:[A-Za-z_][\w.]*$")
#: Where the shipped weights live (``spikejdd.models.WEIGHTS_DIR``, without importing torch).
_WEIGHTS_DIR = Path(__file__).resolve().parent / "weights"


def _accepted(fn: Callable) -> tuple[set[str], bool]:
    """Keyword names ``fn`` accepts, and whether it takes ``**kwargs``."""
    try:
        sig = inspect.signature(fn)
    except (TypeError, ValueError):  # builtins without a signature: pass everything
        return set(), True
    names = {p.name for p in sig.parameters.values()
             if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}
    return names, any(p.kind is p.VAR_KEYWORD for p in sig.parameters.values())


class MethodError(SpikeSimError, RuntimeError):
    """A reconstruction method raised while it ran (its own failure, named)."""

    #: The command line's one-line error says that ``--debug`` shows the
    #: method's traceback (:func:`spikesim.cli_guard.run_guarded`).
    traceback_helps = True


@dataclass(frozen=True)
class Method:
    """A resolved method: the callable, its name, description and bound options.

    Calling it applies the protocol: ``rate``/``device``/``threads``/``ensemble``
    reach the callable only if it declares them (an invalid ``ensemble`` is
    refused either way); other options must be declared.
    """

    name: str
    fn: Callable[..., Any]
    description: str = ""
    options: dict = field(default_factory=dict)

    def __call__(self, spikes, cfa, center, **options) -> np.ndarray:
        kwargs = {**self.options, **options}
        check_ensemble(kwargs.get("ensemble"))  # refused even where the method ignores it
        names, var_kw = _accepted(self.fn)
        if not var_kw:
            unknown = sorted(k for k in kwargs if k not in names and k not in AMBIENT_OPTIONS)
            if unknown:
                raise bad_value("options", unknown, f"options method {self.name!r} declares "
                                f"{sorted(names - {'spikes', 'cfa', 'center'})}")
            kwargs = {k: v for k, v in kwargs.items() if k in names}
        try:
            return self.fn(spikes, cfa, center, **kwargs)
        except SpikeSimError as exc:  # a clear error already: say which method raised it
            if not str(exc).startswith("method "):
                exc.args = (f"method {self.name!r}: {exc}",)
            raise
        except Exception as exc:  # the method's own failure, not the harness's
            raise MethodError(f"method {self.name!r} failed: {type(exc).__name__}: {exc}") \
                from exc

    def window_for(self, n_readouts: int) -> int | None:
        """Readouts the method uses on a stream of ``n_readouts`` (None: it does not say)."""
        fn = getattr(self.fn, "window_for", None)
        if fn is None:
            return None
        names, var_kw = _accepted(fn)
        opts = self.options if var_kw else {k: v for k, v in self.options.items() if k in names}
        return int(fn(n_readouts, **opts))


@dataclass(frozen=True)
class _Entry:
    target: Callable[..., Any] | str  # callable, or "module:attr" imported on first use
    description: str


def _describe(fn: Callable, description: str) -> str:
    if description:
        return description
    doc = (getattr(fn, "__doc__", None) or "").strip()
    return doc.split("\n")[0] if doc else ""


def _import_target(text: str, what: str = "method") -> Any:
    """Import ``package.module:attr`` (attr may be dotted); one clear error otherwise."""
    mod_name, _, attr = text.partition(":")
    try:
        obj = importlib.import_module(mod_name)
    except ImportError as exc:
        hint = ""
        if isinstance(exc, ModuleNotFoundError) and exc.name == mod_name.split(".")[0]:
            hint = ("; a module of your own must be on the import path: run from its folder "
                    "with PYTHONPATH=. or install it")
        raise bad_value(what, text,
                        f"an importable package.module:function ({exc}{hint})") from None
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise bad_value(what, text, f"a name defined in module {mod_name!r} ({attr!r} is not)")
        obj = getattr(obj, part)
    return obj


def _as_callable(obj: Any, label: str) -> Callable[..., Any]:
    torch = sys.modules.get("torch")
    if torch is not None and isinstance(obj, torch.nn.Module):
        from spikejdd.models.adapter import TorchMethod

        return TorchMethod(obj)
    if isinstance(obj, type):
        raise bad_value("method", label, "a function or an object instance following the method "
                        "protocol (got a class: instantiate it in your module)")
    if not callable(obj):
        raise SpikeSimTypeError(f"method {label!r} is not callable ({type(obj).__name__})")
    return obj


class Registry:
    """Named reconstruction methods (BasicSR ``ARCH_REGISTRY`` style).

    ``register`` works as a call or a decorator::

        METHODS.register(fn, name="mine")

        @METHODS.register(name="mine")
        def mine(spikes, cfa, center): ...

    ``get(name)`` resolves every naming form of the module doc; ``names()``
    lists registered and entry-point names; ``describe()`` adds descriptions.
    """

    def __init__(self, name: str, entry_point_group: str | None = None):
        self.name = name
        self.entry_point_group = entry_point_group
        self._entries: dict[str, _Entry] = {}
        self._from_entry_points: set[str] = set()
        self._entry_points_loaded = False

    # --- registration ---------------------------------------------------
    def register(self, obj: Callable | None = None, *, name: str | None = None,
                 description: str = "", overwrite: bool = False):
        """Register ``obj`` (a callable, or ``"module:attr"`` imported on first use).

        ``name`` defaults to the function's name (lower case).  Raises if the
        name is malformed, ``obj`` is not callable or the name is taken (a
        registered method or a pipeline name) and ``overwrite`` is false.
        """
        if obj is None:
            def deco(fn):
                self.register(fn, name=name, description=description, overwrite=overwrite)
                return fn
            return deco
        if name is None:
            name = getattr(obj, "__name__", "").lower()
        if not isinstance(name, str) or not _NAME_RE.match(name):
            raise bad_value("name", name, "a lower-case name of letters, digits and _ . - +")
        if isinstance(obj, str):
            if not _TARGET_RE.match(obj):
                raise bad_value("obj", obj, "a callable or 'package.module:function'")
        elif not callable(obj):
            raise SpikeSimTypeError(f"fn must be callable, got {type(obj).__name__}")
        if not overwrite and (name in self._entries or parse_pipeline(name) is not None):
            raise bad_value("name", name, "a name not already registered (or pass overwrite=True)")
        desc = description if isinstance(obj, str) else _describe(obj, description)
        self._entries[name] = _Entry(obj, desc)
        return obj

    def unregister(self, name: str) -> None:
        """Remove a registered method (pipelines cannot be removed)."""
        if name not in self._entries:
            raise bad_value("name", name, f"a registered method {tuple(sorted(self._entries))}")
        del self._entries[name]
        self._from_entry_points.discard(name)

    def _load_entry_points(self) -> None:
        if self._entry_points_loaded or not self.entry_point_group:
            return
        self._entry_points_loaded = True
        from importlib.metadata import entry_points

        for ep in entry_points(group=self.entry_point_group):
            key = ep.name.strip().lower()
            if key in self._entries or not _NAME_RE.match(key) or parse_pipeline(key):
                continue  # registered names win; malformed names are not reachable
            self._entries[key] = _Entry(ep.value, "")
            self._from_entry_points.add(key)

    def reload_entry_points(self) -> None:
        """Read the entry points again (after installing a package in this process)."""
        for key in self._from_entry_points:
            self._entries.pop(key, None)
        self._from_entry_points.clear()
        self._entry_points_loaded = False
        self._load_entry_points()

    # --- lookup ---------------------------------------------------------
    def _registered(self, key: str) -> Method | None:
        entry = self._entries.get(key)
        if entry is None:
            self._load_entry_points()
            entry = self._entries.get(key)
        if entry is None:
            return None
        fn = entry.target
        if isinstance(fn, str):
            fn = _as_callable(_import_target(fn), key)
        return Method(key, fn, _describe(fn, entry.description))

    def get(self, name: str) -> Method:
        """The :class:`Method` for ``name``; raises naming the choices if unknown."""
        if not isinstance(name, str) or not name.strip():
            raise bad_value("method", name, "a method name (see `spikejdd methods`)")
        text = name.strip()
        if "@" in text:
            base, _, weights = text.partition("@")
            method = self.get(base)
            names, var_kw = _accepted(method.fn)
            if not weights or not (var_kw or "weights" in names):
                raise bad_value("method", name, "NAME@WEIGHTS where NAME takes weights "
                                "(e.g. sjdd@runs/x/best.pt or sjdd@sjdd-lite)")
            check = getattr(method.fn, "check_weights", None)
            if check is not None:  # refused now, not when the method first runs
                check(weights)
            return Method(text, method.fn, f"{method.description} [weights {weights}]",
                          {**method.options, "weights": weights})
        if ":" in text:
            if not _TARGET_RE.match(text):
                raise bad_value("method", name, "package.module:function")
            fn = _as_callable(_import_target(text), text)
            return Method(text, fn, _describe(fn, ""))
        key = text.lower()
        method = self._registered(key)
        if method is not None:
            return method
        pipe = parse_pipeline(key)
        if pipe is not None:
            return Method(key, pipe, pipe.description)
        hint = (f" (shipped weights are named as sjdd@{key})"
                if (_WEIGHTS_DIR / f"{key}.pt").is_file() else "")
        raise bad_value("method", name, f"a registered method ({', '.join(self.names())}), a "
                        f"pipeline {PIPELINE_GRAMMAR}, package.module:function or "
                        f"NAME@WEIGHTS{hint}")

    def names(self) -> list[str]:
        """Registered and entry-point names (pipelines are resolved from their names)."""
        self._load_entry_points()
        return sorted(self._entries)

    def describe(self) -> dict[str, str]:
        """Standard pipelines and every registered name → one-line description."""
        out = {n: parse_pipeline(n).description for n in standard_pipelines()}
        self._load_entry_points()
        out.update({n: e.description or (f"entry point {e.target}" if isinstance(e.target, str)
                                         else "") for n, e in sorted(self._entries.items())})
        return out

    def __contains__(self, name: str) -> bool:
        try:
            self.get(name)
        except SpikeSimValueError:
            return False
        return True


#: The registry every part of spikejdd uses.
METHODS = Registry("methods", entry_point_group=ENTRY_POINT_GROUP)
METHODS.register("spikejdd.models.adapter:sjdd_method", name="sjdd",
                 description="SJDD-Net (AAAI 2024) learned JDD with the shipped sjdd-full "
                             "weights (sjdd@sjdd-lite: 4x faster on a CPU, 1.3 dB lower; "
                             "sjdd@PATH.pt for a checkpoint), 39-readout window")


# --- functional face (kept for existing callers) ---------------------------
def register_method(name: str, fn: Callable[..., np.ndarray], description: str = "",
                    overwrite: bool = False) -> None:
    """``METHODS.register(fn, name=name, ...)``."""
    METHODS.register(fn, name=name, description=description, overwrite=overwrite)


def unregister_method(name: str) -> None:
    """``METHODS.unregister(name)``."""
    METHODS.unregister(name)


def get_method(name: str) -> Method:
    """``METHODS.get(name)``: a callable :class:`Method`."""
    return METHODS.get(name)


def reconstructor(method: str):
    """``fn(spikes, cfa, center, rate=0.6)`` → (H, W, 3) linear RGB with ``method`` (any name
    :meth:`Registry.get` resolves, checked now): the form spikesim's noise budget takes.
    spikejdd offers it to spikesim through the ``spikesim.reconstructors`` entry point, so
    ``spikesim analyze budget --method tfp+menon2007`` works without spikesim importing
    spikejdd."""
    resolved = METHODS.get(method)

    def fn(spikes, cfa, center, rate: float = 0.6) -> np.ndarray:
        return call_method(resolved, spikes, cfa, center, rate=rate)

    fn.__name__ = fn.__qualname__ = str(method)
    return fn


def list_methods() -> dict[str, str]:
    """``METHODS.describe()``: pipelines and registered methods with descriptions."""
    return METHODS.describe()


def _check_spikes(spikes) -> np.ndarray:
    arr = np.asarray(spikes)
    if arr.dtype != np.bool_ and arr.dtype.kind not in "iu":
        raise SpikeSimTypeError(f"spikes must be bool or integer 0/1 (T, H, W), got {arr.dtype}")
    if arr.ndim != 3 or 0 in arr.shape:
        raise bad_value("spikes.shape", arr.shape, "(T, H, W) with T, H, W >= 1")
    return arr


def _check_bits(spikes) -> None:
    """Integer spikes must be 0/1 (a full pass over the array: done once per
    :func:`reconstruct` call, outside the timed calls of an evaluation)."""
    arr = np.asarray(spikes)
    if arr.dtype != np.bool_ and arr.dtype.kind in "iu" and arr.size:
        low, high = int(arr.min()), int(arr.max())
        if low < 0 or high > 1:
            raise bad_value("spikes", f"values from {low} to {high}",
                            "0/1 spikes (unpacked bits, e.g. SpikeStream.unpack())")


def call_method(method: Method, spikes, cfa, center, **options) -> np.ndarray:
    """Call ``method`` under the protocol and check its output (shape, finite values)."""
    arr = _check_spikes(spikes)
    pattern = normalize_cfa(cfa)
    window_bounds(arr.shape[0], center, 1)  # validates center
    out = np.asarray(method(arr, pattern, center, **options))
    if out.shape != arr.shape[1:] + (3,):
        raise SpikeSimValueError(
            f"method {method.name!r} returned shape {out.shape}, expected {arr.shape[1:] + (3,)}"
        )
    if out.dtype.kind != "f":
        hint = (" (an 8-bit image? return spikesim.srgb.srgb_to_linear(image / 255))"
                if out.dtype.kind in "iub" else "")
        raise SpikeSimTypeError(f"method {method.name!r} returned dtype {out.dtype}, "
                                f"expected float linear RGB{hint}")
    bad = out.size - int(np.count_nonzero(np.isfinite(out)))
    if bad:
        raise SpikeSimValueError(f"method {method.name!r} returned {bad} non-finite values "
                                 "(NaN or inf), expected finite linear RGB")
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
        Any name :meth:`Registry.get` resolves (registered, pipeline,
        ``package.module:function``, ``NAME@WEIGHTS``, entry point).
    center : int or None
        Readout index (0-based within ``spikes``); ``None`` = ``T // 2``.
    rate : float
        Sensor ``full_scale_rate``: spikes per readout at intensity 1.0.
    **options
        Passed to the method (e.g. ``no_spike`` for TFI pipelines, ``weights``
        and ``device`` for SJDD-Net).

    Examples
    --------
    >>> import spikesim as ss, spikejdd as sj
    >>> scene = ss.scenes.procedural("astronaut", size=(16, 16))
    >>> stream = ss.simulate(scene, ss.Sensor(height=16, width=16), 41)
    >>> rgb = sj.reconstruct(stream.unpack(), "RGGB", "tfp+menon2007", center=20)
    >>> rgb.shape, rgb.dtype
    ((16, 16, 3), dtype('float64'))
    """
    fn = METHODS.get(method)
    _check_bits(spikes)
    return call_method(fn, spikes, cfa, center, rate=rate, **options)
