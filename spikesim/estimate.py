"""Classical intensity estimators for a spike stream: TFP and TFI (NumPy only).

Both estimators return **scene units**: linear light, relative, where 1.0 is the
intensity at which the sensor fires ``rate`` spikes per readout (``rate`` is the
sensor's ``full_scale_rate``, docs/model.md).  A perfect (noise-free, clocked)
stream of constant intensity ``I`` therefore returns ``I``, up to the
quantization error of the window (see each function).

* **TFP** — *texture from playback*: the mean spike count over a window of
  readouts, divided by ``rate``.  Zhu et al., "A Retina-Inspired Sampling
  Method for Visual Texture Reconstruction", ICME 2019, §3.1 (window
  accumulation); the photometric scaling is ours.
* **TFI** — *texture from inter-spike interval*: ``1 / (ISI · rate)``, where
  ISI is the interval in readouts between the last spike at or before the
  centre readout and the first spike after it (same paper, §3.2).

Time convention: readout ``n`` covers ``[n, n+1) / clock_hz``; the ground truth
tied to readout ``n`` is the radiance at its middle.  A TFP window of
``2h + 1`` readouts centred on ``n`` is therefore centred in time on the GT.

Why no TFSTP here: the short-term-plasticity model (Zheng et al., CVPR 2021)
outputs a synaptic state with a non-linear, history-dependent relation to
intensity that is only made viewable by histogram equalisation; it has no
photometric scale, so it cannot be scored against linear ground truth.

spikesim itself never imports torch; ``spikejdd.baselines`` wraps these.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from spikesim.errors import SpikeSimTypeError, bad_value

__all__ = [
    "tfp",
    "tfi",
    "window_bounds",
    "NO_SPIKE_RULES",
    "tfp_std",
    "TFP_DEFAULT_WINDOW",
    "default_tfp_window",
]

#: TFP's default window in readouts; shorter streams use their whole length.
TFP_DEFAULT_WINDOW = 41

#: Allowed rules for TFI pixels that lack a spike on one or both sides of the
#: centre inside the search range.
NO_SPIKE_RULES: tuple[str, ...] = ("bound", "zero", "nan", "tfp")

NoSpikeRule = Literal["bound", "zero", "nan", "tfp"]


def _check_spikes(spikes: np.ndarray) -> np.ndarray:
    arr = np.asarray(spikes)
    if arr.dtype != np.bool_ and arr.dtype.kind not in "iu":
        raise SpikeSimTypeError(
            f"spikes must be a bool or integer 0/1 array (T, H, W), got dtype {arr.dtype}"
        )
    if arr.ndim != 3:
        raise bad_value("spikes.shape", arr.shape, "a 3-D array (T, H, W) of readouts")
    if arr.shape[0] < 1:
        raise bad_value("spikes.shape", arr.shape, "at least one readout (T >= 1)")
    return arr


def _check_rate(rate: float) -> float:
    try:
        value = float(rate)
    except (TypeError, ValueError):
        raise bad_value("rate", rate, "a positive number of spikes per readout") from None
    if not (np.isfinite(value) and 0 < value <= 1):
        raise bad_value("rate", rate, "0 < rate <= 1 spikes per readout at full scale")
    return value


def _check_center(center: int | None, n: int) -> int:
    if center is None:
        return n // 2
    if isinstance(center, bool) or not isinstance(center, int | np.integer):
        raise bad_value("center", center, f"an integer readout index in [0, {n - 1}]")
    c = int(center)
    if not 0 <= c < n:
        raise bad_value("center", center, f"a readout index in [0, {n - 1}]")
    return c


def window_bounds(n_readouts: int, center: int | None, window: int) -> tuple[int, int]:
    """Return ``(start, stop)`` of a ``window``-readout window around ``center``.

    The window is ``[center - window//2, center - window//2 + window)``: centred
    for odd ``window``, one readout earlier than centred for even.  Near the ends
    of the stream the window is shifted (not shortened) to fit, which moves its
    time centre off ``center``; a window longer than the stream is an error.

    Parameters
    ----------
    n_readouts : int
        Number of readouts ``T`` in the stream.
    center : int or None
        Readout index the window is centred on; ``None`` = ``T // 2``.
    window : int
        Number of readouts, ``1 <= window <= T``.
    """
    if isinstance(window, bool) or not isinstance(window, int | np.integer):
        raise bad_value("window", window, f"an integer number of readouts in [1, {n_readouts}]")
    window = int(window)
    if window < 1:
        raise bad_value("window", window, f"at least 1 readout (stream has {n_readouts})")
    if window > n_readouts:
        raise bad_value("window", window, f"at most the {n_readouts} readouts given (a longer "
                        "stream, or a wider context: --context of spikejdd's commands)")
    c = _check_center(center, n_readouts)
    start = c - window // 2
    start = min(max(start, 0), n_readouts - window)
    return start, start + window


def default_tfp_window(n_readouts: int) -> int:
    """The window TFP uses when none is given: 41 readouts, or the whole stream when it
    is shorter (the largest window that fits; placed as :func:`window_bounds` does)."""
    return max(1, min(TFP_DEFAULT_WINDOW, int(n_readouts)))


def tfp(
    spikes: np.ndarray,
    center: int | None = None,
    window: int | None = None,
    rate: float = 0.6,
) -> np.ndarray:
    """Texture from playback: mean spike count over a window, in scene units.

    ``I_hat = (number of spikes in the window) / (window · rate)``.

    For a noise-free clocked stream of constant intensity ``I < 1/rate`` the
    count over ``w`` readouts is ``floor(a0 + w·rate·I) - floor(a0)`` for an
    initial phase ``a0``; the error is therefore below ``1 / (w · rate)`` in
    scene units, with standard deviation ``sqrt(f(1-f)) / (w · rate)`` over a
    uniform phase, ``f = frac(w·rate·I)`` (see :func:`tfp_std`).

    Parameters
    ----------
    spikes : (T, H, W) bool or integer array of 0/1
        Unpacked spike stream, row 0 = top.
    center : int or None
        Readout index to estimate at; ``None`` = ``T // 2``.
    window : int or None
        Readouts counted; see :func:`window_bounds` for placement near the ends.
        ``None`` = :func:`default_tfp_window` (41, or the stream length when
        shorter); an explicit window longer than the stream is an error.
    rate : float, default 0.6
        Spikes per readout at intensity 1.0 (the sensor's ``full_scale_rate``).

    Returns
    -------
    (H, W) float64
        Estimated linear intensity (not clipped; saturates at ``1 / rate``).

    References
    ----------
    Zhu, Duan, Dong, Xiong, Huang, "A Retina-Inspired Sampling Method for
    Visual Texture Reconstruction", ICME 2019.

    Examples
    --------
    One spike every 4 readouts: 11 spikes in 41 readouts, 11 / (41 · 0.6):

    >>> import numpy as np
    >>> from spikesim.estimate import tfp
    >>> spikes = np.zeros((41, 2, 2), np.uint8)
    >>> spikes[::4] = 1
    >>> tfp(spikes, center=20, window=41, rate=0.6).round(4).tolist()
    [[0.4472, 0.4472], [0.4472, 0.4472]]
    """
    arr = _check_spikes(spikes)
    r = _check_rate(rate)
    if window is None:
        window = default_tfp_window(arr.shape[0])
    start, stop = window_bounds(arr.shape[0], center, window)
    counts = arr[start:stop].sum(axis=0, dtype=np.int64)
    return counts.astype(np.float64) / ((stop - start) * r)


def tfp_std(intensity: float | np.ndarray, window: int, rate: float = 0.6) -> np.ndarray:
    """Theoretical standard deviation of :func:`tfp` on a perfect constant stream.

    Over a uniformly random initial accumulator phase, the count over ``w``
    readouts is ``n0`` or ``n0 + 1`` with ``P(n0+1) = f = frac(w·rate·I)``,
    so the estimate's standard deviation is ``sqrt(f·(1-f)) / (w·rate)``
    (scene units).  Valid while ``rate·I < 1`` (no clipping by the clock).
    """
    x = np.asarray(intensity, dtype=np.float64) * window * rate
    f = x - np.floor(x)
    return np.sqrt(f * (1.0 - f)) / (window * rate)


def tfi(
    spikes: np.ndarray,
    center: int | None = None,
    rate: float = 0.6,
    window: int | None = None,
    no_spike: NoSpikeRule = "bound",
) -> np.ndarray:
    """Texture from inter-spike interval, in scene units.

    For each pixel, ``p`` is the last readout ``<= center`` holding a spike and
    ``q`` the first readout ``> center`` holding one; the estimate is
    ``1 / ((q - p) · rate)``.  Every readout lies in exactly one interval
    ``[p, q)``, so averaged over time (or over the random initial phase) the
    estimate of a constant stream is unbiased for ``rate·I`` rather than
    length-biased; per frame the error is at most one readout of ISI.

    Parameters
    ----------
    spikes : (T, H, W) bool or integer array of 0/1
        Unpacked spike stream, row 0 = top.
    center : int or None
        Readout index to estimate at; ``None`` = ``T // 2``.
    rate : float, default 0.6
        Spikes per readout at intensity 1.0 (the sensor's ``full_scale_rate``).
    window : int or None
        Readouts searched for the two spikes, placed as in
        :func:`window_bounds`; ``None`` searches the whole stream.
    no_spike : {"bound", "zero", "nan", "tfp"}, default "bound"
        What a pixel gets when the search range holds no spike at or before
        the centre, or none after it:

        * ``"bound"`` — a missing ``p`` is put one readout before the search
          range and a missing ``q`` one readout after it, i.e. the shortest
          interval the data cannot rule out; a pixel with no spike at all gets
          ``1 / ((L + 1) · rate)`` for a range of ``L`` readouts, an upper bound
          on a dark pixel's intensity (what Spike-Zoo's TFI does in effect).
        * ``"zero"`` — 0.
        * ``"nan"`` — NaN, so the caller decides.
        * ``"tfp"`` — the TFP estimate over the search range (0 when it holds
          no spike at all).

    Returns
    -------
    (H, W) float64
        Estimated linear intensity.

    References
    ----------
    Zhu, Duan, Dong, Xiong, Huang, "A Retina-Inspired Sampling Method for
    Visual Texture Reconstruction", ICME 2019.
    """
    arr = _check_spikes(spikes)
    r = _check_rate(rate)
    n = arr.shape[0]
    if no_spike not in NO_SPIKE_RULES:
        raise bad_value("no_spike", no_spike, f"one of {NO_SPIKE_RULES}")
    c = _check_center(center, n)
    if window is None:
        start, stop = 0, n
    else:
        start, stop = window_bounds(n, c, window)
    if not start <= c < stop:  # a window shifted at the stream end can miss the centre
        c = min(max(c, start), stop - 1)
    before = arr[start : c + 1][::-1].astype(bool, copy=False)
    after = arr[c + 1 : stop].astype(bool, copy=False)
    has_p = before.any(axis=0)
    p = c - before.argmax(axis=0).astype(np.int64)
    if after.shape[0]:
        has_q = after.any(axis=0)
        q = c + 1 + after.argmax(axis=0).astype(np.int64)
    else:
        has_q = np.zeros(arr.shape[1:], bool)
        q = np.full(arr.shape[1:], c + 1, np.int64)
    ok = has_p & has_q
    if no_spike == "bound":
        p = np.where(has_p, p, start - 1)
        q = np.where(has_q, q, stop)
        return 1.0 / ((q - p).astype(np.float64) * r)
    out = np.empty(arr.shape[1:], np.float64)
    out[ok] = 1.0 / ((q[ok] - p[ok]).astype(np.float64) * r)
    missing = ~ok
    if no_spike == "zero":
        out[missing] = 0.0
    elif no_spike == "nan":
        out[missing] = np.nan
    else:  # "tfp"
        counts = arr[start:stop].sum(axis=0, dtype=np.int64)
        out[missing] = counts[missing] / ((stop - start) * r)
    return out
