"""Event-driven shot noise (``spikesim._event``): bit for bit against the NumPy
reference, in law against the per-readout sampler and the theory, invariant to
chunking.

Statistical tolerances: KS two-sample p-values > 1e-4 and means within about
4 standard errors (false alarm ~1e-4 per check if the laws were equal; the
seeds are fixed, so a pass is reproducible).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

import spikesim as ss
from spikesim import _event, _kernels
from spikesim._poisson import poisson
from spikesim.analysis import theory
from spikesim.errors import SpikeSimValueError
from spikesim.reference import mix64_np, reference_simulate
from spikesim.reference_event import gamma_ref, poisson_ref
from tests.support.core_helpers import Keyframes, flat_rows

RESETS = ["modulo", "subtract", "zero"]


def _scene(rng, h, w, bright, clock, n):
    imgs = [(rng.random((h, w, 3)) * bright).astype(np.float32) for _ in range(3)]
    return Keyframes(np.array([0.0, 0.37 * n, 0.81 * n + 0.5]) / clock, imgs)


@pytest.mark.parametrize("reset", RESETS)
@pytest.mark.parametrize("e, bright, loss, jitter", [
    (1000.0, 1.0, 0.0, 0.006),   # the defaults
    (37.3, 2.5, 0.3, 0.05),      # few electrons, saturating light, large loss and jitter
    (3.6, 1.5, 0.0, 0.1),        # a handful of electrons: many drops and backlogs
])
def test_event_sampler_matches_reference(reset, e, bright, loss, jitter):
    """Moving scene, fixed patterns, hot pixels, every reset; chunk size 13."""
    rng = np.random.default_rng(5)
    clock, n = 1000.0, 90
    noise = ss.noise.PhysicalNoise(electrons_per_threshold=e, temporal_threshold_noise=jitter,
                                   reset_charge_loss=loss, hot_pixel_fraction=0.05)
    sensor = ss.Sensor(height=3, width=70, cfa="RGGB", clock_hz=clock, reset=reset, noise=noise)
    scene = _scene(rng, 3, 70, bright, clock, n)
    got = ss.simulate(scene, sensor, n, seed=7, chunk_readouts=13).packed
    want = reference_simulate(scene, sensor, n, seed=7)
    np.testing.assert_array_equal(got, want)
    assert 0.02 < ss.bits.unpack(got, 70).mean() < 0.98


@pytest.mark.parametrize("reset", RESETS)
@pytest.mark.parametrize("e, bright, jitter", [(1000.0, 1.0, 0.006), (3.6, 1.5, 0.1)])
def test_static_scene_matches_reference(reset, e, bright, jitter):
    """A static scene (every run of constant radiance: firing to firing,
    :func:`spikesim._event.event_direct`), chunk size 29, against the reference."""
    rng = np.random.default_rng(6)
    clock, n = 1000.0, 120
    noise = ss.noise.PhysicalNoise(electrons_per_threshold=e, temporal_threshold_noise=jitter,
                                   hot_pixel_fraction=0.05)
    sensor = ss.Sensor(height=3, width=70, cfa="RGGB", clock_hz=clock, reset=reset, noise=noise)
    scene = ss.scenes.Static((rng.random((3, 70, 3)) * bright).astype(np.float32))
    got = ss.simulate(scene, sensor, n, seed=3, chunk_readouts=29).packed
    np.testing.assert_array_equal(got, reference_simulate(scene, sensor, n, seed=3))
    assert 0.02 < ss.bits.unpack(got, 70).mean() < 0.98


@pytest.mark.parametrize("reset", RESETS)
def test_long_moving_runs_walked_equal_the_readout_loop_and_the_reference(reset):
    """Runs of changing radiance from :data:`MOVING_WALK_MIN` readouts on go from
    firing to firing; cut into chunks of 7 readouts the same runs take the
    readout loop.  Both give the reference's bits (fixed patterns, hot pixels,
    jitter), so the walk is exact for a changing charge."""
    rng = np.random.default_rng(15)
    clock, n = 1000.0, 2 * _event.MOVING_WALK_MIN + 60
    noise = ss.noise.PhysicalNoise(electrons_per_threshold=300.0, temporal_threshold_noise=0.02,
                                   hot_pixel_fraction=0.05)
    sensor = ss.Sensor(height=3, width=70, cfa="RGGB", clock_hz=clock, reset=reset, noise=noise)
    imgs = [(rng.random((3, 70, 3)) * 1.6).astype(np.float32) for _ in range(3)]
    imgs[1][:, :20] = 0.0  # light that fades to nothing and comes back
    keys = np.array([0.0, _event.MOVING_WALK_MIN + 0.5, n - 1.0]) / clock
    scene = Keyframes(keys, imgs)
    walked = ss.simulate(scene, sensor, n, seed=2, chunk_readouts=n).packed
    looped = ss.simulate(scene, sensor, n, seed=2, chunk_readouts=7).packed
    np.testing.assert_array_equal(walked, looped)
    np.testing.assert_array_equal(walked, reference_simulate(scene, sensor, n, seed=2))
    assert 0.02 < ss.bits.unpack(walked, 70).mean() < 0.98


def _per_readout(ev, lam, dlam, electrons, reset, jitter, keys, lkw, count):
    """The definition :func:`event_direct` must equal: subtract ``lam + k·dlam``
    at readout ``k``, fire where the wait is ≤ 0 and end the cycle with
    :func:`fire_cycle`.  Returns the spike words; ``ev`` is advanced."""
    words = []
    for k in range(count):
        ev[_event.WAIT] = ev[_event.WAIT] - (lam + np.float64(k) * dlam)
        word = 0
        for lane in np.flatnonzero(ev[_event.WAIT] <= 0.0).tolist():
            word |= 1 << lane
            ev[_event.WAIT, lane], ev[_event.NEED, lane], ev[_event.CYCLE, lane] = (
                _event.fire_cycle(ev[_event.WAIT, lane], ev[_event.NEED, lane],
                                  ev[_event.CYCLE, lane], electrons[lane], reset, jitter,
                                  lkw[lane], keys[1], keys[2], np.uint64(lane)))
        words.append(word)
    return words


def _direct_block(rng, e, count, moving):
    """A block's state and charges covering the direct path's cases: no light,
    a trace of it, typical, near and beyond one threshold a readout (modulo
    drops, subtract backlogs), waits at or below zero and waits beyond the
    exact ranges (stepped); ``moving``: charges that change by up to 3× (up
    and down, from zero) over the ``count`` readouts, half the lanes."""
    electrons = e * (1.0 + 0.05 * rng.standard_normal(64))
    frac = rng.random(64)
    lam = electrons * np.repeat([0.0, 1e-7, 0.05, 0.17, 0.4, 0.75, 1.2, 3.0], 8)
    lam = np.array([_event.on_grid(x) for x in lam])
    dlam = np.zeros(64)
    if moving:
        change = np.where(lam > 0, lam, 0.3 * electrons) * rng.uniform(-0.9, 2.0, 64)
        change[lam == 0] = np.abs(change[lam == 0])
        dlam = np.array([_event.on_grid(x) for x in change / count])
        dlam[::2] = 0.0
    ev = np.zeros((4, 64))
    ev[_event.NEED] = electrons * (1.0 - frac)
    ev[_event.CYCLE] = rng.integers(0, 50, 64).astype(np.float64)
    ev[_event.WAIT] = electrons * (1.0 - frac) * (0.5 + rng.random(64))
    ev[_event.WAIT, ::9] = -rng.random(8) * lam[::9]  # fire at the first readout
    ev[_event.WAIT, 5::13] = 2.0**20 + rng.random(5) * 1e3  # beyond the exact range
    ev[_event.WAIT, 3::16] = 2.0**19 + rng.random(4) * 1e3  # beyond a moving lane's
    for lane, k in zip((42, 43, 60, 61), (5, 137, 138, count), strict=True):  # ties: the sum
        ev[_event.WAIT, lane] = _event.charge_sum(float(k), lam[lane], dlam[lane])  # reaches it
    return ev, lam, dlam, electrons


@pytest.mark.parametrize("moving", [False, True])
@pytest.mark.parametrize("reset", [0, 1, 2])
@pytest.mark.parametrize("e, jitter", [(1000.0, 0.006), (1000.0, 0.0), (40.0, 0.1), (5.0, 0.2)])
def test_direct_runs_equal_the_per_readout_definition_bit_for_bit(reset, e, jitter, moving):
    """:func:`event_direct` (firing to firing) gives the words and the state of
    the per-readout definition bit for bit, in one run or split in two, for
    constant and for linear charges."""
    rng = np.random.default_rng(reset * 17 + int(e) + 5 * moving)
    count = 300
    ev, lam, dlam, electrons = _direct_block(rng, e, count, moving)
    keys = rng.integers(1, 2**63, 3, dtype=np.uint64)
    wu = np.zeros((_event.EV_WORK_U, 64), np.uint64)
    wu[_event.LKW] = [_event.lane_key(keys[0], np.uint64(p)) for p in range(64)]
    wf = np.zeros((_event.EV_WORK_F, 64))
    want_ev = ev.copy()
    want = _per_readout(want_ev, lam, dlam, electrons, reset, jitter, keys, wu[_event.LKW], count)
    for split in (count, 137):
        got_ev, words = ev.copy(), np.zeros(count, np.uint64)
        _event.event_direct(got_ev, lam, dlam, electrons, reset, jitter, keys, np.uint64(0), wf,
                            wu, words, split)
        if split < count:
            rest = np.zeros(count - split, np.uint64)
            _event.event_direct(got_ev, lam + split * dlam, dlam, electrons, reset, jitter, keys,
                                np.uint64(0), wf, wu, rest, count - split)
            words[split:] = rest
        assert [int(x) for x in words] == want
        np.testing.assert_array_equal(got_ev[:3].view(np.uint64), want_ev[:3].view(np.uint64))
    assert sum(bin(x).count("1") for x in want) > 64  # every kind of lane fired


def test_linear_crossing_is_the_first_readout_whose_sum_reaches_the_wait():
    """:func:`crossing_linear` against a brute-force search over exact sums, for
    charges rising, falling to zero, starting at zero, nearly constant, waits
    far beyond the run and waits exactly equal to a sum; any reciprocal gives
    the same readout (it only places the first guess: halved and doubled here,
    so the walk steps both ways); :func:`charge_sum` is each sum exactly."""
    rng = np.random.default_rng(12)
    cases = 0
    for _ in range(3000):
        left = int(rng.integers(1, 400))
        lam = _event.on_grid(rng.choice([0.0, rng.uniform(0.0, 1.0), rng.uniform(0.0, 2e3)]))
        end = _event.on_grid(rng.choice([0.0, lam * rng.uniform(0.0, 3.0), rng.uniform(0, 2e3)]))
        dlam = _event.on_grid((end - lam) / max(left - 1, 1))
        if lam + (left - 1) * dlam < 0.0 or dlam == 0.0:
            continue
        sums = np.cumsum([lam + k * dlam for k in range(left)])  # exact: all on the grid
        j = int(rng.integers(0, left))
        for w in (_event.on_grid(rng.uniform(1e-9, 1.3) * max(sums[-1], 1.0)), sums[j],
                  sums[j] - 2.0**-32, sums[j] + 2.0**-32):
            if not w > 0.0:
                continue
            hit = np.flatnonzero(sums >= w)
            want = float(hit[0] + 1) if hit.size else left + 1.0
            inv = 1.0 / lam if lam > 0.0 else np.inf
            for guess in (inv, 0.5 * inv, 2.0 * inv):
                got = _event.crossing_linear(w, lam, dlam, guess, float(left))
                assert got == want, (w, lam, dlam, guess)
            k = float(min(want, left))
            assert _event.charge_sum(k, lam, dlam) == sums[int(k) - 1]
            cases += 1
    assert cases > 6000


def test_linear_charge_is_on_the_exact_grid_and_chunk_free():
    """:func:`linear_charge` rounds ``λ`` at the segment's reference readout and
    its change per readout to :data:`CHARGE_GRID` (what makes the direct runs
    exact), by at most half a step, gives no change where the radiance holds,
    leaves large values alone and declines ramps too steep for the form."""
    rng = np.random.default_rng(9)
    level, slope = rng.random(64) * 3.0, rng.standard_normal(64) * 0.2
    slope[::3] = 0.0
    gain, offset, e = 1.0 + rng.random(64), np.full(64, 0.003), np.full(64, 977.7)
    t_a, inv = 41.3, 1.0 / 16.25
    lam, dlam = np.empty(64), np.empty(64)
    assert _event.linear_charge(t_a, inv, level, slope, gain, offset, e, lam, dlam)
    phi = (np.floor(t_a) + 0.5 - t_a) * inv
    assert np.all(lam * 2.0**32 == np.round(lam * 2.0**32))
    assert np.all(dlam * 2.0**32 == np.round(dlam * 2.0**32))
    assert np.max(np.abs(lam - (gain * (level + slope * phi) + offset) * e)) <= 2.0**-33
    assert np.max(np.abs(dlam - gain * slope * inv * e)) <= 2.0**-33
    assert np.all(dlam[::3] == 0.0)
    assert _event.on_grid(3.0e7 + 0.1) == 3.0e7 + 0.1 and _event.on_grid(2.0**62) == 2.0**62
    # readout n collects charge_at(lam, dlam, n − ⌊t_a⌋): within 2⁻³³·(1 + m) of the exact line
    m = 300.0
    exact = (gain * (level + slope * (phi + m * inv)) + offset) * e
    got = np.array([_event.charge_at(lam[k], dlam[k], m, 2.0**62) for k in range(64)])
    assert np.max(np.abs(got - exact)) <= 2.0**-33 * (1.0 + m) + 1e-9
    # a ramp steeper than DLAM_MAX (or one that overflows) does not take the form
    for steep in (1e300, np.inf):
        level2, slope2 = level.copy(), slope.copy()
        level2[5], slope2[5] = 3e38, -steep
        assert not _event.linear_charge(t_a, inv, level2, slope2, gain, offset, e, lam, dlam)


def test_negligible_drop_rule_keeps_below_two_to_the_minus_64():
    """Where :func:`drop_negligible` skips a modulo drop, the exact Poisson tail
    P(Poisson(L) >= h0) is below 2**-64, and the rule gives away little: its
    largest L/h0 is within 0.03 of the exact one (and within 1 % of the tail's
    log) for h0 from 230 to 10⁵; it never skips where h0 < 1 or L ≥ h0."""
    log_limit = -64 * np.log(2)
    fractions = np.linspace(0.0, 0.999, 1000)
    for h0 in (54.0, 60.0, 230.0, 500.0, 1000.0, 1001.0, 5000.0, 1e5):
        rule = np.array([_event.drop_negligible(f * h0, h0) for f in fractions])
        exact = stats.poisson.logsf(h0 - 1, fractions * h0)
        assert (exact[rule] < log_limit).all(), h0
        if h0 >= 230.0:
            assert rule[0] and fractions[exact < log_limit].max() - fractions[rule].max() < 0.03
            assert stats.poisson.logsf(h0 - 1, fractions[rule].max() * h0) < 0.99 * log_limit
    assert _event.drop_negligible(0.73 * 1000.0, 1000.0)
    assert not _event.drop_negligible(0.75 * 1000.0, 1000.0)
    assert not _event.drop_negligible(10.0, 20.0)
    assert not _event.drop_negligible(0.0, 0.0) and not _event.drop_negligible(0.5, 0.0)
    assert not _event.drop_negligible(1000.0, 1000.0) and not _event.drop_negligible(2e3, 1e3)


def test_drop_free_limit_implies_the_rule_and_the_tables_hold_it_and_c():
    """Every ``left`` ≤ :func:`drop_free_limit` passes :func:`drop_negligible`
    (0.70 threshold per readout at 1000 e⁻); the shape tables hold that limit
    and Marsaglia–Tsang's ``c`` bit for bit."""
    for h0 in (1.0, 2.0, 54.0, 89.0, 230.0, 1000.0, 1001.0, 5000.0, 1e5, 1e12, 2.0**52):
        limit = _event.drop_free_limit(h0)
        if limit < 0:
            continue
        for left in (0.0, 0.3 * limit, limit, np.nextafter(limit, -np.inf)):
            assert _event.drop_negligible(left, h0), (h0, left)
    assert 0.70 < _event.drop_free_limit(1000.0) / 1000.0 < 0.71
    assert _event.drop_free_limit(0.5) == -np.inf and _event.drop_free_limit(2.0**53) == -np.inf
    tables = _event.SHAPE_TABLES
    h = np.arange(tables.shape[1], dtype=np.float64)
    assert tables.shape[1] == _event.TABLE_SHAPES
    want_c = 1.0 / np.sqrt(9.0 * (h[9:] - 1.0 / 3.0))
    np.testing.assert_array_equal(tables[0, 9:], want_c)
    np.testing.assert_array_equal(tables[1, 1:], [_event.drop_free_limit(x) for x in h[1:]])


