"""The counter-based random numbers of :mod:`spikesim.rng` in PyTorch tensor code.

The same functions of (key, readout, pixel), bit for bit: ``mix64`` (the
SplitMix64 finaliser), per-readout keys ``mix64(key + n·G1)``, per-pixel bits
``mix64(rk ^ p·G2)``, and the normal deviates of :func:`spikesim.rng.normal`
(4096-bin piecewise-linear inverse CDF from the shipped float32 table, a
finer float64 table in the outer 1/128 of probability, exact inversion
``√2·erfinv(2u − 1)`` below u = 2⁻¹⁶).  Constants and tables come from
:mod:`spikesim.rng` (its Python values, no compiled function is called).

Unsigned 64-bit words are held in ``torch.int64`` tensors (the same bits, two's
complement): addition and multiplication wrap alike, a logical right shift is
the arithmetic one masked (:func:`lsr`), and unsigned order is the signed order
of the words with their top bit flipped (:func:`ult`).  Every float64 step is
one IEEE operation in the order of the numba code (no fused multiply-add), so
the deviates equal the kernel's on any device whose float64 arithmetic rounds
correctly.
"""

from __future__ import annotations

import threading

import numpy as np
import torch

from spikesim import rng as _rng

__all__ = ["as_signed", "lsr", "ult", "mix64", "readout_keys", "pixel_keys", "normal",
           "normal_exact", "sqrt_rn"]

_MIN64 = -(1 << 63)


def as_signed(v: int) -> int:
    """The int64 with the bits of the unsigned 64-bit value ``v``."""
    v = int(v) & _rng.MASK64
    return v - (1 << 64) if v >> 63 else v


_M1 = as_signed(0xBF58476D1CE4E5B9)
_M2 = as_signed(0x94D049BB133111EB)
_G1 = as_signed(_rng.G1)
_G2 = as_signed(_rng.G2)


def lsr(x: torch.Tensor, s: int) -> torch.Tensor:
    """Logical right shift of 64-bit words by ``0 < s < 64``."""
    return (x >> s) & ((1 << (64 - s)) - 1)


