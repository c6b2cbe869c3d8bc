"""NumPy twins of the kernel's counter-based random numbers (:mod:`spikesim.rng`), shared by
the slow references (:mod:`spikesim.reference`, :mod:`spikesim.reference_event`)."""

from __future__ import annotations

import numpy as np

from spikesim import rng

__all__ = ["mix64_np", "normal_np"]


def mix64_np(z: np.ndarray) -> np.ndarray:
    """SplitMix64 finaliser on uint64 arrays (wrap-around arithmetic)."""
    z = np.asarray(z, dtype=np.uint64)
    with np.errstate(over="ignore"):
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


def _readout_key_np(key: int, n: int) -> np.uint64:
    return mix64_np(np.uint64((int(key) + n * rng.G1) % 2**64))


def _pixel_bits_np(rkey: np.uint64, n_pixels: int) -> np.ndarray:
    with np.errstate(over="ignore"):
        p = np.arange(n_pixels, dtype=np.uint64) * np.uint64(rng.G2)
    return mix64_np(np.uint64(rkey) ^ p)


def _log_positive_np(y: np.ndarray) -> np.ndarray:
    """``rng.log_positive`` in NumPy, the same float64 operations in the same
    order (exponent, mantissa folded into [√½, √2), atanh series), so the same
    bits as the kernel (``np.log`` may differ in the last bit)."""
    bits = y.view(np.uint64)
    e = ((bits >> np.uint64(52)).astype(np.int64) - 1023).astype(np.float64)
    m = ((bits & rng._MANT) | rng._ONE_BITS).view(np.float64)
    fold = m > rng._SQRT2
    m = np.where(fold, m * 0.5, m)
    e = np.where(fold, e + 1.0, e)
    s = (m - 1.0) / (m + 1.0)
    s2 = s * s
    p = np.full_like(s, 1.0 / 15.0)
    for c in (1.0 / 13.0, 1.0 / 11.0, 1.0 / 9.0, 1.0 / 7.0, 1.0 / 5.0, 1.0 / 3.0, 1.0):
        p = p * s2 + c
    return e * rng._LN2 + 2.0 * s * p


def _normal_exact_np(bits: np.ndarray) -> np.ndarray:
    """Exact inversion ``√2·erfinv(2u − 1)`` (same polynomial and operation
    order as ``spikesim.rng.normal_exact``)."""
    u = ((bits >> np.uint64(12)).astype(np.float64) + 0.5) * 2.0**-52
    x = 2.0 * u - 1.0
    w = -_log_positive_np(4.0 * u * (1.0 - u))
    high = w >= rng._W_SPLIT
    s = np.where(high, np.sqrt(w) * rng._HIGH_SCALE - rng._HIGH_SHIFT, w * rng._LOW_SCALE - 1.0)
    g = np.zeros_like(w)
    for lo, hi in zip(rng._G_LOW, rng._G_HIGH, strict=True):
        g = g * s + np.where(high, hi, lo)
    return rng._SQRT2 * (x * g)


def _f32_pair(pairs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The two float32 halves (low, high) of packed uint64 table entries, as float64."""
    low = (pairs & np.uint64(0xFFFFFFFF)).astype(np.uint32).view(np.float32)
    high = (pairs >> np.uint64(32)).astype(np.uint32).view(np.float32)
    return low.astype(np.float64), high.astype(np.float64)


def _normal_tail_np(bits: np.ndarray) -> np.ndarray:
    """Tail lanes: the upper tail mirrored (``~bits``), bins of width 2**-20
    from the shipped tail table, exact inversion below 2**-16."""
    upper = (bits >> np.uint64(63)) != 0
    r = np.where(upper, ~bits, bits)
    m = (r >> np.uint64(64 - rng.TAIL_BITS)).astype(np.int64)
    t = ((r & rng._TAIL_POS_MASK).astype(np.float64) + 0.5) * 2.0 ** -(64 - rng.TAIL_BITS)
    mm = np.maximum(m, 1)  # m = 0 is replaced below
    z = rng._TAIL_Q[mm] + rng._TAIL_D[mm] * t
    z = np.where(upper, -z, z)
    exact = m < int(rng._EXACT_SUB)
    if exact.any():
        z[exact] = _normal_exact_np(bits[exact])
    return z


def normal_np(bits: np.ndarray) -> np.ndarray:
    """Standard normals, the mapping of ``spikesim.rng.normal``: linear
    interpolation in the body table (float32 pairs ``Q_k, D_k`` of the shipped
    Φ⁻¹(k/4096)), the finer tail table in the outermost ``rng.ICDF_TAIL_BINS``
    bins on each side, exact inversion beyond 2**-16."""
    bits = np.asarray(bits, dtype=np.uint64)
    k = (bits >> np.uint64(64 - rng.ICDF_BITS)).astype(np.int64)
    t = (((bits >> np.uint64(12)) & np.uint64(2**40 - 1)).astype(np.float64) + 0.5) * 2.0**-40
    q, d = _f32_pair(rng._ICDF_PAIRS[k])
    z = q + d * t
    tail = (k < rng.ICDF_TAIL_BINS) | (k >= rng.ICDF_BINS - rng.ICDF_TAIL_BINS)
    if tail.any():
        z[tail] = _normal_tail_np(bits[tail])
    return z
