"""Optical flow, occlusion, and flow-based frame interpolation with adaptive sampling.

Pipeline for one pair of consecutive video frames ``I0`` (time 0) and ``I1``
(time 1), all images in linear light:

1. **Static test.**  If the sRGB-encoded luma of the two frames differs
   nowhere by more than ``static_tol`` (8-bit code values), the pair is static:
   no flow is computed and no intermediate frame is made (linear blending then
   errs by less than ``static_tol`` anywhere).  Method ``"none"`` treats every
   pair so (the plain-blending baseline).
2. **Flow.**  Dense forward flow ``F01`` and backward flow ``F10`` on the
   8-bit sRGB-encoded luma, with an OpenCV method (:data:`FLOW_METHODS`;
   default DIS, medium preset — Kroeger et al., "Fast Optical Flow using Dense
   Inverse Search", ECCV 2016).
3. **Occlusion.**  Forward–backward consistency (Sundaram, Brox & Keutzer,
   "Dense point trajectories by GPU-accelerated large displacement optical
   flow", ECCV 2010, eq. 5): a pixel of ``I0`` is visible in ``I1`` when
   ``|F01 + F10(x + F01)|² <= 0.01 (|F01|² + |F10(x + F01)|²) + 0.5``;
   likewise for ``I1``.
4. **Adaptive count.**  ``D`` = the largest flow magnitude over consistent
   pixels (both directions); the pair gets ``ceil(D / max_px) − 1``
   intermediate key frames (capped), equally spaced in time, so consecutive
   key frames are at most ``max_px`` pixels apart — the rule of v2e (Hu,
   Liu & Delbruck, CVPRW 2021) and ESIM (Rebecq et al., CoRL 2018).
5. **Interpolation at τ ∈ (0, 1)** (after Baker et al., "A Database and
   Evaluation Methodology for Optical Flow", IJCV 2011, §3.3): the motion
   vectors of visible pixels are forward-splatted (bilinear weights) to their
   positions at time τ — ``x0 + τ F01`` from ``I0`` and ``x1 + (1−τ) F10``
   from ``I1`` (carrying ``−F10``); holes take the vector of the nearest
   filled pixel.  With that field ``u`` each output pixel samples
   ``I0(x − τu)`` and ``I1(x + (1−τ)u)`` (bicubic) and blends them with
   weights ``(1−τ)·v0`` and ``τ·v1``, where ``v0``, ``v1`` are the
   visibilities (consistency mask, and inside the frame) at the sampled
   points.  ``occlusion=False`` drops the masks (all pixels splat, weights
   ``1−τ`` and ``τ``), for comparison.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import cv2
import numpy as np

from spikesim._flow_splat import splat_flow
from spikesim.errors import SpikeSimValueError, bad_value

__all__ = [
    "FLOW_METHODS",
    "DEFAULT_FLOW",
    "PairMotion",
    "flow_image",
    "compute_flow",
    "consistency",
    "analyse_pair",
    "n_intermediate",
    "interpolate",
    "blend",
]

#: Flow method → description.
FLOW_METHODS: dict[str, str] = {
    "none": "no flow: key frames only at video frames (plain linear blending); baseline",
    "dis": "DIS, medium preset (Kroeger et al. ECCV 2016); fast, the default",
    "dis-fast": "DIS, fast preset; fastest, coarser",
    "farneback": "Farneback polynomial expansion (SCIA 2003)",
    "deepflow": "DeepFlow (Weinzaepfel et al. ICCV 2013), opencv-contrib; slow",
    "rlof": "dense RLOF (Senst et al. 2016), opencv-contrib; run twice to check (see _rlof)",
    "dualtvl1": "Dual TV-L1 (Zach et al. 2007), opencv-contrib; slowest",
}
DEFAULT_FLOW = "dis"
#: Smallest frame side accepted by the RLOF wrapper (smaller frames crashed OpenCV).
RLOF_MIN_SIDE = 128

_LUMA = np.array([0.2126, 0.7152, 0.0722], np.float32)


def check_method(method: str) -> str:
    if method not in FLOW_METHODS:
        raise bad_value("flow", method, f"one of {sorted(FLOW_METHODS)}")
    return method


def flow_image(frame: np.ndarray) -> np.ndarray:
    """(H, W) uint8 sRGB-encoded Rec. 709 luma of a linear (H, W, 3) frame (flow input)."""
    from spikesim.srgb import linear_to_srgb8

    return linear_to_srgb8(frame @ _LUMA)


def compute_flow(img0: np.ndarray, img1: np.ndarray, method: str = DEFAULT_FLOW) -> np.ndarray:
    """Dense flow (H, W, 2) float32 (dx, dy) from ``img0`` to ``img1`` (uint8 grey images)."""
    if check_method(method) == "none":
        raise bad_value("flow", method, "a flow method other than 'none' for compute_flow")
    if method in ("dis", "dis-fast"):
        preset = (cv2.DISOPTICAL_FLOW_PRESET_MEDIUM if method == "dis"
                  else cv2.DISOPTICAL_FLOW_PRESET_FAST)
        flow = cv2.DISOpticalFlow_create(preset).calc(img0, img1, None)
    elif method == "farneback":
        flow = cv2.calcOpticalFlowFarneback(img0, img1, None, 0.5, 5, 15, 5, 7, 1.5, 0)
    elif method == "deepflow":
        flow = cv2.optflow.createOptFlow_DeepFlow().calc(img0, img1, None)
    elif method == "rlof":
        flow = _rlof(img0, img1)
    else:  # dualtvl1
        flow = cv2.optflow.DualTVL1OpticalFlow_create().calc(img0, img1, None)
    return np.ascontiguousarray(flow, dtype=np.float32)


def _rlof(img0: np.ndarray, img1: np.ndarray, tries: int = 6) -> np.ndarray:
    """Dense RLOF, guarded: accept a result only when two consecutive runs agree.

    In opencv-contrib 5.0 dense RLOF now and then returns NaN or wild vectors
    (it reads memory it did not initialise; cf. opencv_contrib issues #2094 and
    #2663 on RLOF's robustness); a correct run is deterministic, so two equal
    consecutive runs identify it.  On frames smaller than
    :data:`RLOF_MIN_SIDE` it also crashed the process in our tests, so those
    are refused.
    """
    if min(img0.shape[:2]) < RLOF_MIN_SIDE:
        raise bad_value("flow", "rlof", f"frames at least {RLOF_MIN_SIDE} px on each side for "
                        f"RLOF (got {img0.shape[0]}x{img0.shape[1]}); use 'dis'")
    a = cv2.cvtColor(img0, cv2.COLOR_GRAY2BGR)
    b = cv2.cvtColor(img1, cv2.COLOR_GRAY2BGR)
    prev = None
    for _ in range(tries):
        init = np.zeros(img0.shape[:2] + (2,), np.float32)
        flow = cv2.optflow.DenseRLOFOpticalFlow_create().calc(a, b, init)
        if prev is not None and np.isfinite(flow).all() and np.array_equal(flow, prev):
            return flow
        prev = flow
    raise SpikeSimValueError(
        f"flow='rlof' gave no stable result in {tries} runs (OpenCV dense RLOF); "
        "use another method, e.g. 'dis'"
    )


def _grid(h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float32)
    return xs, ys


def _sample(img: np.ndarray, mx: np.ndarray, my: np.ndarray, cubic: bool = False) -> np.ndarray:
    interp = cv2.INTER_CUBIC if cubic else cv2.INTER_LINEAR
    return cv2.remap(img, mx, my, interp, borderMode=cv2.BORDER_REPLICATE)


def sq_norm(v: np.ndarray) -> np.ndarray:
    """Squared length of (..., 2) vectors: the same bits as ``(v**2).sum(-1)``, several
    times faster (no reduction over a length-2 axis)."""
    x, y = v[..., 0], v[..., 1]
    return x * x + y * y


def consistency(fwd: np.ndarray, bwd: np.ndarray) -> np.ndarray:
    """Boolean (H, W): pixels whose forward flow is confirmed by the backward flow."""
    h, w = fwd.shape[:2]
    xs, ys = _grid(h, w)
    mx, my = xs + fwd[..., 0], ys + fwd[..., 1]
    back = _sample(bwd, mx, my)
    err = sq_norm(fwd + back)
    ok = err <= 0.01 * (sq_norm(fwd) + sq_norm(back)) + 0.5
    inside = (mx >= 0) & (mx <= w - 1) & (my >= 0) & (my <= h - 1)
    return ok & inside


@dataclass
class PairMotion:
    """Motion between two frames: flows (None when static), visibility, largest displacement."""

    static: bool
    max_disp: float
    fwd: np.ndarray | None = None
    bwd: np.ndarray | None = None
    valid0: np.ndarray | None = None
    valid1: np.ndarray | None = None
    seconds: float = 0.0


def analyse_pair(
    f0: np.ndarray, f1: np.ndarray, method: str = DEFAULT_FLOW, static_tol: float = 1.0
) -> PairMotion:
    """Static test, then forward/backward flow and occlusion masks of one frame pair."""
    check_method(method)
    t0 = time.perf_counter()
    g0, g1 = flow_image(f0), flow_image(f1)
    if method == "none" or (
        int(np.abs(g0.astype(np.int16) - g1.astype(np.int16)).max()) <= static_tol
    ):
        return PairMotion(static=True, max_disp=0.0, seconds=time.perf_counter() - t0)
    fwd = compute_flow(g0, g1, method)
    bwd = compute_flow(g1, g0, method)
    v0, v1 = consistency(fwd, bwd), consistency(bwd, fwd)
    mag0 = np.sqrt(sq_norm(fwd))
    mag1 = np.sqrt(sq_norm(bwd))
    parts = [m[v] for m, v in ((mag0, v0), (mag1, v1)) if v.any()]
    disp = max(float(p.max()) for p in parts) if parts else float(max(mag0.max(), mag1.max()))
    return PairMotion(False, disp, fwd, bwd, v0, v1, time.perf_counter() - t0)


def n_intermediate(max_disp: float, max_px: float = 1.0, cap: int = 255) -> int:
    """Intermediate key frames so that consecutive key frames move at most ``max_px`` pixels."""
    if not max_px > 0:
        raise bad_value("max_px", max_px, "> 0 pixels")
    if max_disp <= max_px:
        return 0
    return int(min(cap, math.ceil(max_disp / max_px - 1e-9) - 1))


def _splat_flows(pair: PairMotion, tau: float, sel0: np.ndarray, sel1: np.ndarray):
    """Splat ``F01`` of frame 0 to ``x + τF01`` and ``−F10`` of frame 1 to ``x + (1−τ)F10``."""
    h, w = pair.fwd.shape[:2]
    wsum = np.zeros((h, w))
    vsum = np.zeros((h, w, 2))
    splat_flow(pair.fwd, np.ascontiguousarray(sel0), float(tau), 1.0, wsum, vsum)
    splat_flow(pair.bwd, np.ascontiguousarray(sel1), float(1.0 - tau), -1.0, wsum, vsum)
    return wsum, vsum


def _flow_at(pair: PairMotion, tau: float, occlusion: bool) -> np.ndarray:
    """Motion field (0→1 vectors) at time ``tau`` by splatting both flows.

    With ``occlusion`` the consistent pixels splat first; pixels seen in one
    frame only (being covered or uncovered) then fill what is still empty, so
    (dis)occluded areas take the motion of the surface that is actually there;
    any remaining hole takes the nearest filled vector.
    """
    h, w = pair.fwd.shape[:2]
    if occlusion:
        wsum, vsum = _splat_flows(pair, tau, pair.valid0, pair.valid1)
        filled = wsum > 1e-3
        w2, v2 = _splat_flows(pair, tau, ~pair.valid0, ~pair.valid1)
        take = ~filled & (w2 > 1e-3)
        wsum = np.where(take, w2, wsum)
        vsum = np.where(take[..., None], v2, vsum)
    else:
        every = np.ones((h, w), bool)
        wsum, vsum = _splat_flows(pair, tau, every, every)
    filled = wsum > 1e-3
    if not filled.any():
        return np.zeros((h, w, 2), np.float32)
    # vsum / wsum where filled, 0 elsewhere (whole-array operations: the same bits as
    # dividing the filled pixels alone, without slow boolean indexing)
    q = vsum / np.where(filled, wsum, 1.0)[..., None]
    u = np.where(filled[..., None], q, 0.0).astype(np.float32)
    if not filled.all():
        from scipy import ndimage  # only where the splatted flow has holes

        idx = ndimage.distance_transform_edt(~filled, return_distances=False, return_indices=True)
        u = u[idx[0], idx[1]]
    return u


def blend(f0: np.ndarray, f1: np.ndarray, tau: float) -> np.ndarray:
    """Plain linear cross-fade ``(1 − τ) I0 + τ I1`` (no motion)."""
    return ((1 - tau) * f0 + tau * f1).astype(np.float32)


def interpolate(
    f0: np.ndarray, f1: np.ndarray, pair: PairMotion, tau: float, occlusion: bool = True,
    roi: tuple[int, int, int, int] | None = None,
) -> np.ndarray:
    """Frame at time ``tau`` in (0, 1) between linear frames ``f0`` and ``f1`` (H, W, 3 float32).

    ``roi = (top, left, height, width)`` returns only that box: the motion
    field is still splatted from the whole frames (content may move into the
    box), but sampling and blending are done for the box's pixels alone.
    """
    if not 0.0 <= tau <= 1.0:
        raise bad_value("tau", tau, "0 <= tau <= 1")
    h, w = f0.shape[:2]
    top, left, bh, bw = roi if roi is not None else (0, 0, h, w)
    if pair.static or tau == 0.0 or tau == 1.0:
        return blend(f0[top : top + bh, left : left + bw], f1[top : top + bh, left : left + bw],
                     tau)
    u = _flow_at(pair, tau, occlusion)[top : top + bh, left : left + bw]
    xs, ys = _grid(bh, bw)
    xs += left
    ys += top
    m0x, m0y = xs - tau * u[..., 0], ys - tau * u[..., 1]
    m1x, m1y = xs + (1 - tau) * u[..., 0], ys + (1 - tau) * u[..., 1]
    # bicubic sampling over- and undershoots at edges: kept within each frame's range
    a = np.clip(_sample(f0, m0x, m0y, cubic=True), 0.0, float(f0.max()))
    b = np.clip(_sample(f1, m1x, m1y, cubic=True), 0.0, float(f1.max()))
    if occlusion:
        # a candidate counts when the pixel sampled there moves with the local motion u
        # (it belongs to the surface seen at x at time tau) and lies inside the frame
        tol = 1.0 + 0.1 * np.sqrt(sq_norm(u))
        d0 = _sample(pair.fwd, m0x, m0y) - u
        d1 = -_sample(pair.bwd, m1x, m1y) - u
        v0 = (np.sqrt(sq_norm(d0)) <= tol).astype(np.float32)
        v1 = (np.sqrt(sq_norm(d1)) <= tol).astype(np.float32)
        v0 *= (m0x >= -0.5) & (m0x <= w - 0.5) & (m0y >= -0.5) & (m0y <= h - 0.5)
        v1 *= (m1x >= -0.5) & (m1x <= w - 0.5) & (m1y >= -0.5) & (m1y <= h - 0.5)
        w0, w1 = (1 - tau) * v0, tau * v1
        none = (w0 + w1) < 1e-3
        w0 = np.where(none, 1 - tau, w0)
        w1 = np.where(none, tau, w1)
    else:
        w0 = np.full((bh, bw), 1 - tau, np.float32)
        w1 = np.full((bh, bw), tau, np.float32)
    out = (w0[..., None] * a + w1[..., None] * b) / (w0 + w1)[..., None]
    return out.astype(np.float32)
