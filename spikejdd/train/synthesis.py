"""A fixed procedural training set on disk: :func:`synthesize` (``spikejdd train --synthesize N``).

Each sequence is one scene of :func:`spikejdd.train.scenes.draw_scene` (the
distribution the in-loader simulation uses: pictures, dead leaves and
textures, camera and object motion, static to 4000 px/s) simulated with
``spikesim.simulate`` and written with ``spikesim.io.write_h5``: RGGB, 20 kHz,
full_scale_rate 0.6, modulo reset; GT every ``gt_every`` readouts wherever a ``window``-readout
window fits.  Even sequences get Gaussian noise σ ~ U(0, 15) DN, odd ones
Gaussian–Poisson noise with the evaluation's random-GPN ranges
(``spikejdd.evaluate.GPN_RANGE``).  For training, prefer ``--online``: a file
set repeats the same noise and motion every epoch.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from tqdm import tqdm

from spikesim.errors import bad_value

__all__ = ["synthesize"]


def synthesize(out_dir, n_sequences: int = 96, sizes=((64, 96), (96, 128)),
               n_readouts: int = 99, gt_every: int = 6, window: int = 39, seed: int = 1234,
               progress: bool = True) -> dict:
    """Write ``n_sequences`` procedural HDF5 sequences to ``out_dir`` (see the module doc).

    Returns the description (also written to ``synth.json``).
    """
    import spikesim as ss
    from spikejdd.evaluate import GPN_RANGE
    from spikejdd.train.pictures import TEST_PICTURES, TRAIN_PICTURES
    from spikejdd.train.scenes import CAMERA_MOTIONS, CONTENT_MIX, SPEED_BINS, draw_scene

    if isinstance(n_sequences, bool) or not isinstance(n_sequences, int) or n_sequences < 1:
        raise bad_value("n_sequences", n_sequences, "an integer >= 1")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    half = window // 2
    gts = list(range(half, n_readouts - (window - half) + 1, gt_every))
    if not gts:
        raise bad_value("n_readouts", n_readouts, f"at least window = {window}")
    seqs = []
    for i in tqdm(range(n_sequences), desc="synthesize", disable=not progress):
        size = tuple(int(v) for v in sizes[int(rng.integers(len(sizes)))])
        scene, desc = draw_scene(rng, size)
        if i % 2 == 0:
            sg, sp = float(rng.uniform(0, 15)), 0.0
        else:
            sg = float(rng.uniform(*GPN_RANGE["sigma_g"]))
            sp = float(rng.uniform(*GPN_RANGE["sigma_p"]))
        noise = ss.noise.PaperNoise(sigma_g=sg, sigma_p=sp) if (sg or sp) else None
        sensor = ss.Sensor(height=size[0], width=size[1], cfa="RGGB", clock_hz=20_000.0,
                           full_scale_rate=0.6, noise=noise)
        stream = ss.simulate(scene, sensor, n_readouts=n_readouts, seed=seed + i,
                             gt_readouts=gts)
        ss.io.write_h5(out / f"seq{i:04d}.h5", stream)
        seqs.append(dict(desc, file=f"seq{i:04d}.h5", size=list(size), sigma_g=sg, sigma_p=sp))
    info = {"generator": "spikejdd.train.synthesize", "seed": seed, "n_sequences": n_sequences,
            "n_readouts": n_readouts, "gt_readouts": gts, "window": window,
            "sensor": "RGGB, 20 kHz, full_scale_rate 0.6, modulo reset, paper noise",
            "noise": f"GN sigma~U(0,15) (even sequences) / GPN {GPN_RANGE} (odd)",
            "pictures": list(TRAIN_PICTURES), "excluded_test_pictures": list(TEST_PICTURES),
            "content_mix": [list(c) for c in CONTENT_MIX],
            "motions": list(CAMERA_MOTIONS) + ["sprites", "fan", "disk"],
            "speed_bins": [list(b) for b in SPEED_BINS], "sequences": seqs}
    (out / "synth.json").write_text(json.dumps(info, indent=1))
    return info