def test_squeeze_accepts_only_what_the_log_test_accepts():
    """The squeeze's bound, ``½x² + d(1 − v + ln v) ≥ −(4/3)c²x⁴`` where
    ``1 + c·x ≥ ½``, checked in 50-digit arithmetic over shapes and deviates;
    and it leaves about ``4c²`` of the candidates to the log test."""
    mp = pytest.importorskip("mpmath")
    mp.mp.dps = 50
    rng = np.random.default_rng(4)
    for m in (9.0, 10.0, 30.0, 1000.0, 1e6):
        d = mp.mpf(m) - mp.mpf(1) / 3
        c = 1 / mp.sqrt(9 * d)
        for x in rng.uniform(-8.0, 8.0, 300):
            t = 1 + c * mp.mpf(x)
            if t < 0.5:
                continue
            v = t**3
            exact = mp.mpf(x) ** 2 / 2 + d * (1 - v + mp.log(v))
            assert exact >= -mp.mpf(4) / 3 * c**2 * mp.mpf(x) ** 4, (m, x)
    x = rng.standard_normal(200_000)
    u = rng.random(200_000)
    c = 1.0 / np.sqrt(9.0 * (1000.0 - 1.0 / 3.0))
    left = ~_squeeze(u, x * x, c, 1.0 + c * x)
    assert abs(left.mean() - 4 * c * c) < 5 * np.sqrt(4 * c * c / x.size)


