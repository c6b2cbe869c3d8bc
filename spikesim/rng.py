"""Counter-based random numbers: a pure function of (seed, stream, pixel, readout).

Every random number the simulator draws is a hash of its coordinates, never a
state that advances, so the same seed gives the same bits whatever the chunk
size, the thread count or the order of work (docs/model.md, "Random numbers").

Construction (all arithmetic modulo 2**64):

* ``stream_key(seed, stream)`` — a 64-bit key per (seed, noise source);
* ``readout_key(key, n) = mix64(key + n·G1)``, computed once per readout;
* ``pixel_bits(rk, p) = mix64(rk ^ p·G2)`` for pixel index ``p = y·W + x``.

``mix64`` is the SplitMix64 output finaliser (Steele, Lea & Flood, "Fast
splittable pseudorandom number generators", OOPSLA 2014; constants of
D. Stafford's "Mix13" variant), a bijection of 64-bit words with full
avalanche.  Uniforms use the top 52 bits, ``u = ((h >> 12) + 0.5) · 2**-52``
in (0, 1).  Normal deviates (:func:`normal`) come from a piecewise-linear
inverse CDF: 4096 equal-probability bins for the body (one packed float32
table entry, a single lookup, and one multiply-add), bins 256× finer in the
outer 1/128 of probability, and exact inversion below u = 2**-16 (and above
1 − 2**-16): ``z = √2 · erfinv(2u − 1)``, ``erfinv`` evaluated as
``x · g(w)``, ``w = −log(1 − x²)`` (the variable of M. Giles, "Approximating
the erfinv function", GPU Computing Gems, 2011), and g a polynomial fitted by
``tools/fit_erfinv.py`` (relative error < 1.3e-9 down to u = 2**-53, i.e.
|z| ≤ 8.3).  The logarithm is computed here from the float's exponent and a
series so that the kernel loops vectorise (no libm call).

All functions are numba ``njit``.
"""

from __future__ import annotations

import math
from pathlib import Path

import llvmlite.ir as llvm_ir
import numpy as np
from numba import njit, types
from numba.extending import intrinsic

from spikesim._simd import LANES as BLOCK_LANES
from spikesim._simd import high_bits_at_least64, lowest_bit_index

__all__ = [
    "STREAM_INIT",
    "STREAM_PAPER",
    "STREAM_SHOT",
    "STREAM_JITTER",
    "STREAM_CHARGE",
    "STREAM_WAIT",
    "STREAM_RESIDUAL",
    "STREAM_REFILL",
    "STREAM_FPN_THRESHOLD",
    "STREAM_FPN_GAIN",
    "STREAM_FPN_DARK",
    "STREAM_FPN_HOT",
    "MASK64",
    "G1",
    "G2",
    "mix64",
    "stream_key",
    "readout_key",
    "pixel_bits",
    "uniform",
    "normal",
    "normal_exact",
    "normal_field",
    "NORMAL_ABS_MAX",
    "normals_into",
    "pixel_keys_into",
    "log_positive",
    "exp_nonpositive",
    "erfinv",
    "pixel_normals",
    "pixel_uniforms",
]

MASK64 = (1 << 64) - 1
G1 = 0x9E3779B97F4A7C15  # 2**64 / golden ratio
G2 = 0xD1B54A32D192ED03  # an odd constant with good bit dispersion

# Noise-source stream identifiers (part of the file format's reproducibility
# contract: changing them changes every simulated stream).
STREAM_INIT = 1
STREAM_PAPER = 2
STREAM_SHOT = 3
STREAM_JITTER = 4
STREAM_CHARGE = 5
# Event-driven shot noise (spikesim._event): keyed per (pixel, firing cycle),
# the cycle index taking the place of the readout index.
STREAM_WAIT = 6
STREAM_RESIDUAL = 7
STREAM_REFILL = 8
STREAM_FPN_THRESHOLD = 16
STREAM_FPN_GAIN = 17
STREAM_FPN_DARK = 18
STREAM_FPN_HOT = 19

