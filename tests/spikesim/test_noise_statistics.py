"""Noise statistics against theory (fixed seeds, stated confidence).

Each test measures a statistic over M independent pixels; tolerances are
about 4 standard errors of that statistic (two-sided ~6e-5 false alarm
if the model were right and the seed random; the seeds are fixed).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

import spikesim as ss
from spikesim import rng
from spikesim._poisson import poisson
from spikesim.reference_event import _normal_field
from spikesim.reference_rng import _f32_pair, normal_np
from tests.support.core_helpers import counts, flat_rows

N = 4000  # readouts
W = 1024  # pixels per intensity


def test_normal_generator_matches_standard_normal():
    z = rng.pixel_normals(rng.stream_key(1, rng.STREAM_PAPER), 200_000)
    assert abs(z.mean()) < 4 / np.sqrt(z.size)
    assert abs(z.var() - 1) < 4 * np.sqrt(2 / z.size)
    assert stats.kstest(z, "norm").pvalue > 1e-3
    # the far tails exist and are symmetric
    big = rng.pixel_normals(rng.stream_key(2, rng.STREAM_PAPER), 2_000_000)
    assert np.sum(big > 4) > 50 and np.sum(big < -4) > 50


def test_icdf_tables_are_the_normal_quantiles_and_symmetric():
    tables = Path(rng.__file__).with_name("tables")
    q = np.load(tables / f"normal_icdf_{rng.ICDF_BINS}.npy")
    k = np.arange(1, rng.ICDF_BINS)
    np.testing.assert_allclose(q[1:-1], stats.norm.ppf(k / rng.ICDF_BINS), rtol=1e-14, atol=1e-15)
    np.testing.assert_array_equal(q[1:-1], -q[-2:0:-1])
    tail = np.load(tables / f"normal_icdf_tail_{rng.ICDF_BINS}.npy")
    m = np.arange(1, tail.size)
    np.testing.assert_allclose(tail[1:], stats.norm.ppf(m / 2.0**rng.TAIL_BITS), rtol=1e-14)
    # the tail table covers exactly the tail bins of the body table
    assert tail[-1] == q[rng.ICDF_TAIL_BINS]


def _bits_with_forced_tails(seed, n, n_forced):
    """``n`` hashed 64-bit words plus, from the first ``n_forced``, words forced
    into each tail region (body tail bins, fine tail bins, exact inversion),
    on both sides."""
    bits = rng.mix64(np.uint64(seed)) + np.arange(n, dtype=np.uint64) * np.uint64(rng.G2)
    forced = [np.uint64((int(b) >> s) ^ mirror) for b in bits[:n_forced]
              for s in (8, 12, 16, 17) for mirror in (0, (1 << 64) - 1)]
    return np.concatenate([bits, np.array(forced, dtype=np.uint64)])


def _bins_moments(lo, hi_edge, prob):
    """Second and fourth moments contributed by bins where z = lo + d·t, t
    uniform on [0, 1), d = hi_edge − lo, each bin carrying probability ``prob``."""
    d = hi_edge - lo
    m2 = np.sum(prob * (lo**2 + lo * d + d**2 / 3))
    m4 = np.sum(prob * ((lo + d) ** 5 - lo**5) / (5 * d))
    return m2, m4


def test_fast_normal_against_exact_quantiles_and_exact_moments():
    """Every path of :func:`rng.normal` is within 1.4e-4 of Φ⁻¹(u) (u from all
    64 bits); its variance and fourth moment, computed in closed form from the
    float32 body pairs, the tail table and the exact normal beyond 2**-16,
    are within 4e-6 and 4.5e-5 of 1 and 3."""
    bits = _bits_with_forced_tails(12345, 40_000, 3000)
    fast = np.array([rng.normal(b) for b in bits])
    u = (bits >> np.uint64(11)).astype(np.float64) * 2.0**-53 + 2.0**-54  # Φ⁻¹ needs u, 53 bits
    exact = stats.norm.ppf(u)
    assert np.max(np.abs(fast - exact)) < 1.4e-4
    # where u or 1 − u < 2**-16 the deviate is the exact inversion itself
    far = np.minimum(u, 1 - u) < rng.EXACT_BELOW * (1 - 2**-40)
    assert far.sum() > 100
    np.testing.assert_array_equal(fast[far], [rng.normal_exact(b) for b in bits[far]])
    # closed-form moments of the generator's distribution (by symmetry, 2 × lower half
    # where the tables are mirror images; the body uses its float32 pairs as stored)
    pairs = rng._ICDF_PAIRS[rng.ICDF_TAIL_BINS:rng.ICDF_BINS - rng.ICDF_TAIL_BINS]
    q, d = _f32_pair(pairs)
    m2, m4 = _bins_moments(q, q + d, 1 / rng.ICDF_BINS)
    first = int(rng._EXACT_SUB)
    tq = rng._TAIL_Q[first:]
    t2, t4 = _bins_moments(tq[:-1], tq[1:], 2.0**-rng.TAIL_BITS)
    a = stats.norm.ppf(rng.EXACT_BELOW)  # beyond it the exact normal
    e2 = stats.norm.cdf(a) - a * stats.norm.pdf(a)
    e4 = 3 * stats.norm.cdf(a) - (a**3 + 3 * a) * stats.norm.pdf(a)
    m2, m4 = m2 + 2 * (t2 + e2), m4 + 2 * (t4 + e4)
    assert abs(m2 - 1) < 4e-6 and abs(m4 - 3) < 4.5e-5


def _tail_moments():
    """Second and fourth moments of :func:`rng.normal` beyond the body table
    (both sides): the refined tail table, then the exact normal."""
    tq = rng._TAIL_Q[int(rng._EXACT_SUB):]
    t2, t4 = _bins_moments(tq[:-1], tq[1:], 2.0**-rng.TAIL_BITS)
    a = stats.norm.ppf(rng.EXACT_BELOW)
    e2 = stats.norm.cdf(a) - a * stats.norm.pdf(a)
    e4 = 3 * stats.norm.cdf(a) - (a**3 + 3 * a) * stats.norm.pdf(a)
    return 2 * (t2 + e2), 2 * (t4 + e4)


def test_normal_field_is_the_body_on_a_grid_and_the_exact_tails():
    """:func:`rng.normal_field` (26 bits, tails from further bits): in the body
    within D_k·2⁻¹⁵ ≤ 6.5e-7 of :func:`rng.normal` of any word with the same top
    26 bits; in a tail bin :func:`rng.normal` of that bin filled with the fresh
    bits (so inside the bin's quantiles); variance and fourth moment, in closed
    form over the 2¹⁴-point grid, within 4e-6 and 4.5e-5 of 1 and 3; and the
    NumPy reference gives the same bits."""
    words = _bits_with_forced_tails(99, 20_000, 1000)
    fields = words >> np.uint64(64 - rng.FIELD_BITS)
    fresh = rng.mix64(np.uint64(5)) + np.arange(words.size, dtype=np.uint64) * np.uint64(rng.G1)
    got = np.array([rng.normal_field(f, x) for f, x in zip(fields, fresh, strict=True)])
    k = (fields >> np.uint64(rng.FIELD_BITS - rng.ICDF_BITS)).astype(np.int64)
    tail = (k < rng.ICDF_TAIL_BINS) | (k >= rng.ICDF_BINS - rng.ICDF_TAIL_BINS)
    assert tail.sum() > 1000 and (~tail).sum() > 10_000
    body = np.array([rng.normal(w) for w in words[~tail]])
    assert np.max(np.abs(got[~tail] - body)) <= 6.5e-7
    edges = stats.norm.ppf(np.r_[k[tail], k[tail] + 1] / rng.ICDF_BINS).reshape(2, -1)
    assert np.all((got[tail] >= edges[0] - 1.4e-4) & (got[tail] <= edges[1] + 1.4e-4))
    composed = (fields[tail] >> np.uint64(14) << np.uint64(52)) | (fresh[tail] >> np.uint64(12))
    np.testing.assert_array_equal(got[tail], [rng.normal(w) for w in composed])
    ref = [_normal_field(int(f), int(x)) for f, x in zip(fields[:3000], fresh[:3000], strict=True)]
    np.testing.assert_array_equal(got[:3000], ref)
    # closed-form moments: z = q + d·t on the grid t_j = (j + ½)·2⁻¹⁴ in each body bin
    q, d = _f32_pair(rng._ICDF_PAIRS[rng.ICDF_TAIL_BINS:rng.ICDF_BINS - rng.ICDF_TAIL_BINS])
    t = (np.arange(2**14) + 0.5) * 2.0**-14
    et = [np.mean(t**p) for p in range(5)]
    m2 = np.sum(q**2 + 2 * q * d * et[1] + d**2 * et[2]) / rng.ICDF_BINS
    m4 = np.sum(sum(math.comb(4, p) * q ** (4 - p) * d**p * et[p] for p in range(5)))
    m4 /= rng.ICDF_BINS
    t2, t4 = _tail_moments()
    assert abs(m2 + t2 - 1) < 4e-6 and abs(m4 + t4 - 3) < 4.5e-5


def test_reference_normals_equal_kernel_normals():
    """The NumPy reference's deviates are the kernel's, bit for bit, on every
    path (body, refined tails, exact inversion, both sides)."""
    bits = _bits_with_forced_tails(7, 30_000, 500)
    np.testing.assert_array_equal(normal_np(bits), [rng.normal(b) for b in bits])


def test_block_normals_equal_scalar_normals():
    z, scratch, keys = np.empty(64), np.empty(64, np.uint64), np.empty(64, np.uint64)
    rng.pixel_keys_into(np.uint64(640), keys)
    low = high = 0
    for n in range(80):  # enough readouts that tail lanes occur
        rk = np.uint64(rng.readout_key(rng.stream_key(3, rng.STREAM_PAPER), n))
        rng.normals_into(rk, keys, z, scratch)
        bits = [np.uint64(rng.pixel_bits(rk, np.uint64(640 + i))) for i in range(64)]
        np.testing.assert_array_equal(scratch, bits)
        np.testing.assert_array_equal(z, [rng.normal(b) for b in bits])
        low += sum(int(b) >> 52 < rng.ICDF_TAIL_BINS for b in bits)
        high += sum(int(b) >> 52 >= rng.ICDF_BINS - rng.ICDF_TAIL_BINS for b in bits)
    assert low > 0 and high > 0


def test_normal_deviates_are_bounded_by_normal_abs_max():
    """Kernels prove noisy charges < 1 θ with this bound: it must hold for the
    extreme inputs (the uniforms 2**-53 and 1 − 2**-53) and be tight."""
    extremes = [0, 1, (1 << 12) - 1, (1 << 64) - 1, (1 << 64) - (1 << 12)]
    z = np.array([rng.normal(np.uint64(b)) for b in extremes])
    assert np.all(np.abs(z) < rng.NORMAL_ABS_MAX)
    assert np.abs(z).max() > rng.NORMAL_ABS_MAX - 0.05
    assert abs(np.abs(z).max() - (-stats.norm.ppf(2.0**-53))) < 1e-9


def test_mix64_matches_splitmix64_reference_value():
    # first output of SplitMix64 seeded with 0 (Steele et al. 2014)
    assert int(rng.mix64(np.uint64(rng.G1))) == 0xE220A8397B1DCDAF


@pytest.mark.parametrize("lam", [0.3, 4.0, 9.99, 10.0, 37.5, 800.0])
def test_poisson_sampler(lam):
    key = np.uint64(rng.readout_key(rng.stream_key(5, rng.STREAM_SHOT), 0))
    k = np.array([poisson(lam, np.uint64(rng.pixel_bits(key, p))) for p in range(60_000)])
    assert abs(k.mean() - lam) < 4 * np.sqrt(lam / k.size)
    assert abs(k.var() / lam - 1) < 4 * np.sqrt(2 / k.size) + 4 / np.sqrt(lam * k.size)
    if lam < 50:  # chi-square goodness of fit on the pmf
        top = int(lam + 6 * np.sqrt(lam) + 5)
        observed = np.bincount(k.astype(int), minlength=top + 1)[: top + 1]
        expected = stats.poisson.pmf(np.arange(top + 1), lam) * k.size
        keep = expected > 5
        chi2 = np.sum((observed[keep] - expected[keep]) ** 2 / expected[keep])
        assert stats.chi2.sf(chi2, keep.sum() - 1) > 1e-3


def test_block_shot_noise_equals_the_scalar_sampler():
    """The kernel's block sampler is bit for bit ``poisson`` per lane, for
    λ = 0, small (inversion in lock-step, tiny to just below 10, whole dark
    blocks too), large (rejection, squeeze or not)
    and beyond the ``log k!`` table (λ > 4096)."""
    from numba import njit

    from spikesim._poisson import _shot_noise_block

    @njit
    def block(charge, electrons, rkey, pix0):
        q = charge.copy()
        _shot_noise_block(q, electrons, rkey, pix0, np.empty(64), np.empty(64, np.uint64),
                          np.empty((5, 64)))
        return q

    gen = np.random.default_rng(4)
    electrons = gen.uniform(200.0, 2000.0, 64)
    for trial in range(60):
        charge = gen.uniform(0.0, 0.8, 64) * (gen.random(64) > 0.1)  # some lanes dark
        charge[:8] = gen.uniform(0.0, 0.01, 8)  # λ < 10: inversion
        charge[8:10] = 10.0 ** gen.uniform(-12, -3, 2) / electrons[8:10]  # λ ≪ 1
        charge[10:14] = gen.uniform(2.0, 40.0, 4)  # λ > 4096: log k! beyond the table
        if trial % 3 == 0:  # a whole dark block
            charge = gen.uniform(0.0, 10.0, 64) ** gen.uniform(1, 3) / 10.0 ** 2 / electrons
        rkey = np.uint64(rng.readout_key(rng.stream_key(7, rng.STREAM_SHOT), trial))
        got = block(charge, electrons, rkey, np.uint64(128))
        want = [poisson(charge[i] * electrons[i],
                        np.uint64(rng.pixel_bits(rkey, np.uint64(128 + i)))) / electrons[i]
                for i in range(64)]
        np.testing.assert_array_equal(got, want)


def test_lockstep_inversion_leaves_unfinished_searches_to_the_scalar_sampler():
    """Lanes whose search runs past the block's step count stay unsettled (NaN,
    then :func:`poisson` finishes them); the settled ones are ``poisson``'s."""
    from numba import njit

    from spikesim._poisson import _inversion_lockstep

    @njit
    def lockstep(lam, bits, small_max):
        z = np.full(64, np.nan)
        _inversion_lockstep(lam, bits, z, np.empty((5, 64)), small_max)
        return z

    gen = np.random.default_rng(9)
    lam = gen.uniform(0.0, 9.9, 64)
    lam[40:] = gen.uniform(10.0, 500.0, 24)  # not for the inversion: untouched
    bits = gen.integers(0, 2**63, 64, dtype=np.uint64) * np.uint64(2)
    lam[:6] = 9.5  # with u = 1 − 2**-53 the search goes far past λ + 4√λ + 6
    bits[:6] = np.uint64(2**64 - 1)
    z = lockstep(lam, bits, lam[:40].max())
    assert np.isnan(z[:6]).all() and np.isnan(z[40:]).all()
    assert not np.isnan(z[6:40]).any()
    np.testing.assert_array_equal(z[6:40], [poisson(lam[i], bits[i]) for i in range(6, 40)])
    assert min(poisson(lam[i], bits[i]) for i in range(6)) > lam[:40].max() + 4 * 3.2 + 6