def _squeeze(u, x2, c, t):
    return np.array([_event.squeeze_accepts(a, b, c, s) for a, b, s in zip(u, x2, t, strict=True)])


def _lanes(rng, n, e, bright):
    """``n`` lanes (needs near ``e``, cycles, electrons, wait keys)
    and their waits at a firing, just below 0 (down to ``−bright·e``, the
    electrons of a readout)."""
    need = e * (0.5 + rng.random(n))
    cycle = rng.integers(0, 5000, n).astype(np.float64)
    electrons = e * (1.0 + 0.05 * rng.standard_normal(n))
    kw = rng.integers(0, 2**63, n, dtype=np.uint64) * np.uint64(2) + np.uint64(1)
    return need, cycle, electrons, kw, -rng.random(n) * bright * e


@pytest.mark.parametrize("reset", [0, 1, 2])
@pytest.mark.parametrize("e, bright, jitter", [(1000.0, 0.5, 0.006), (1000.0, 1.5, 0.0),
                                                (40.0, 0.9, 0.1), (5.0, 0.5, 0.2)])
def test_drawn_ahead_cycle_gives_the_scalar_cycle_where_it_applies(reset, e, bright, jitter):
    """:func:`lane_draw` (ahead of the firing), or :func:`prepare_lane` for the
    lanes it leaves, then :func:`apply_cached` at the firing give
    :func:`fire_cycle`'s bits for every lane where they apply; ``lane_draw``
    takes ≥ 97 % of the spikes at the default 1000 e⁻ per threshold, and with
    ``prepare_lane`` the cache holds every subtract and zero firing and the
    modulo ones below the drop-free limit."""
    rng = np.random.default_rng(reset * 31 + int(e))
    n = 4096
    need, cycle, electrons, kw, waits = _lanes(rng, n, e, bright)
    fast = applied = 0
    for i in range(n):
        state = (need[i], cycle[i], electrons[i])
        want = _event.fire_cycle(waits[i], *state, reset, jitter, kw[i], np.uint64(5),
                                 np.uint64(6), np.uint64(i))
        g, d, wmin, ok = _event.lane_draw(need[i], np.uint64(cycle[i]), electrons[i], kw[i],
                                          reset, jitter > 0.0, jitter)
        if ok:
            fast += 1
        else:
            g, d, wmin = _event.prepare_lane(*state, reset, jitter, kw[i])
        new_wait, valid = _event.apply_cached(waits[i], g, wmin, state[2], reset)
        if valid:
            applied += 1
            got = (new_wait, d, state[1] + 1.0)
            assert np.array(got).view(np.uint64).tolist() == (
                np.array(want).view(np.uint64).tolist()), (i, got, want)
        else:
            assert reset == 0  # only modulo firings beyond the limit go to fire_cycle
    if e >= 1000.0 and bright <= 0.5:
        assert fast > 0.97 * n and applied == n
    if e <= 5.0:
        assert fast < 0.01 * n  # shapes ≤ 8 (nearly all here): the scalar product of uniforms


