"""The kernels build for CPUs without AVX-512 and give the same bits there.

The vector helpers (``spikesim._simd``) pick some of their IR by the target's
instruction set.  This test compiles every kernel for a Haswell (AVX2, the
common laptop and pre-Zen-4 AMD case) in a fresh numba cache and compares the
spikes of each noise model and reset mode, static and moving, with this
process's build.
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

DIGEST = """
import hashlib
import numpy as np
import spikesim as ss
img = np.random.default_rng(0).uniform(0, 1, (20, 130, 3)).astype(np.float32)
moving = ss.scenes.Keyframes([0.0, 0.002], [img, np.roll(img, 3, axis=1)])
h = hashlib.sha256()
for scene in (ss.scenes.Static(img), moving):
    for noise in (None, ss.noise.PaperNoise(sigma_g=10), ss.noise.PhysicalNoise()):
        for reset in ("modulo", "subtract", "zero"):
            sensor = ss.Sensor(height=20, width=130, cfa="RGGB", noise=noise, reset=reset)
            h.update(ss.simulate(scene, sensor, 40, gt_readouts=[]).packed.tobytes())
print(h.hexdigest())
"""

HASWELL = {
    "NUMBA_CPU_NAME": "haswell",
    "NUMBA_CPU_FEATURES": "+64bit,+cmov,+cx8,+fxsr,+mmx,+sse,+sse2,+sse3,+ssse3,+sse4.1,"
                          "+sse4.2,+popcnt,+avx,+avx2,+fma,+bmi,+bmi2,+lzcnt,+f16c,+movbe",
}


def _run(code, env):
    """The standard output of ``code`` run in a fresh interpreter from the
    repository's root with environment ``env`` (it must succeed)."""
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=root, env=env, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout


def _for_haswell(tmp_path):
    """This process's environment with numba compiling for a Haswell CPU into a
    fresh cache."""
    return dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path), **HASWELL)


def _digest(env):
    return _run(DIGEST, env).strip()


@pytest.mark.slow
def test_kernels_build_without_avx512_and_give_the_same_bits(tmp_path):
    here = _digest(dict(os.environ))
    there = _digest(_for_haswell(tmp_path))
    assert len(here) == 64 and there == here


LOOP_ASM = """
import re
import numpy as np
from numba import njit
from spikesim._simd import carry_run64, carry_run64_zero, countdown_run32, linear_carry_run64

@njit(cache=False)
def runs(acc, inc, x, out, count):
    CALLS

x = np.full(64, 0.25)
runs(np.zeros(64, np.uint64), np.ones(64, np.uint64), x, np.zeros(64, np.uint8), 1)
lines = "".join(runs.inspect_asm().values()).splitlines()
seen = set()
for i, line in enumerate(lines):  # each readout loop: from its block's label to its back edge
    if "vpmovmskb" in line:
        start = max(j for j in range(i) if re.match(r"\\.LBB\\d+_\\d+:", lines[j]))
        if start in seen:
            continue
        seen.add(start)
        label = lines[start].rstrip(":")
        back_edge = re.compile(r"\\bj\\w+\\s+" + re.escape(label) + "$")
        end = next(j for j in range(i, len(lines)) if back_edge.search(lines[j]))
        print(" ".join(line.split()[0] + ("@stack" if "(%rsp)" in line else "")
                       for line in lines[start + 1:end] if line.startswith("\\t")))
"""
CARRY_CALLS = """carry_run64(acc, inc, out, 0, 8, 8, count)
    carry_run64_zero(acc, inc, out, 0, 8, 8, count)
    linear_carry_run64(acc, x, x, x, x, 0, 0.0, 1.0, out, 0, 8, 8, count)"""


