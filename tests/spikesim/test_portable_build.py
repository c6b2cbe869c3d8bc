"""The kernels build for CPUs without AVX-512 and give the same bits there.

The vector helpers (``spikesim._simd``) steer LLVM's AVX-512 code with empty
inline-asm copies that name 512-bit registers; compiled for a CPU without
them, LLVM stopped the process ("couldn't allocate output register for
constraint 'v'").  This test compiles every kernel for a Haswell (AVX2, the
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


def _digest(env):
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    done = subprocess.run([sys.executable, "-c", DIGEST], capture_output=True, text=True,
                          cwd=root, env=env, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout.strip()


@pytest.mark.slow
def test_kernels_build_without_avx512_and_give_the_same_bits(tmp_path):
    here = _digest(dict(os.environ))
    there = _digest(dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path), **HASWELL))
    assert len(here) == 64 and there == here