def test_exp_nonpositive_is_accurate():
    x = np.concatenate([-np.linspace(0.0, 40.0, 40_001), [-1e-300, -300.0, -708.0]])
    got = np.array([rng.exp_nonpositive(v) for v in x])
    np.testing.assert_allclose(got, np.exp(x), rtol=5e-16, atol=0)


@pytest.mark.parametrize("sigma_g,sigma_p", [(10.0, 0.0), (15.0, 0.0), (3.0, 4.0)])
def test_paper_mode_mean_and_variance_follow_eq5(sigma_g, sigma_p):
    """count = floor(A0 + S), S = Σ r·max(ỹ_n, 0)/255 with ỹ ~ N(y, σ_g² + σ_p²·y):
    E = N·r·m/255 and Var = N·r²·v/255² + 1/6, where m, v are the moments of the
    Gaussian rectified at 0 (negative light clipped) and 1/6 is the uniform-A0
    quantization term."""
    levels = [0.25, 0.5, 0.9]
    noise = ss.noise.PaperNoise(sigma_g=sigma_g, sigma_p=sigma_p)
    sensor = ss.Sensor(height=len(levels), width=W, cfa=None, noise=noise)
    c = counts(ss.scenes.Static(flat_rows(levels, W)), sensor, N, seed=21)
    for row, level in enumerate(levels):
        y = 255.0 * float(np.float32(level))
        sd = float(np.sqrt(noise.variance_dn(y)))
        a = y / sd
        m1 = y * stats.norm.cdf(a) + sd * stats.norm.pdf(a)
        m2 = (y * y + sd * sd) * stats.norm.cdf(a) + y * sd * stats.norm.pdf(a)
        var_theory = N * 0.36 * (m2 - m1 * m1) / 255.0**2 + 1 / 6
        mean_theory = N * 0.6 * m1 / 255.0
        m, v = c[row].mean(), c[row].var(ddof=1)
        assert abs(m - mean_theory) < 4 * np.sqrt(var_theory / W)
        assert abs(v / var_theory - 1) < 4 * np.sqrt(2 / (W - 1))


