"""Lazy frame sources: video files, image folders (REDS, DAVIS, any sorted folder), scenes.

A source knows its frame count and size without decoding pixels, and decodes
a frame only when :meth:`read` asks for it (``n_decoded`` counts decodes), so a
long video is never loaded whole.  Decoded image files are kept in a small
per-process cache (:mod:`spikesim.scenes.frame_cache`), so clips of one video
cut by a dataset decode each frame once.  Frames come back as stored values in RGB
channel order (uint8, uint16 or float); photometry is applied later
(:mod:`spikesim.scenes.photometry`).

Folder layouts (``layout=``):

* ``"reds"`` – ``<root>/<sequence>/%08d.png`` (REDS, Nah et al. CVPRW 2019);
* ``"davis"`` – ``<root>/JPEGImages/480p/<sequence>/%05d.jpg`` (DAVIS 2017);
* ``"folder"`` – every image file (png, jpg, jpeg, bmp, tif, tiff, exr, webp)
  in a folder, in natural sort order (``2.png`` before ``10.png``);
* ``"file"`` – a video file readable by OpenCV (FFmpeg backend);
* ``"auto"`` – a file is ``"file"``; a folder with ``sequence`` is DAVIS if
  ``JPEGImages/480p/<sequence>`` exists, else REDS; a folder without
  ``sequence`` is ``"folder"``.
"""

from __future__ import annotations

import os
import re
from abc import ABC, abstractmethod
from pathlib import Path

import cv2
import numpy as np

from spikesim.errors import SpikeSimFileError, SpikeSimFormatError, bad_value
from spikesim.scenes.frame_cache import read_image
from spikesim.scenes.jpeg_check import jpeg_truncated

__all__ = [
    "IMAGE_EXTENSIONS",
    "LAYOUTS",
    "FrameSource",
    "ImageFolderSource",
    "VideoFileSource",
    "SceneSource",
    "open_frames",
]

IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".exr", ".webp")
LAYOUTS = ("auto", "file", "reds", "davis", "folder")


def _natural_key(name: str) -> list:
    return [int(part) if part.isdigit() else part.lower() for part in re.split(r"(\d+)", name)]


class FrameSource(ABC):
    """Interface: ``n_frames``, ``height``, ``width``, ``native_fps`` (or None), ``read(i)``."""

    n_frames: int
    height: int
    width: int
    native_fps: float | None = None
    name: str = ""
    linear: bool | None = None  # True when frames are known linear (scene renders)

    def __init__(self) -> None:
        self.n_decoded = 0

    @abstractmethod
    def read(self, index: int) -> np.ndarray:
        """Frame ``index`` as decoded (H, W, 3) array."""

    def _check_index(self, index: int) -> int:
        if not 0 <= index < self.n_frames:
            raise bad_value("frame index", index, f"0..{self.n_frames - 1}")
        return int(index)


def _to_rgb(img: np.ndarray) -> np.ndarray:
    if img.ndim == 2:
        return img
    if img.shape[2] == 4:
        return cv2.cvtColor(img, cv2.COLOR_BGRA2RGB)
    if img.shape[2] == 3:
        return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    return img[..., 0]


class ImageFolderSource(FrameSource):
    """Frames stored as one image file each (names sorted naturally)."""

    def __init__(self, files: list[Path], name: str):
        super().__init__()
        if not files:
            raise SpikeSimFileError(f"no image frames ({', '.join(IMAGE_EXTENSIONS)}) in {name}")
        self.files = list(files)
        self.name = name
        self.n_frames = len(self.files)
        self.height, self.width = self._header_size(self.files[0])
        for f in self.files[1:]:
            size = self._header_size(f)
            if size != (self.height, self.width):
                raise SpikeSimFormatError(
                    f"mixed frame sizes in {name}: {f.name} is {size[0]}x{size[1]} (HxW), "
                    f"{self.files[0].name} is {self.height}x{self.width}"
                )

    @staticmethod
    def _header_size(path: Path) -> tuple[int, int]:
        """(H, W) from the file header only (Pillow), without decoding pixels."""
        try:
            from PIL import Image

            with Image.open(path) as im:
                w, h = im.size
            return h, w
        except ImportError:  # pragma: no cover - Pillow ships with scikit-image
            img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        except Exception:  # noqa: BLE001 - Pillow cannot parse it; let OpenCV try
            img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise SpikeSimFormatError(f"unreadable frame {path}: not a decodable image")
        return img.shape[0], img.shape[1]

    def read(self, index: int) -> np.ndarray:
        """Frame ``index`` (read-only; decoded once per process while it stays in
        :mod:`spikesim.scenes.frame_cache`, shared by every source of the file)."""
        path = self.files[self._check_index(index)]
        return read_image(str(path), self._decode)

    def _decode(self, name: str) -> np.ndarray:
        path = Path(name)
        data = path.read_bytes()
        if path.suffix.lower() in (".jpg", ".jpeg") and jpeg_truncated(data):
            raise SpikeSimFormatError(f"unreadable frame {path}: a truncated JPEG (it ends "
                                      "before its end-of-image marker; restore the file)")
        img = cv2.imdecode(np.frombuffer(data, np.uint8),
                           cv2.IMREAD_UNCHANGED | cv2.IMREAD_ANYDEPTH)
        if img is None:
            raise SpikeSimFormatError(f"unreadable frame {path}: OpenCV could not decode it")
        if img.shape[:2] != (self.height, self.width):
            raise SpikeSimFormatError(
                f"mixed frame sizes in {self.name}: {path.name} decodes to "
                f"{img.shape[0]}x{img.shape[1]}, expected {self.height}x{self.width}"
            )
        self.n_decoded += 1
        return np.ascontiguousarray(_to_rgb(img))