def _haswell_loops(tmp_path, calls):
    """The instructions of each readout loop (``@stack``: with a stack operand)
    of ``calls`` (the body of ``runs(acc, inc, x, out, count)``) built for a
    Haswell CPU in a fresh cache."""
    out = _run(LOOP_ASM.replace("CALLS", calls), _for_haswell(tmp_path))
    return [loop.split() for loop in out.split("\n")[:-1]]


@pytest.mark.slow
def test_avx2_readout_loops_pack_their_words_without_cross_lane_permutes(tmp_path):
    """Built for an AVX2 CPU, the noise-free readout loops hold their lanes in
    the order the packs leave them (``spikesim._simd._RunLanes``): each
    readout's word takes blends, packs and two ``vpmovmskb`` (zero reset's
    static loop: one for each 32-lane half), no ``vpermq`` (LLVM's own
    lowering of the 64-bit mask used seven a readout, and the loop ran twice
    as long), the carry is one signed compare, and the linear loop's charges
    become fixed point with shifts, not compares."""
    loops = _haswell_loops(tmp_path, CARRY_CALLS)
    masks = sorted(ops.count("vpmovmskb") for ops in loops)
    assert masks[:2] == [1, 1] and masks[2:] and set(masks[2:]) == {2}  # 2 halves, 2 whole
    for ops in loops:
        assert "vpblendd" in ops and "vpcmpgtq" in ops
        assert "vpermq" not in ops and "vpxor" not in ops


@pytest.mark.slow
def test_avx2_countdown_loop_takes_spikes_and_resets_from_sign_bits(tmp_path):
    """Built for an AVX2 CPU, zero reset's countdown loop
    (``spikesim._simd.countdown_run32``) keeps its 64 int32 counters in eight
    registers (no store to the stack), decrements them, packs their sign bits
    into the word (four ``vpackssdw``, two ``vpacksswb``, two ``vpmovmskb``)
    and resets the fired lanes with ``vblendvps`` on the same sign bits: no
    compare, no cross-lane permute."""
    (ops,) = _haswell_loops(tmp_path, "countdown_run32(acc, inc, out, 0, 8, 8, count)")
    counts = {op: ops.count(op) for op in ("vpaddd", "vpackssdw", "vpacksswb", "vpmovmskb")}
    assert counts == {"vpaddd": 8, "vpackssdw": 4, "vpacksswb": 2, "vpmovmskb": 2}
    assert sum(op.startswith("vblendvps") for op in ops) == 8
    assert not any(op.startswith(("vpcmp", "vpermq", "vpxor")) for op in ops)
    assert not any(op.startswith("vmov") and op.endswith("@stack") for op in ops)


REFILL_ASM = """
import re
import numpy as np
from numba import njit
from spikesim import _event
from spikesim._simd import expands_natively

@njit(cache=False)
def native():
    return expands_natively()

ev = np.zeros((4, 64))
ev[_event.NEED] = 900.0
wf = np.zeros((_event.EV_WORK_F, 64))
wu = np.zeros((_event.EV_WORK_U, 64), np.uint64)
_event._PACKED_S(np.uint64(0x5555_5555_0000_FFFF), np.full(64, 1000.0), ev, 0.0, wf, wu)
asm = "".join(_event._PACKED_S.inspect_asm().values())
print(native(), len(re.findall(r"\\n\\s+j(?!mp\\b)[a-z]+\\s", asm)))
"""


def test_avx2_refill_puts_its_draws_back_without_a_branch_per_lane(tmp_path):
    """Built for an AVX2 CPU, the packed refill (``spikesim._event``) puts its
    draws back lane by lane in its pass over the stale lanes, not with
    expanding loads (``spikesim._simd.expand_lanes64``), which LLVM splits
    there into a conditional branch per lane and row: 542 conditional jumps
    in the refill's code with them, 194 without (on an AMD EPYC host, three
    such put-backs took 635 ns at 28 stale lanes, the loop 54)."""
    native, branches = _run(REFILL_ASM, _for_haswell(tmp_path)).split()
    assert native == "False" and int(branches) < 300