def test_paper_noise_raises_variance_over_clean_twin():
    noise = ss.noise.PaperNoise(sigma_g=10.0)
    sensor = ss.Sensor(height=1, width=W, cfa=None, noise=noise)
    scene = ss.scenes.Static(flat_rows([0.5], W))
    noisy = counts(scene, sensor, 2000, seed=2)
    clean = counts(scene, sensor, 2000, seed=2, clean=True)
    # theory: clean 1/6 + rounding of a constant sum (< 0.25); noisy 1.27 (eq. 5)
    assert clean.var() < 0.3 and noisy.var() > 1.0


def test_shot_noise_variance():
    """Poisson electrons: Var(q_n) = q/E thresholds², so Var(count) = N·q/E + 1/6."""
    e = 50.0
    noise = ss.noise.PhysicalNoise(electrons_per_threshold=e, dark_current_rel=0.0,
                                   threshold_mismatch=0.0, prnu=0.0,
                                   temporal_threshold_noise=0.0, hot_pixel_fraction=0.0)
    sensor = ss.Sensor(height=1, width=W, cfa=None, noise=noise)
    c = counts(ss.scenes.Static(flat_rows([0.5], W)), sensor, N, seed=4)
    q = 0.6 * 0.5
    var_theory = N * q / e + 1 / 6
    assert abs(c.mean() - N * q) < 4 * np.sqrt(var_theory / W)
    assert abs(c.var(ddof=1) / var_theory - 1) < 4 * np.sqrt(2 / (W - 1))