_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_G1 = np.uint64(G1)
_G2 = np.uint64(G2)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S12 = np.uint64(12)
_S52 = np.uint64(52)
_TWO_M52 = 2.0**-52
_ONE = np.uint64(1)
_MANT = np.uint64(0x000FFFFFFFFFFFFF)
_ONE_BITS = np.uint64(0x3FF0000000000000)
_SQRT2 = 1.4142135623730951
_LN2 = 0.6931471805599453

# erfinv(x) = x * g(w), w = -log(1 - x^2); Horner coefficients, highest degree
# first, in the normalised variable s in [-1, 1] (see tools/fit_erfinv.py).
_G_LOW = (1.8592610894098583e-07, -8.464437773624513e-07, -9.363845561391755e-08,
          6.660972032607879e-06, -1.180768858306798e-05, -1.456725162160255e-05,
          9.367107446406456e-05, -0.00011713384656548219, -0.0002644927611571621,
          0.0012325579311627515, -0.0012716740594109798, -0.004137325568006293,
          0.017808360142313722, -0.022604446683662592, -0.058922567044518814,
          0.7504943200646456, 1.6536545626827615)  # w in [0, 6.25]
_G_HIGH = (2.9963650963221848e-05, 8.234976745370404e-06, -0.0002155782752685568,
           0.00017656762607483667, 0.0002759542388929564, -0.0005026178101840458,
           0.00039129566240308556, -0.00040835988661481803, 0.0005064835089908585,
           -0.0005181167009006673, 0.0006429508301859733, -0.0011284280871460062,
           0.002115982102576942, -0.0033354996800940805, 0.0019171344351457086,
           1.8506822426766056, 4.175255197909927)  # sqrt(w) in [2.5, 6.1644...]
_W_SPLIT = 6.25
_HIGH_A = 2.5
_HIGH_B = 6.164414002968976


def _reinterpret(src, dst, llvm_dst):
    """A numba intrinsic reading a ``src`` value's bits as a ``dst`` (same width, no conversion)."""

    @intrinsic
    def reinterpret(typingctx, x):
        if x != src:
            return None

        def codegen(context, builder, signature, args):
            return builder.bitcast(args[0], llvm_dst)

        return dst(src), codegen

    return reinterpret


_f64_bits = _reinterpret(types.float64, types.uint64, llvm_ir.IntType(64))
_bits_f64 = _reinterpret(types.uint64, types.float64, llvm_ir.DoubleType())
_bits_f32 = _reinterpret(types.uint32, types.float32, llvm_ir.FloatType())


@njit(cache=True, inline="always", error_model="numpy")
def mix64(z):
    """SplitMix64 finaliser (Mix13): a bijective 64-bit avalanche hash."""
    z = np.uint64(z)
    z = (z ^ (z >> _S30)) * _M1
    z = (z ^ (z >> _S27)) * _M2
    return z ^ (z >> _S31)


def stream_key(seed: int, stream: int) -> np.uint64:
    """64-bit key of one noise source for one seed (Python-level helper)."""
    seed = int(seed) & MASK64
    k = _mix64_int((seed + G1) & MASK64)
    return np.uint64(_mix64_int((k + int(stream) * G2) & MASK64))


def _mix64_int(z: int) -> int:
    """:func:`mix64` on a Python int (no compiled-call overhead for the few keys of a call)."""
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & MASK64
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & MASK64
    return z ^ (z >> 31)


@njit(cache=True, inline="always", error_model="numpy")
def readout_key(key, n):
    """Per-readout key: ``mix64(key + n·G1)`` for readout index ``n >= 0``."""
    return mix64(counter_input(key, n))


@njit(cache=True, inline="always", error_model="numpy")
def counter_input(key, n):
    """What :func:`readout_key` mixes, ``key + n·G1`` (mod 2⁶⁴): a Weyl
    sequence in ``n``, so the input for ``n + 1`` is this plus ``G1``."""
    return np.uint64(key) + np.uint64(n) * _G1


@njit(cache=True, inline="always", error_model="numpy")
def pixel_bits(rkey, pixel):
    """64 random bits for one pixel under a readout key."""
    return mix64(np.uint64(rkey) ^ (np.uint64(pixel) * _G2))