class VideoFileSource(FrameSource):
    """A video file read through OpenCV, sequentially with seeking when needed.

    FFmpeg's own log is silenced (``OPENCV_FFMPEG_LOGLEVEL``, unless the user set
    it): a file it cannot read printed ``moov atom not found`` before this
    class's one-line error."""

    def __init__(self, path: Path):
        super().__init__()
        self.path, self.name = path, str(path)
        os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # read when a capture opens
        self._cap = cv2.VideoCapture(str(path))
        if not self._cap.isOpened():
            raise SpikeSimFormatError(f"unreadable video {path}: OpenCV could not open it")
        self.n_frames = int(self._cap.get(cv2.CAP_PROP_FRAME_COUNT))
        self.height = int(self._cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
        self.width = int(self._cap.get(cv2.CAP_PROP_FRAME_WIDTH))
        fps = float(self._cap.get(cv2.CAP_PROP_FPS))
        self.native_fps = fps if fps > 0 else None
        if self.n_frames < 1 or self.height < 1 or self.width < 1:
            raise SpikeSimFormatError(f"unreadable video {path}: no frames or no size reported")
        self._next = 0

    def read(self, index: int) -> np.ndarray:
        index = self._check_index(index)
        if index != self._next:
            self._cap.set(cv2.CAP_PROP_POS_FRAMES, index)
        ok, img = self._cap.read()
        if not ok or img is None:
            self._next = -1
            raise SpikeSimFormatError(f"unreadable frame {index} of video {self.path}")
        self._next = index + 1
        self.n_decoded += 1
        return _to_rgb(img)

    def close(self) -> None:
        self._cap.release()

    def __getstate__(self):  # pragma: no cover - reopen in the worker
        return {"path": self.path}

    def __setstate__(self, state):  # pragma: no cover
        self.__init__(state["path"])


class SceneSource(FrameSource):
    """Frames ``scene.radiance(i / fps)`` rendered on demand (linear float, or 8-bit sRGB)."""

    def __init__(self, scene, fps: float, n_frames: int, srgb8: bool = False):
        super().__init__()
        self.scene, self.native_fps, self.n_frames = scene, float(fps), int(n_frames)
        self.height, self.width = scene.height, scene.width
        self.srgb8 = bool(srgb8)
        self.linear = not self.srgb8
        self.name = f"render of {scene.describe().get('name', type(scene).__name__)}"

    def read(self, index: int) -> np.ndarray:
        from spikesim.srgb import linear_to_srgb8

        frame = self.scene.radiance(self._check_index(index) / self.native_fps)
        self.n_decoded += 1
        if self.srgb8:
            return linear_to_srgb8(frame)
        return np.asarray(frame, np.float32)


def _images_in(folder: Path, pattern: str | None = None) -> list[Path]:
    names = [e.name for e in os.scandir(folder) if e.is_file()]
    if pattern is not None:
        rx = re.compile(pattern)
        names = [n for n in names if rx.fullmatch(n)]
    else:
        names = [n for n in names if n.lower().endswith(IMAGE_EXTENSIONS)]
    return [folder / n for n in sorted(names, key=_natural_key)]


def open_frames(path: str | os.PathLike, layout: str = "auto",
                sequence: str | None = None) -> FrameSource:
    """Open ``path`` as a lazy frame source according to ``layout`` (see module doc)."""
    if layout not in LAYOUTS:
        raise bad_value("layout", layout, f"one of {LAYOUTS}")
    p = Path(path)
    if not p.exists():
        raise SpikeSimFileError(f"path={str(path)!r} does not exist")
    if layout == "auto":
        if p.is_file():
            layout = "file"
        elif sequence is not None:
            layout = "davis" if (p / "JPEGImages" / "480p" / sequence).is_dir() else "reds"
        else:
            layout = "folder"
    if layout == "file":
        if not p.is_file():
            raise SpikeSimFileError(f"path={str(path)!r} is not a video file")
        return VideoFileSource(p)
    if not p.is_dir():
        raise SpikeSimFileError(f"path={str(path)!r} is not a folder (layout={layout!r})")
    if layout in ("reds", "davis") and sequence is None:
        raise bad_value("sequence", sequence, f"a sequence name for layout={layout!r}")
    if layout == "reds":
        folder, pattern = p / sequence, r"\d{8}\.png"
    elif layout == "davis":
        folder, pattern = p / "JPEGImages" / "480p" / sequence, r"\d{5}\.jpg"
    else:
        folder, pattern = (p / sequence if sequence else p), None
    if not folder.is_dir():
        raise SpikeSimFileError(f"sequence folder {str(folder)!r} does not exist")
    return ImageFolderSource(_images_in(folder, pattern), str(folder))