def test_threshold_jitter_variance():
    """Renewal process with cycle lengths 1 + ε, ε ~ N(0, σ_t²): Var ≈ N·q·σ_t² + 1/6."""
    sig = 0.05
    noise = ss.noise.PhysicalNoise(shot_noise=False, dark_current_rel=0.0,
                                   threshold_mismatch=0.0, prnu=0.0,
                                   temporal_threshold_noise=sig, hot_pixel_fraction=0.0)
    sensor = ss.Sensor(height=1, width=W, cfa=None, noise=noise)
    c = counts(ss.scenes.Static(flat_rows([0.5], W)), sensor, N, seed=6)
    q = 0.3
    var_theory = N * q * sig**2 + 1 / 6
    assert abs(c.mean() - N * q) < 4 * np.sqrt(var_theory / W) + 0.5
    assert abs(c.var(ddof=1) / var_theory - 1) < 4 * np.sqrt(2 / (W - 1)) + 0.05


def _only(**kw):
    base = dict(shot_noise=False, dark_current_rel=0.0, dark_current_spread=0.0,
                threshold_mismatch=0.0, prnu=0.0, temporal_threshold_noise=0.0,
                hot_pixel_fraction=0.0)
    base.update(kw)
    return ss.noise.PhysicalNoise(**base)