def ult(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """``a < b`` as unsigned 64-bit words."""
    return (a ^ _MIN64) < (b ^ _MIN64)


def mix64(z: torch.Tensor) -> torch.Tensor:
    """SplitMix64 finaliser (Mix13) on int64 words, wrapping (:func:`spikesim.rng.mix64`)."""
    z = (z ^ lsr(z, 30)) * _M1
    z = (z ^ lsr(z, 27)) * _M2
    return z ^ lsr(z, 31)


def readout_keys(keys: torch.Tensor, readouts: torch.Tensor) -> torch.Tensor:
    """``mix64(key + n·G1)`` for every key (shape ``S``) and readout ``n`` (shape
    ``(T,)``): shape ``S + (T,)`` (:func:`spikesim.rng.readout_key`)."""
    return mix64(keys.unsqueeze(-1) + readouts * _G1)


def pixel_keys(height: int, width: int, device) -> torch.Tensor:
    """(H, W) pixel terms ``p·G2`` of :func:`spikesim.rng.pixel_bits`, ``p = y·W + x``."""
    p = torch.arange(height * width, dtype=torch.int64, device=device)
    return (p * _G2).view(height, width)


_SPLIT = 134217729.0  # 2**27 + 1: Veltkamp's splitting constant for float64


def _product_error(a: torch.Tensor, b: torch.Tensor, p: torch.Tensor) -> torch.Tensor:
    """The exact rounding error ``a·b − p`` of ``p = fl(a·b)`` (Dekker's product
    with Veltkamp's split: plain float64 operations, no fused multiply-add)."""
    c = _SPLIT * a
    ah = c - (c - a)
    al = a - ah
    c = _SPLIT * b
    bh = c - (c - b)
    bl = b - bh
    return ((ah * bh - p) + ah * bl + al * bh) + al * bl


def sqrt_rn(x: torch.Tensor) -> torch.Tensor:
    """Correctly rounded square root of non-negative float64 ``x`` (as numba's
    ``np.sqrt``, the IEEE operation) on any device.

    PyTorch's CPU ``sqrt`` may come from a vector math library (MKL's) whose
    results are within one unit in the last place but not always the nearest
    double.  From that estimate ``r`` the nearest double is chosen by the
    exact test: ``r`` is ``√x`` rounded to nearest iff ``r·r⁻ < x ≤ r·r⁺``
    (``r⁻``, ``r⁺`` the neighbouring doubles; both sides are multiples of a
    grid finer than the distance between ``x``'s neighbours, and ``√x`` is
    never exactly halfway), each product compared exactly through its
    rounding error (:func:`_product_error`).  Exact for ``x`` in
    [2⁻⁹⁰⁰, 2⁹⁰⁰] and 0; on CUDA ``sqrt`` rounds correctly and the estimate
    is returned as it is."""
    r = torch.sqrt(x)
    if x.device.type == "cuda":
        return r
    up = torch.nextafter(r, torch.full_like(r, float("inf")))
    dn = torch.nextafter(r, torch.zeros_like(r))
    p = r * up
    above = (x - p) > _product_error(r, up, p)  # x > r·r⁺: round up
    p = r * dn
    below = (x - p) <= _product_error(r, dn, p)  # x ≤ r·r⁻: round down
    return torch.where(above, up, torch.where(below & (r > 0), dn, r))


class _Tables:
    """The inverse-CDF tables as float64 tensors on one device."""

    def __init__(self, device):
        pairs = _rng._ICDF_PAIRS
        q = (pairs & np.uint64(0xFFFFFFFF)).astype(np.uint32).view(np.float32)
        d = (pairs >> np.uint64(32)).astype(np.uint32).view(np.float32)
        self.q = torch.from_numpy(q.astype(np.float64)).to(device)
        self.d = torch.from_numpy(d.astype(np.float64)).to(device)
        self.tail_q = torch.from_numpy(np.asarray(_rng._TAIL_Q, np.float64)).to(device)
        self.tail_d = torch.from_numpy(np.asarray(_rng._TAIL_D, np.float64)).to(device)


_TABLES: dict = {}
_TABLES_LOCK = threading.Lock()


def _tables(device) -> _Tables:
    key = str(torch.device(device))
    with _TABLES_LOCK:
        if key not in _TABLES:
            _TABLES[key] = _Tables(device)
        return _TABLES[key]


_BIN_SHIFT = 64 - _rng.ICDF_BITS
_TAIL_LO = _rng.ICDF_TAIL_BINS
_TAIL_HI = _rng.ICDF_BINS - _rng.ICDF_TAIL_BINS
_TAIL_SHIFT = 64 - _rng.TAIL_BITS
_TAIL_POS_MASK = (1 << _TAIL_SHIFT) - 1
_EXACT_SUB = int(_rng._EXACT_SUB)


def _lookup(table: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
    """``table[index]`` (a 1-D table, any index shape; ``index_select`` is several
    times faster than advanced indexing on the CPU)."""
    return table.index_select(0, index.reshape(-1)).view(index.shape)


def _log_positive(y: torch.Tensor) -> torch.Tensor:
    """:func:`spikesim.rng.log_positive`: exponent plus a 2·atanh series of the
    mantissa folded into [√½, √2), the same operations in the same order."""
    bits = y.view(torch.int64)
    e = ((bits >> 52) - 1023).to(torch.float64)
    m = ((bits & int(_rng._MANT)) | int(_rng._ONE_BITS)).view(torch.float64)
    fold = m > _rng._SQRT2
    m = torch.where(fold, m * 0.5, m)
    e = torch.where(fold, e + 1.0, e)
    s = (m - 1.0) / (m + 1.0)
    s2 = s * s
    p = torch.full_like(s, 1.0 / 15.0)
    for c in (1.0 / 13.0, 1.0 / 11.0, 1.0 / 9.0, 1.0 / 7.0, 1.0 / 5.0, 1.0 / 3.0, 1.0):
        p = p * s2 + c
    return e * _rng._LN2 + (2.0 * s) * p


def normal_exact(bits: torch.Tensor) -> torch.Tensor:
    """:func:`spikesim.rng.normal_exact`: ``√2·erfinv(2u − 1)``, ``u`` from the top 52 bits."""
    u = (lsr(bits, 12).to(torch.float64) + 0.5) * 2.0**-52
    x = 2.0 * u - 1.0
    w = -_log_positive((4.0 * u) * (1.0 - u))
    high = w >= _rng._W_SPLIT
    s = torch.where(high, sqrt_rn(w) * _rng._HIGH_SCALE - _rng._HIGH_SHIFT,
                    w * _rng._LOW_SCALE - 1.0)
    coeff = torch.tensor(np.asarray(_rng._G_TABLE, np.float64), device=bits.device)[high.long()]
    g = torch.zeros_like(w)
    for i in range(coeff.shape[-1]):
        g = g * s + coeff[..., i]
    return _rng._SQRT2 * (x * g)


def _normal_tail(bits: torch.Tensor, tables: _Tables) -> torch.Tensor:
    """:func:`spikesim.rng._normal_tail` for words in a tail bin."""
    upper = bits < 0  # the top bit
    r = torch.where(upper, ~bits, bits)
    m = r >> _TAIL_SHIFT  # (r's top bit is 0)
    t = ((r & _TAIL_POS_MASK).to(torch.float64) + 0.5) * 2.0 ** -_TAIL_SHIFT
    mm = m.clamp_min(1)  # m = 0 is replaced by exact inversion below
    z = _lookup(tables.tail_q, mm) + _lookup(tables.tail_d, mm) * t
    z = torch.where(upper, -z, z)
    exact = m < _EXACT_SUB
    if bool(exact.any()):
        z[exact] = normal_exact(bits[exact])
    return z


def normal(bits: torch.Tensor) -> torch.Tensor:
    """Standard normal deviates of 64-bit words (:func:`spikesim.rng.normal`), float64."""
    tables = _tables(bits.device)
    k = lsr(bits, _BIN_SHIFT)
    t = ((lsr(bits, 12) & ((1 << 40) - 1)).to(torch.float64) + 0.5) * 2.0**-40
    z = _lookup(tables.q, k) + _lookup(tables.d, k) * t
    tail = (k < _TAIL_LO) | (k >= _TAIL_HI)
    idx = tail.nonzero(as_tuple=True)
    if idx[0].numel():
        z[idx] = _normal_tail(bits[idx], tables)
    return z