_TWO52_BITS = np.uint64(0x4330000000000000)  # the bits of 2.0**52


@njit(cache=True, inline="always", error_model="numpy")
def float_of_52(v):
    """``float64(v)`` for an integer ``0 ≤ v < 2**52``, exactly: ``v`` put into
    the mantissa of 2⁵² and 2⁵² subtracted.  The same value as the conversion,
    but an integer-or and a subtraction, which vectorise on AVX2 (it has no
    64-bit integer-to-float instruction, so LLVM made such loops scalar)."""
    return _bits_f64(v | _TWO52_BITS) - 2.0**52


@njit(cache=True, inline="always", error_model="numpy")
def uint_of_52(x):
    """``uint64(x)`` for an integer-valued float ``0 ≤ x < 2**52``, exactly
    (the inverse of :func:`float_of_52`: branch-free, so it vectorises)."""
    return _f64_bits(x + 2.0**52) & _MANT


@njit(cache=True, inline="always", error_model="numpy")
def uniform(bits):
    """Uniform deviate in (0, 1) from the top 52 bits: ``(k + ½)·2**-52``.

    The grid is symmetric about ½ and ``1 − u`` is exact, which keeps the
    normal deviates symmetric in the far tails.
    """
    return (float_of_52(bits >> _S12) + 0.5) * _TWO_M52


@njit(cache=True, inline="always", error_model="numpy")
def log_positive(y):
    """Natural log of a positive, normal float64 (absolute error < 1e-13).

    ``y = 2**e · m`` with ``m`` folded into [√½, √2); ``log m = 2 atanh(s)``,
    ``s = (m − 1)/(m + 1)``, summed to s**15 (|s| < 0.172).
    """
    bits = _f64_bits(y)
    e = np.float64(np.int64(bits >> _S52) - 1023)
    m = _bits_f64((bits & _MANT) | _ONE_BITS)
    if m > _SQRT2:
        m = m * 0.5
        e = e + 1.0
    s = (m - 1.0) / (m + 1.0)
    s2 = s * s
    p = 1.0 / 15.0
    p = p * s2 + 1.0 / 13.0
    p = p * s2 + 1.0 / 11.0
    p = p * s2 + 1.0 / 9.0
    p = p * s2 + 1.0 / 7.0
    p = p * s2 + 1.0 / 5.0
    p = p * s2 + 1.0 / 3.0
    p = p * s2 + 1.0
    return e * _LN2 + 2.0 * s * p


# exp: Cody–Waite split of ln 2 (the high part has 32 significant bits, so
# n·_LN2_HI is exact for |n| < 2**20) and Taylor coefficients 1/k!.
_INV_LN2 = 1.4426950408889634
_LN2_HI = 6.93147180369123816490e-01
_LN2_LO = 1.90821492927058770002e-10
_EXP_TAYLOR = tuple(1.0 / math.factorial(k) for k in range(13, -1, -1))  # 1/13! … 1/0!


@njit(cache=True, inline="always", error_model="numpy")
def exp_nonpositive(x):
    """``e**x`` for ``−708 ≤ x ≤ 0`` (relative error < 5e-16), vectorisable
    (no libm call).  ``x = n·ln 2 + r`` with ``|r| ≤ ½ ln 2`` (Cody & Waite's
    two-part ln 2), ``e**r`` by its Taylor series to ``r**13`` (remainder
    < 1e-17), and ``2**n`` added to the exponent bits."""
    n = np.floor(x * _INV_LN2 + 0.5)
    r = (x - n * _LN2_HI) - n * _LN2_LO
    p = 0.0
    for c in _EXP_TAYLOR:
        p = p * r + c
    return _bits_f64(_f64_bits(p) + np.uint64(np.int64(n) << np.int64(52)))