def test_dark_count_rate_and_spread():
    """In the dark each pixel fires at r·d_i, d_i log-normal with mean 0.005, CV 0.39."""
    noise = _only(dark_current_rel=0.005, dark_current_spread=0.39)
    sensor = ss.Sensor(height=16, width=256, cfa=None, noise=noise)
    n = 40_000
    c = counts(ss.scenes.Static(np.zeros((16, 256))), sensor, n, seed=1, chunk=8192)
    rate = c / n
    m = rate.size
    assert abs(rate.mean() / (0.6 * 0.005) - 1) < 4 * 0.39 / np.sqrt(m) + 1 / (n * 0.003)
    cv = rate.std() / rate.mean()
    assert abs(cv - 0.39) < 4 * 0.39 / np.sqrt(2 * m) + 0.02


@pytest.mark.parametrize("name", ["threshold_mismatch", "prnu"])
def test_fixed_pattern_spread(name):
    """Flat field: per-pixel rates spread as r·I·g_i/t_i; compare the CV with the
    exact moments of 1/(1 + σz) (threshold) or (1 + σz) (gain)."""
    sigma = 0.045 if name == "threshold_mismatch" else 0.058
    sensor = ss.Sensor(height=8, width=512, cfa=None, noise=_only(**{name: sigma}))
    n = 20_000
    c = counts(ss.scenes.Static(np.full((8, 512), 0.5)), sensor, n, seed=0, chunk=8192)
    rate = c / n
    z, wts = np.polynomial.hermite_e.hermegauss(60)
    wts = wts / wts.sum()
    f = 1 / (1 + sigma * z) if name == "threshold_mismatch" else 1 + sigma * z
    mean = np.sum(wts * f)
    cv_theory = np.sqrt(np.sum(wts * f**2) - mean**2) / mean
    m = rate.size
    assert abs(rate.mean() / (0.3 * mean) - 1) < 4 * cv_theory / np.sqrt(m) + 1e-3
    assert abs(rate.std() / rate.mean() / cv_theory - 1) < 4 / np.sqrt(2 * m) + 0.02


