"""Helpers of the dataset tests: small REDS- and DAVIS-shaped folders made on the fly,
and file-by-file comparison of two built datasets."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np


def texture(height: int, width: int, seed: int = 0) -> np.ndarray:
    """Smooth random 8-bit RGB texture (structure at every scale, so flow has a grip)."""
    rng = np.random.default_rng(seed)
    out = np.zeros((height, width, 3), np.float32)
    for cells, amp in ((8, 0.5), (40, 0.3), (160, 0.2)):
        small = rng.random((max(2, height // cells), max(2, width // cells), 3)).astype(np.float32)
        out += amp * cv2.resize(small, (width, height), interpolation=cv2.INTER_CUBIC)
    return np.clip(out * 255, 0, 255).astype(np.uint8)


def write_frames(folder: Path, n_frames: int, size=(720, 1280), px_per_frame: int = 6,
                 pattern: str = "{:08d}.png", seed: int = 0) -> Path:
    """``n_frames`` frames of a texture panning ``px_per_frame`` pixels right per frame."""
    h, w = size
    folder.mkdir(parents=True, exist_ok=True)
    big = texture(h, w + px_per_frame * n_frames, seed)
    for i in range(n_frames):
        x = px_per_frame * (n_frames - i)
        img = np.ascontiguousarray(big[:, x : x + w, ::-1])
        params = [cv2.IMWRITE_PNG_COMPRESSION, 1] if pattern.endswith(".png") else []
        assert cv2.imwrite(str(folder / pattern.format(i)), img, params)
    return folder


def reds_root(root: Path, videos=("000",), n_frames: int = 12, size=(720, 1280)) -> Path:
    """``root/<video>/%08d.png`` (REDS train_sharp layout)."""
    for k, v in enumerate(videos):
        write_frames(root / v, n_frames, size, seed=k)
    return root


def davis_root(root: Path, videos=("bear",), n_frames: int = 8, size=(480, 854)) -> Path:
    """``root/JPEGImages/480p/<video>/%05d.jpg`` (DAVIS layout)."""
    for k, v in enumerate(videos):
        write_frames(root / "JPEGImages" / "480p" / v, n_frames, size, pattern="{:05d}.jpg",
                     seed=10 + k)
    return root


def _content(path: Path) -> dict:
    import h5py

    with h5py.File(path, "r") as f:
        out = {k: f[k][()] for k in f.keys()}
        out.update({f"attr:{k}": v for k, v in f.attrs.items() if k != "versions"})
    return out


def assert_same_files(a: Path, b: Path) -> None:
    """Same ``*.h5`` files under ``a`` and ``b``, with equal datasets and attributes."""
    files_a = sorted(p.relative_to(a) for p in a.rglob("*.h5"))
    assert files_a == sorted(p.relative_to(b) for p in b.rglob("*.h5")) and files_a
    for rel in files_a:
        ca, cb = _content(a / rel), _content(b / rel)
        assert ca.keys() == cb.keys()
        for k in ca:
            np.testing.assert_array_equal(ca[k], cb[k], err_msg=f"{rel}:{k}")