# Range normalisation as multiply-adds (divisions by constants do not vectorise
# cheaply without fast-math); the fit used the same affine maps.
_LOW_SCALE = 2.0 / _W_SPLIT
_HIGH_SCALE = 2.0 / (_HIGH_B - _HIGH_A)
_HIGH_SHIFT = (_HIGH_A + _HIGH_B) / (_HIGH_B - _HIGH_A)
_G_TABLE = np.array([_G_LOW, _G_HIGH], dtype=np.float64)
_N_COEFF = len(_G_LOW)


@njit(cache=True, inline="always", error_model="numpy")
def _erfinv_core(x, one_minus_x2):
    """erfinv(x) given x and 1 − x² (the caller computes the latter accurately).

    Both ranges share one Horner loop with per-lane coefficient selection, so
    the loop vectorises (no data-dependent branch).
    """
    w = -log_positive(one_minus_x2)
    high = w >= _W_SPLIT
    r = np.sqrt(w)
    s_low = w * _LOW_SCALE - 1.0
    s_high = r * _HIGH_SCALE - _HIGH_SHIFT
    s = s_high if high else s_low
    g = 0.0
    for i in range(_N_COEFF):
        g = g * s + (_G_TABLE[1, i] if high else _G_TABLE[0, i])
    return x * g


@njit(cache=True, inline="always", error_model="numpy")
def erfinv(x):
    """Inverse error function for x in (−1, 1) (relative error < 1.3e-9)."""
    return _erfinv_core(x, (1.0 - x) * (1.0 + x))


@njit(cache=True, inline="always", error_model="numpy")
def normal_exact(bits):
    """Standard normal deviate from 64 random bits by exact inversion,
    ``√2·erfinv(2u − 1)`` with ``u = uniform(bits)`` (see the module doc)."""
    u = uniform(bits)
    # 1 - x^2 = 4u(1 - u): both factors exact, no cancellation near the tails.
    return _SQRT2 * _erfinv_core(2.0 * u - 1.0, 4.0 * u * (1.0 - u))


# Fast path: piecewise-linear inverse CDF.  Body: the top ICDF_BITS bits pick
# one of ICDF_BINS equal-probability bins k, the next 40 bits the position t in
# it; table entry k packs (Q_k, D_k) as two float32 in one uint64 so that a
# vector of lanes needs a single gather.  Tails: the ICDF_TAIL_BINS outermost
# body bins on each side (u < 2**-8 or u > 1 − 2**-8) are refined 256× by the
# next 8 bits (a float64 table read per tail lane); below 2**-16 exact inversion.
ICDF_BITS = 12
ICDF_BINS = 1 << ICDF_BITS
ICDF_TAIL_BINS = 16
TAIL_BITS = 20  # tail bins are 2**-TAIL_BITS wide
EXACT_BELOW = 2.0**-16  # exact inversion for u (or 1 − u) below this
_TABLES = Path(__file__).with_name("tables")
_BODY_Q = np.load(_TABLES / f"normal_icdf_{ICDF_BINS}.npy")  # Φ⁻¹(k/4096), ±inf ends
_BODY_Q[0], _BODY_Q[-1] = _BODY_Q[1], _BODY_Q[-2]  # tail bins: never read; finite
_ICDF_PAIRS = (_BODY_Q[:-1].astype(np.float32).view(np.uint32).astype(np.uint64)
               | (np.diff(_BODY_Q).astype(np.float32).view(np.uint32).astype(np.uint64)
                  << np.uint64(32)))
_TAIL_Q = np.load(_TABLES / f"normal_icdf_tail_{ICDF_BINS}.npy")  # Φ⁻¹(m/2**20)
_TAIL_Q[0] = _TAIL_Q[1]  # exact inversion there: never read; finite
_TAIL_D = np.diff(_TAIL_Q)
_S52_BIN = np.uint64(64 - ICDF_BITS)
_POS_MASK = np.uint64((1 << 40) - 1)
_TWO_M40 = 2.0**-40
_TAIL_LO = np.uint64(ICDF_TAIL_BINS)
_BODY_SPAN = np.uint64(ICDF_BINS - 2 * ICDF_TAIL_BINS)
_S_TAIL = np.uint64(64 - TAIL_BITS)
_TAIL_POS_MASK = np.uint64((1 << (64 - TAIL_BITS)) - 1)
_TWO_M_TAIL_POS = 2.0 ** -(64 - TAIL_BITS)
_EXACT_SUB = np.uint64(EXACT_BELOW * 2**TAIL_BITS)
_LOW32 = np.uint64(0xFFFFFFFF)
_S32 = np.uint64(32)
_S63 = np.uint64(63)
# Bound on |normal(bits)| over all 2**64 inputs: the extreme uniforms are
# 2**-53 and 1 − 2**-53, where Φ⁻¹ is ±8.21 (tested).  Kernels use it to prove
# that a noisy charge stays below one threshold.
NORMAL_ABS_MAX = 8.25