@pytest.mark.parametrize("reset", [0, 1, 2])
@pytest.mark.parametrize("n_stale", [0, 3, 5, 7, 8, 9, 30, 63, 64])
@pytest.mark.parametrize("jitter", [0.006, 0.0])
@pytest.mark.parametrize("packed", [False, True])
@pytest.mark.parametrize("beyond", [False, True])
def test_refill_draws_every_stale_lane_as_the_scalar_draw_and_keeps_the_rest(
        reset, n_stale, jitter, packed, beyond):
    """:func:`event_refill` gives every stale lane :func:`prepare_lane`'s draw
    bit for bit, leaves the fresh lanes' cache alone, and makes every lane
    fresh: with and without jitter, small shapes, shapes beyond the tables,
    needs ≤ 0, cycles up to 2⁵² − 1 (``beyond``: up to 2⁵³ − 2, which the
    packed refill leaves to the scalar draw); one by one below
    ``PACKED_REFILL_MIN`` stale lanes, packed from there (the counts around it
    and around whole groups), and packed at every count when called directly
    (``packed``)."""
    rng = np.random.default_rng(reset * 7 + n_stale + int(jitter * 1000) + 100 * beyond)
    ev = np.zeros((4, 64))
    ev[_event.NEED] = 1000.0 * (0.2 + rng.random(64))
    ev[_event.NEED, :4] = [3.5, -2.0, float(_event.TABLE_SHAPES) + 3.5, 0.0]
    ev[_event.CYCLE] = rng.integers(0, 9000, 64).astype(np.float64)
    ev[_event.CYCLE, 4:7] = ([2.0**52 - 1.0, 2.0**52, 2.0**53 - 2.0] if beyond  # (cycle + 1 exact)
                             else [2.0**52 - 1.0, 2.0**52 - 2.0, 2.0**51])
    electrons = 1000.0 * (1.0 + 0.05 * rng.standard_normal(64))
    wf = np.full((_event.EV_WORK_F, 64), 7.5)
    wu = np.zeros((_event.EV_WORK_U, 64), np.uint64)
    wu[_event.LKW] = rng.integers(0, 2**63, 64, dtype=np.uint64)
    stale_lanes = rng.choice(64, n_stale, replace=False) if n_stale < 7 else (
        np.r_[np.arange(7), rng.choice(np.arange(7, 64), n_stale - 7, replace=False)])
    stale = sum(1 << int(k) for k in stale_lanes)
    wu[_event.MASKS, _event.FRESH] = ~np.uint64(stale)
    if packed and n_stale:
        _event._packed_refill(reset, np.uint64(stale), electrons, ev, jitter, wf, wu)
    else:
        _event.event_refill(electrons, ev, reset, jitter, wf, wu)
        assert int(wu[_event.MASKS, _event.FRESH]) == 2**64 - 1
    assert _event.PACKED_REFILL_MIN == 8  # (the counts above straddle it)
    for lane in range(64):
        cached = wf[[_event.GNEXT, _event.DNEXT, _event.WMIN], lane]
        if stale >> lane & 1:
            want = _event.prepare_lane(ev[_event.NEED, lane], ev[_event.CYCLE, lane],
                                       electrons[lane], reset, jitter, wu[_event.LKW, lane])
            assert cached.view(np.uint64).tolist() == np.array(want).view(np.uint64).tolist()
        else:
            assert cached.tolist() == [7.5, 7.5, 7.5]