def test_hot_pixel_fraction():
    noise = _only(hot_pixel_fraction=0.02, hot_pixel_dark_rel=0.3)
    sensor = ss.Sensor(height=64, width=256, cfa=None, noise=noise)
    c = counts(ss.scenes.Static(np.zeros((64, 256))), sensor, 200, seed=0)
    hot = c > 0
    m = hot.size
    assert abs(hot.mean() - 0.02) < 4 * np.sqrt(0.02 * 0.98 / m)
    # a hot pixel fires at r·0.3 = 0.18 per readout
    assert abs(c[hot].mean() / 200 - 0.18) < 0.01
    # the pattern belongs to the chip: same fpn_seed, same pixels, any simulation seed
    c2 = counts(ss.scenes.Static(np.zeros((64, 256))), sensor, 200, seed=99)
    np.testing.assert_array_equal(c2 > 0, hot)


def test_log_factorial_table_equals_lgamma_inside_and_beyond_the_table():
    import math

    from numba import njit

    from spikesim._poisson import _LOG_FACTORIAL, _log_factorial

    @njit
    def both(k):
        return _log_factorial(k), math.lgamma(k + 1.0)

    n = _LOG_FACTORIAL.shape[0]
    for k in [0.0, 1.0, 2.0, 9.0, 10.0, 57.0, 480.0, n - 1.0, float(n), n + 7.0, 1e6]:
        got, want = both(k)
        assert got == want, k


def test_float_of_52_and_uint_of_52_are_the_exact_conversions():
    """The vectorisable conversions of :mod:`spikesim.rng` equal the plain ones
    on their whole range [0, 2⁵²): both ends, powers of two and their
    neighbours, and random values (the normals and uniforms use them)."""
    edges = [0, 1, 2, 3, 2**52 - 1, 2**52 - 2, 2**40 - 1, 2**40, 4095, 4096]
    edges += [2**k + d for k in range(1, 52) for d in (-1, 0, 1)]
    rand = np.random.default_rng(0).integers(0, 2**52, 20_000, dtype=np.uint64)
    ints = np.concatenate([np.array(edges, dtype=np.uint64), rand])
    floats = ints.astype(np.float64)
    assert [rng.float_of_52(v) for v in ints] == floats.tolist()
    assert [int(rng.uint_of_52(x)) for x in floats] == ints.tolist()
    assert int(rng.uint_of_52(-0.0)) == 0