@njit(cache=True, inline="always", error_model="numpy")
def _body_deviate(k, t):
    """``z = float64(Q_k) + float64(D_k)·t`` in body bin ``k`` from its packed
    float32 pair, ``t`` ∈ (0, 1) the position in the bin."""
    pair = _ICDF_PAIRS[k]
    q = np.float64(_bits_f32(np.uint32(pair & _LOW32)))
    d = np.float64(_bits_f32(np.uint32(pair >> _S32)))
    return q + d * t


@njit(cache=True, inline="always", error_model="numpy")
def _normal_body(bits):
    """(deviate by the body table, True when the bits fall in a tail bin)."""
    k = bits >> _S52_BIN
    t = (float_of_52((bits >> _S12) & _POS_MASK) + 0.5) * _TWO_M40
    return _body_deviate(k, t), (k - _TAIL_LO) >= _BODY_SPAN  # unsigned wrap


@njit(cache=True, inline="always", error_model="numpy")
def _normal_tail(bits):
    """Deviate for bits in a tail bin (|z| > 2.66): the upper tail is mirrored
    onto the lower (``~bits`` is the uniform ``1 − u`` exactly), the top 20
    bits pick a bin of width 2**-20, the other 44 the position in it; exact
    inversion below u = 2**-16 (|z| > 4.17)."""
    upper = (bits >> _S63) != 0
    r = ~bits if upper else bits
    m = r >> _S_TAIL
    if m < _EXACT_SUB:
        return normal_exact(bits)
    t = (np.float64(r & _TAIL_POS_MASK) + 0.5) * _TWO_M_TAIL_POS
    z = _TAIL_Q[m] + _TAIL_D[m] * t
    return -z if upper else z


@njit(cache=True, inline="always", error_model="numpy")
def normal(bits):
    """Standard normal deviate from 64 random bits (the simulator's normal).

    ``u = (k + t)/4096`` with bin ``k`` the top 12 bits and ``t`` from the next
    40: inside the 4064 central bins ``z = Q_k + D_k·t`` with ``Q_k`` and
    ``D_k = Φ⁻¹((k+1)/4096) − Q_k`` from the shipped table of
    ``Φ⁻¹(k/4096)`` (``tools/make_icdf_table.py``) rounded to float32, each
    bin carrying exactly its probability 1/4096.  In the 16 outermost bins on
    each side (|z| > 2.66, probability 1/128) the same on bins of width 2**-20
    (a second shipped table, float64), and exact inversion
    (:func:`normal_exact`) where u or 1 − u is below 2**-16 (|z| > 4.17,
    probability 3e-5).  The error is below 1.4e-4 in z (interpolation, largest
    at the edges of the two tables; the float32 rounding adds < 2.4e-7); the
    variance is off by < 4e-6 and the fourth moment by < 4.5e-5 (computed exactly
    from the tables in the tests), far below what a simulation can resolve.
    """
    z, tail = _normal_body(bits)
    return _normal_tail(bits) if tail else z


#: A normal deviate from a ``FIELD_BITS``-bit field of a word, so that one
#: hash can feed several draws (:func:`normal_field`): the top
#: :data:`ICDF_BITS` (12) pick the bin as in :func:`normal`, the other 14 the
#: position in it.
FIELD_BITS = 26
_FIELD_POS = np.uint64(FIELD_BITS - ICDF_BITS)
_FIELD_POS_MASK = np.uint64((1 << (FIELD_BITS - ICDF_BITS)) - 1)
_TWO_M_FIELD_POS = 2.0 ** -(FIELD_BITS - ICDF_BITS)