@pytest.mark.parametrize("seed", range(6))
def test_first_waits_equal_the_scalar_first_wait_bit_for_bit(seed):
    """:func:`first_waits` (vector candidates, scalar fallback) gives every lane
    ``cycle_wait(need, key, 0)`` bit for bit: ordinary shapes (most taken on
    the vectors), needs ≤ 0, small shapes, shapes beyond the table, and
    enough lanes that some normals fall in the tails."""
    rng = np.random.default_rng(seed)
    ev = np.zeros((4, 64))
    need = 1000.0 * (0.01 + rng.random(64))
    need[:4] = [0.0, -3.5, 2.2, 8.0]  # no wait, a backlog, small shapes
    need[4:6] = [float(_event.TABLE_SHAPES) + 10.5, 5e5]  # beyond the table
    ev[_event.NEED] = need
    wu = np.zeros((_event.EV_WORK_U, 64), np.uint64)
    wu[_event.LKW] = rng.integers(0, 2**63, 64, dtype=np.uint64)
    _event.first_waits(ev, wu)
    want = [_event.cycle_wait(n, k, 0) for n, k in zip(need, wu[_event.LKW], strict=True)]
    assert ev[_event.WAIT].view(np.uint64).tolist() == np.array(want).view(np.uint64).tolist()
    assert (np.asarray(want)[4:] > 0).all() and want[0] == 0.0 and want[1] == 0.0


