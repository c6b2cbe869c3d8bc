"""Small inputs that documentation examples name (a REDS folder, a video file,
a PKU capture), made on the spot by ``<!-- doc-setup -->`` comments.

Every function writes into the current directory (the example's temporary
working directory) and returns the path it made.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

import spikesim as ss
from spikesim.srgb import linear_to_srgb

PEER_DAT = Path(__file__).resolve().parents[3] / "shared" / "fixtures" / "peer-reds" / \
    "203_part2_key_id151.dat"


#: Frames larger than this (pixels on the long side) are rendered at this size
#: and enlarged, so a 100-frame 720×1280 folder takes seconds, not minutes.
RENDER_MAX = 320


def _frames(n_frames: int, size: tuple[int, int], fps: float) -> list[np.ndarray]:
    """8-bit BGR frames of a panning photograph, frame i at t = i / fps."""
    h, w = size
    scale = min(1.0, RENDER_MAX / max(h, w))
    small = (max(1, round(h * scale)), max(1, round(w * scale)))
    scene = ss.scenes.procedural("astronaut", motion="pan", size=small,
                                 speed=60.0 * fps / 24 * scale)
    out = []
    for i in range(n_frames):
        rgb = linear_to_srgb(np.clip(scene.radiance(i / fps), 0, 1))
        frame = (rgb[..., ::-1] * 255 + 0.5).astype(np.uint8)
        if small != (h, w):
            frame = cv2.resize(frame, (w, h), interpolation=cv2.INTER_LINEAR)
        out.append(np.ascontiguousarray(frame))
    return out


def make_reds(root: str = "REDS/train_sharp", sequence: str = "000", n_frames: int = 100,
              size: tuple[int, int] = (180, 320), fps: float = 24.0) -> Path:
    """A REDS-shaped folder ``root/sequence/%08d.png`` (REDS sequences have 100
    frames at 24 fps)."""
    folder = Path(root) / sequence
    folder.mkdir(parents=True, exist_ok=True)
    for i, frame in enumerate(_frames(n_frames, size, fps)):
        cv2.imwrite(str(folder / f"{i:08d}.png"), frame)
    return Path(root)


def make_video_file(path: str = "clip.mp4", n_frames: int = 12, size: tuple[int, int] = (120, 160),
                    fps: float = 24.0) -> Path:
    """A short MPEG-4 video file."""
    h, w = size
    writer = cv2.VideoWriter(path, cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h))
    for frame in _frames(n_frames, size, fps):
        writer.write(frame)
    writer.release()
    return Path(path)


def make_capture(path: str = "capture.dat", height: int = 250, width: int = 400) -> Path:
    """A monochrome PKU ``.dat`` capture: the peer sample when the shared
    fixtures are beside the repository, else a simulated ColorChecker."""
    if PEER_DAT.is_file() and (height, width) == (250, 400):
        Path(path).write_bytes(PEER_DAT.read_bytes())
        return Path(path)
    sensor = ss.Sensor(height=height, width=width, cfa=None, noise=ss.noise.PhysicalNoise())
    scene = ss.scenes.procedural("colorchecker", size=(height, width))
    ss.io.write_dat(path, ss.simulate(scene, sensor, n_readouts=300, seed=0).unpack())
    return Path(path)


NAMES = {f.__name__: f for f in (make_reds, make_video_file, make_capture)}
