"""numba kernel of forward flow splatting (used by :mod:`spikesim.motion`)."""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["splat_flow"]


@njit(cache=True, nogil=True)
def splat_flow(flow, select, scale, sign, wsum, vsum):  # pragma: no cover - compiled
    """Bilinear forward splatting of motion vectors (used by ``spikesim.motion``).

    Pixel ``(y, x)`` with ``select`` true moves to ``(x, y) + scale · flow`` and
    deposits the vector ``sign · flow`` there with bilinear weights.
    """
    h, w = select.shape
    for y in range(h):
        for x in range(w):
            if not select[y, x]:
                continue
            fx, fy = flow[y, x, 0], flow[y, x, 1]
            px, py = x + scale * fx, y + scale * fy
            x0, y0 = int(np.floor(px)), int(np.floor(py))
            ax, ay = px - x0, py - y0
            for dy in range(2):
                yi = y0 + dy
                if yi < 0 or yi >= h:
                    continue
                wy = ay if dy else 1.0 - ay
                for dx in range(2):
                    xi = x0 + dx
                    if xi < 0 or xi >= w:
                        continue
                    wt = wy * (ax if dx else 1.0 - ax)
                    if wt <= 0.0:
                        continue
                    wsum[yi, xi] += wt
                    vsum[yi, xi, 0] += wt * sign * fx
                    vsum[yi, xi, 1] += wt * sign * fy