def test_reset_codes_and_backlog_limit_agree_with_the_kernel():
    assert (_event.MODULO, _event.SUBTRACT, _event.ZERO) == (
        _kernels.RESET_MODULO, _kernels.RESET_SUBTRACT, _kernels.RESET_ZERO)
    assert _event.BACKLOG_MAX == _kernels.WHOLE_MAX


@pytest.mark.parametrize("m", [1.0, 2.0, 7.0, 60.0, 1000.0])
def test_gamma_sampler_follows_the_gamma_law_and_equals_the_reference(m):
    bits = mix64_np(np.arange(20_000, dtype=np.uint64) * np.uint64(1_000_003) + np.uint64(m))
    draws = np.array([_event.gamma_integer(m, b) for b in bits])
    assert stats.kstest(draws, "gamma", args=(m,)).pvalue > 1e-4
    assert abs(draws.mean() - m) < 4 * np.sqrt(m / draws.size)
    assert abs(draws.var() / m - 1) < 4 * np.sqrt((2 + 6 / m) / draws.size)  # kurtosis 6/m
    ref = [gamma_ref(m, int(b)) for b in bits[:500]]
    np.testing.assert_array_equal(draws[:500], ref)


@pytest.mark.parametrize("lam", [0.0, 0.3, 4.5, 9.99, 10.0, 55.5, 3000.0])
def test_reference_poisson_equals_the_kernel_sampler(lam):
    bits = mix64_np(np.arange(2000, dtype=np.uint64) * np.uint64(7) + np.uint64(1))
    got = [poisson(lam, b) for b in bits]
    np.testing.assert_array_equal(got, [poisson_ref(lam, int(b)) for b in bits])