@njit(cache=True, inline="always", error_model="numpy")
def normal_field_body(f):
    """(deviate by the body table, True when the field falls in a tail bin) for
    a 26-bit field ``f`` (:func:`normal_field`); branch-free."""
    k = f >> _FIELD_POS
    t = (float_of_52(f & _FIELD_POS_MASK) + 0.5) * _TWO_M_FIELD_POS
    return _body_deviate(k, t), (k - _TAIL_LO) >= _BODY_SPAN  # unsigned wrap


@njit(cache=True, inline="always", error_model="numpy")
def normal_field(f, fresh):
    """Standard normal deviate from a 26-bit field ``f`` (bits of a hash shared
    with other draws) and, in the tails only, 64 further bits ``fresh``.

    ``u = (k + t)/4096`` with bin ``k`` the field's top 12 bits and ``t`` on a
    grid of 2⁻¹⁴ (the sub-bin midpoints) from its other 14.  In the 4064
    central bins ``z = Q_k + D_k·t`` as in :func:`normal`: the grid moves ``z``
    by at most ``D_k·2⁻¹⁵`` ≤ 6.5e-7 from the continuous interpolation, far
    below its error (1.4e-4).  In a tail bin the deviate is :func:`normal` of
    the word whose top 12 bits are ``k`` and whose other 52 are the top of
    ``fresh``: uniform within the same bin, so the tails are :func:`normal`'s
    own (finer table, exact inversion below 2⁻¹⁶)."""
    z, tail = normal_field_body(f)
    if tail:
        return normal(((f >> _FIELD_POS) << _S52_BIN) | (fresh >> _S12))
    return z


@njit(cache=True, inline="always", error_model="numpy")
def pixel_keys_into(pixel0, keys):
    """``keys[i] = (pixel0 + i)·G2``: the pixel term of :func:`pixel_bits` for
    consecutive pixels, computed once per block instead of once per draw."""
    for i in range(keys.shape[0]):
        keys[i] = (np.uint64(pixel0) + np.uint64(i)) * _G2


@njit(cache=True, inline="always", error_model="numpy")
def normals_into(rkey, pixel_keys, z, bits):
    """``z[i] = normal(mix64(rkey ^ pixel_keys[i]))`` for the 64 lanes of a block
    (with ``pixel_keys`` from :func:`pixel_keys_into`, the normals of
    ``pixel_bits(rkey, pixel0 + i)``), vectorised: a branch-free table pass
    that keeps the random bits in ``bits``, then the tail lookup for the few
    tail lanes only (found from a 64-bit lane mask).  All arrays hold 64
    C-contiguous lanes."""
    rk = np.uint64(rkey)
    for i in range(BLOCK_LANES):
        b = mix64(rk ^ pixel_keys[i])
        z[i], _ = _normal_body(b)
        bits[i] = b
    tails = high_bits_at_least64(bits, _S52_BIN, _TAIL_LO, _BODY_SPAN)
    while tails:
        i = lowest_bit_index(tails)
        z[i] = _normal_tail(bits[i])
        tails &= tails - _ONE


@njit(cache=True, error_model="numpy")
def pixel_normals(key, n_pixels):
    """Standard normal deviates for pixels 0..n-1 of a per-pixel stream (readout 0)."""
    rk = readout_key(key, 0)
    out = np.empty(n_pixels, np.float64)
    for p in range(n_pixels):
        out[p] = normal(pixel_bits(rk, p))
    return out


@njit(cache=True, error_model="numpy")
def pixel_uniforms(key, n_pixels):
    """Uniform deviates in (0, 1) for pixels 0..n-1 of a per-pixel stream (readout 0)."""
    rk = readout_key(key, 0)
    out = np.empty(n_pixels, np.float64)
    for p in range(n_pixels):
        out[p] = uniform(pixel_bits(rk, p))
    return out
