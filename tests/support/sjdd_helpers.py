"""Shared helpers for the SJDD-Net tests: a tiny configuration and inputs."""

from __future__ import annotations

import numpy as np
import torch

from spikejdd.models import SJDDConfig
from spikesim.cfa import mask_planes

#: A very small model (9 readouts) so that tests run in seconds on 2 CPU cores.
TINY = SJDDConfig(n_readouts=9, block_size=5, n_blocks=3, csr_encoder_feats=2,
                  csr_align_feats=(4, 4), csr_align_depth=0, csr_decoder_feats=4,
                  csr_decoder_depth=0, offset_groups=2, sne_feats=4, sne_res_blocks=1,
                  sne_fusion_depth=0, ccp_widths=(4, 8), ccp_depth=1, stages=3)


def make_inputs(n_readouts: int, h: int, w: int, batch: int = 1, seed: int = 0,
                cfa: str = "RGGB"):
    rng = np.random.default_rng(seed)
    spikes = (rng.random((batch, n_readouts, h, w)) < 0.35).astype(np.float32)
    mask = np.repeat(mask_planes(cfa, h, w)[None], batch, axis=0)
    return torch.from_numpy(spikes), torch.from_numpy(mask)