def _flat_noise(e, jitter, loss=0.0):
    return ss.noise.PhysicalNoise(electrons_per_threshold=e, dark_current_rel=0.0,
                                  threshold_mismatch=0.0, prnu=0.0, hot_pixel_fraction=0.0,
                                  temporal_threshold_noise=jitter, reset_charge_loss=loss)


def _intervals(spikes, k):
    """The k-th inter-spike interval of every pixel (one per pixel: independent)."""
    out = []
    for x in range(spikes.shape[1]):
        t = np.flatnonzero(spikes[:, x])
        if t.size > k + 1:
            out.append(t[k + 1] - t[k])
    return np.array(out)


@pytest.mark.parametrize("reset", RESETS)
@pytest.mark.parametrize("e, jitter, loss", [(200.7, 0.03, 0.0), (6.3, 0.1, 0.25),
                                              (1000.0, 0.03, 0.0)])  # E=1000: negligible drops
def test_event_and_per_readout_samplers_have_the_same_law(reset, e, jitter, loss):
    """Counts over 1500 readouts and the 3rd and 10th intervals of 1024 pixels
    per level, two-sample KS tests and means (old sampler: per-readout Poisson)."""
    levels = [0.03, 0.3, 1.2]  # q = 0.018 (a long interval), 0.18 and 0.72
    w, n = 1024, 1500
    sensor = ss.Sensor(height=len(levels), width=w, cfa=None, reset=reset,
                       noise=_flat_noise(e, jitter, loss))
    scene = ss.scenes.Static(flat_rows(levels, w))
    new = ss.simulate(scene, sensor, n, seed=21).unpack()
    old = ss.simulate(scene, sensor, n, seed=22, shot_sampler="readout").unpack()
    for row in range(len(levels)):
        cn, co = new[:, row].sum(axis=0), old[:, row].sum(axis=0)
        sd = np.sqrt((cn.var() + co.var()) / w) + 1e-9
        assert abs(cn.mean() - co.mean()) < 4.5 * sd, (row, cn.mean(), co.mean())
        assert stats.ks_2samp(cn, co).pvalue > 1e-4, row
        for k in (3, 10):
            i_new, i_old = _intervals(new[:, row], k), _intervals(old[:, row], k)
            assert stats.ks_2samp(i_new, i_old).pvalue > 1e-4, (row, k)


def test_event_counts_and_intervals_follow_theory():
    """Modulo, no fixed pattern: count mean N·q and variance N·q·κ² + E[frac]
    (κ² = 1/E + σ_t²); interval mean 1/q and variance κ²/q² + E[frac(τ)(1 − frac(τ))]."""
    e, jitter = 150.5, 0.02
    noise = _flat_noise(e, jitter)
    k2 = theory.cycle_cv2(noise)
    assert k2 == pytest.approx(1 / e + jitter**2)
    levels = [0.05, 0.4]
    w, n = 2048, 3000
    sensor = ss.Sensor(height=len(levels), width=w, cfa=None, noise=noise)
    spikes = ss.simulate(ss.scenes.Static(flat_rows(levels, w)), sensor, n, seed=3).unpack()
    for row, level in enumerate(levels):
        q = 0.6 * float(np.float32(level))
        c = spikes[:, row].sum(axis=0)
        var_t = theory.count_variance(q, n, q * k2)
        assert abs(c.mean() - n * q) < 4 * np.sqrt(var_t / w)
        assert abs(c.var(ddof=1) / var_t - 1) < 4 * np.sqrt(2 / (w - 1))
        isi = _intervals(spikes[:, row], 4).astype(np.float64)
        v = theory.isi_var_theory(q, k2)
        assert abs(isi.mean() - theory.isi_mean_theory(q)) < 4 * np.sqrt(v / isi.size)
        assert abs(isi.var(ddof=1) / v - 1) < 5 * np.sqrt(2 / (isi.size - 1))


@pytest.mark.parametrize("reset", RESETS)
def test_event_sampler_is_chunk_invariant(reset):
    noise = ss.noise.PhysicalNoise(electrons_per_threshold=20.5, reset_charge_loss=0.1,
                                   temporal_threshold_noise=0.05, hot_pixel_fraction=0.01)
    sensor = ss.Sensor(height=9, width=130, clock_hz=1000.0, reset=reset, noise=noise)
    scene = _scene(np.random.default_rng(2), 9, 130, 2.0, 1000.0, 80)
    whole = ss.simulate(scene, sensor, 80, seed=4, chunk_readouts=80).packed
    for chunk in (1, 7):
        np.testing.assert_array_equal(
            ss.simulate(scene, sensor, 80, seed=4, chunk_readouts=chunk).packed, whole)


def test_shot_sampler_is_validated_and_charge_noise_uses_the_per_readout_path():
    sensor = ss.Sensor(height=2, width=8, cfa=None,
                       noise=ss.noise.PhysicalNoise(charge_noise_electrons=20.0))
    scene = ss.scenes.Static(np.full((2, 8), 0.5, np.float32))
    with pytest.raises(SpikeSimValueError, match="shot_sampler"):
        ss.simulate(scene, sensor, 4, shot_sampler="fast")
    assert not sensor.noise.event_driven and ss.noise.PhysicalNoise().event_driven
    a = ss.simulate(scene, sensor, 40, seed=1).packed
    np.testing.assert_array_equal(a, ss.simulate(scene, sensor, 40, seed=1,
                                                 shot_sampler="readout").packed)
