"""PKU ``.dat`` spike files: read (memory-mapped, windowed) and write (atomic).

The format (docs/io.md, docs/architecture.md), as written by the PKU spike cameras and read by
SpikeCV, Spike-Zoo and the SJDD-Net code:

* no header; the file is a sequence of frames (readouts), nothing else;
* a frame of ``H × W`` pixels is ``H·W/8`` bytes; pixel ``k = y·W + x`` of the
  *stored* frame lives in byte ``k // 8``, bit ``k % 8`` (LSB first);
* frames are stored **upside down**: stored row 0 is the bottom of the image,
  so readers flip rows (``flip=True``, the default) to get row 0 = top;
* raw 416-wide captures carry 16 head columns (sensor metadata, not light) at
  the start of every row: ``head_columns=16`` drops them.

When ``H·W`` is not a multiple of 8 (possible for simulated sizes, never for a
real sensor) each frame is padded with zero bits to a whole byte, so frame
``t`` always starts at byte ``t·ceil(H·W/8)``.  The PKU tools assume
``H·W % 8 == 0``; keep such sizes for files that only this package reads.

Reading maps the file into memory and decodes only the requested window and
crop, so a multi-gigabyte capture opens instantly.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from spikesim._validate import check_crop, check_window
from spikesim.cfa import normalize_cfa
from spikesim.errors import (
    SpikeSimFileError,
    SpikeSimFormatError,
    SpikeSimTypeError,
    SpikeSimValueError,
    bad_value,
)
from spikesim.io._checks import check_flag, check_path_type
from spikesim.io._decode import decode_frames
from spikesim.io._guard import write_error
from spikesim.io._runs import contiguous_chunks
from spikesim.io.atomic import atomic_path, lock_temp

__all__ = [
    "HALF_SIZE",
    "KNOWN_SENSOR_SIZES",
    "RAW_HEAD_COLUMNS",
    "DatFile",
    "dat_frame_bytes",
    "guess_dat_shape",
    "open_dat",
    "read_dat",
    "write_dat",
    "DatWriter",
    "encode_dat_frames",
]

#: Head columns at the start of each row of a raw 416-wide capture.
RAW_HEAD_COLUMNS = 16
#: Stored width of a raw PKU capture with its head columns (400 image columns + 16).
RAW_WIDTH = 400 + RAW_HEAD_COLUMNS

#: Sensor sizes tried, in this order, when a reader is not told the size:
#: ``(height, width, description)`` with width as stored in the file.
KNOWN_SENSOR_SIZES: tuple[tuple[int, int, str], ...] = (
    (250, 400, "PKU Vidar 400x250 (REDS/Spk2ImgNet, Spike-Zoo, SpikeCV)"),
    (250, 416, "PKU raw 416x250 capture with 16 head columns (drop with head_columns=16)"),
    (1000, 1000, "PKU colour spike camera 1000x1000 (SJDD-Net real captures)"),
    (500, 800, "PKU 800x500 spike camera"),
    (256, 448, "256x448 synthetic sets (e.g. X4K/GoPro-derived spike data)"),
)


#: The command lines' error for a ``.dat`` frame size given half (``--height`` without
#: ``--width``).
HALF_SIZE = "give both --height and --width (the .dat frame size), or neither to have it guessed"


def dat_frame_bytes(height: int, width: int) -> int:
    """Bytes per stored frame: ``ceil(height * width / 8)``."""
    return (int(height) * int(width) + 7) // 8


def guess_dat_shape(n_bytes: int, path: str | os.PathLike = "",
                    partial: str = "error") -> tuple[int, int, str]:
    """Pick the first of :data:`KNOWN_SENSOR_SIZES` whose frame size divides ``n_bytes``.

    With ``partial="drop"`` (a truncated capture), when no known size divides
    ``n_bytes``, the one known size of which at least one whole frame fits is
    taken instead, the trailing partial frame then for the reader to drop
    (with its warning); where several fit, nothing tells them apart (a cut
    1000×1000 capture is as many whole 400×250 frames and a part), so that is
    an error naming them.

    Returns ``(height, width, message)``; the message says what was assumed and
    which other known sizes would also have fitted.  Raises
    :class:`SpikeSimFormatError` when none fits.
    """
    if partial not in ("error", "drop"):
        raise bad_value("partial", partial, "'error' or 'drop'")
    fits = _known_sizes_dividing(n_bytes)
    dropping = not fits and partial == "drop"
    if dropping:
        fits = [(h, w, d) for h, w, d in KNOWN_SENSOR_SIZES if n_bytes >= dat_frame_bytes(h, w)]
    if not fits:
        raise _cannot_guess(n_bytes, path, partial)
    if dropping and len(fits) > 1:
        sizes = ", ".join(f"{w}x{h}" for h, w, _ in fits)
        raise SpikeSimFormatError(
            f"cannot guess the frame size of {str(path) or 'the .dat file'} ({n_bytes} bytes): "
            f"no known sensor size is a whole number of frames, and a capture cut short could "
            f"be any of {sizes} (W x H); pass height and width (--height and --width on the "
            "command line)")
    h, w, desc = fits[0]
    n = n_bytes // dat_frame_bytes(h, w)
    msg = f"assumed {w}x{h} (W x H, {desc}): {n} readouts"
    if dropping:
        msg += (f" and {n_bytes - n * dat_frame_bytes(h, w)} trailing bytes of a partial "
                "frame (no known size is a whole number of frames)")
    if len(fits) > 1:
        others = ", ".join(f"{ww}x{hh}" for hh, ww, _ in fits[1:])
        msg += (f"; the size also fits {others}: pass height and width (--height and --width "
                "on the command line) to choose")
    return h, w, msg


def _known_sizes_dividing(n_bytes: int) -> list[tuple[int, int, str]]:
    """The known sensor sizes of which ``n_bytes`` is a whole number (>= 1) of frames."""
    return [(h, w, d) for h, w, d in KNOWN_SENSOR_SIZES
            if n_bytes and n_bytes % dat_frame_bytes(h, w) == 0]


def _cannot_guess(n_bytes: int, path: str | os.PathLike, partial: str) -> SpikeSimFormatError:
    """The error of a size that fits no known sensor (with what else to try)."""
    known = ", ".join(f"{w}x{h}" for h, w, _ in KNOWN_SENSOR_SIZES)
    hint = ("" if partial == "drop" else
            "; for a truncated capture, give them with partial='drop' (--partial drop) to drop "
            "the partial frame at the end")
    return SpikeSimFormatError(
        f"cannot guess the frame size of {str(path) or 'the .dat file'} ({n_bytes} bytes): "
        f"it is not a whole number of frames of any known sensor size ({known}, W x H); "
        f"pass height and width (--height and --width on the command line){hint}"
    )


def _check_dim(name: str, value: object) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise bad_value(name, value, "an integer >= 1 (pixels)")
    return int(value)


@dataclass(frozen=True)
class _Layout:
    height: int
    width: int  # stored width, head columns included
    head: int
    n_readouts: int
    frame_bytes: int


class DatFile:
    """A ``.dat`` capture opened for windowed reading (memory-mapped, lazy).

    Parameters
    ----------
    path : path
        The ``.dat`` file.
    height, width : int, optional
        Stored frame size in pixels (width *including* head columns).  Both or
        neither: when neither is given the size is guessed from
        :data:`KNOWN_SENSOR_SIZES` and a warning says what was assumed.
    flip : bool
        The file is stored upside down (PKU convention, default True).
    head_columns : int
        Columns to drop at the start of every stored row (16 for raw 416-wide
        captures, see :data:`RAW_HEAD_COLUMNS`).
    partial : {"error", "drop"}
        What to do when the file is not a whole number of frames: raise
        (default) or ignore the trailing partial frame with a warning.
    cfa : str or None
        Bayer pattern of the sensor (the file does not record it); None = mono.
    clock_hz : float or None
        Readout clock (the file does not record it either), for durations.

    Attributes
    ----------
    height, width : int
        Output frame size (width after dropping head columns).
    n_readouts : int
        Whole frames in the file.

    The object holds no open file descriptor between calls, so it pickles and
    is safe to use in spawned or forked worker processes.
    """

    def __init__(
        self,
        path: str | os.PathLike,
        height: int | None = None,
        width: int | None = None,
        flip: bool = True,
        head_columns: int = 0,
        partial: str = "error",
        cfa: str | None = None,
        clock_hz: float | None = None,
    ):
        self.path = Path(path)
        self.name = self.path.stem
        self.cfa = normalize_cfa(cfa)
        if clock_hz is not None and not (isinstance(clock_hz, (int, float)) and clock_hz > 0):
            raise bad_value("clock_hz", clock_hz, "a positive readout rate in Hz, or None")
        self.clock_hz = float(clock_hz) if clock_hz else 0.0
        self.gt_index = np.zeros(0, np.int64)
        self.has_clean = False
        self.flip = check_flag("flip", flip)
        if partial not in ("error", "drop"):
            raise bad_value("partial", partial, "'error' or 'drop'")
        if not self.path.is_file():
            raise SpikeSimFileError(f"no such .dat file: {str(self.path)!r}")
        n_bytes = self.path.stat().st_size
        if n_bytes == 0:
            raise SpikeSimFormatError(f"{str(self.path)!r} is empty (0 bytes): no spike frames")
        self.guess_message = None
        if height is None and width is None:
            height, width, self.guess_message = guess_dat_shape(n_bytes, self.path, partial)
            warnings.warn(f"{self.path.name}: {self.guess_message}", UserWarning, stacklevel=2)
        elif height is None or width is None:
            raise bad_value("height/width", (height, width), "both given or both None (guess)")
        height = _check_dim("height", height)
        width = _check_dim("width", width)
        if isinstance(head_columns, bool) or not isinstance(head_columns, (int, np.integer)):
            raise bad_value("head_columns", head_columns, f"an integer in [0, {width - 1}]")
        if not 0 <= head_columns < width:
            raise bad_value("head_columns", head_columns, f"an integer in [0, {width - 1}]")
        if head_columns == RAW_HEAD_COLUMNS and width != RAW_WIDTH:
            warnings.warn(f"{self.path.name}: head_columns={head_columns} on a {width}-wide "
                          f"frame: the raw captures that carry head columns are {RAW_WIDTH} "
                          f"wide, so this file probably has none and loses {head_columns} real "
                          "columns (drop the head only from a raw 416-wide capture)",
                          UserWarning, stacklevel=2)
        fb = dat_frame_bytes(height, width)
        n, rest = divmod(n_bytes, fb)
        if n == 0:
            raise SpikeSimFormatError(
                f"{str(self.path)!r} ({n_bytes} bytes) holds no whole {width}x{height} frame "
                f"({fb} bytes)"
            )
        if rest:
            what = (
                f"{str(self.path)!r} is {n_bytes} bytes, not a whole number of {width}x{height} "
                f"frames ({fb} bytes each): {n} frames and {rest} bytes left over"
            )
            if partial == "error":
                raise SpikeSimFormatError(
                    what + "; check height/width, or pass partial='drop' to ignore the "
                    "partial frame (--height/--width, --partial drop on the command line)"
                )
            warnings.warn(what + "; the partial frame is ignored", UserWarning, stacklevel=2)
        self._layout = _Layout(height, width, int(head_columns), n, fb)

    # --- shape -------------------------------------------------------------
    @property
    def height(self) -> int:
        return self._layout.height

    @property
    def width(self) -> int:
        return self._layout.width - self._layout.head

    @property
    def stored_width(self) -> int:
        return self._layout.width

    @property
    def head_columns(self) -> int:
        return self._layout.head

    @property
    def n_readouts(self) -> int:
        return self._layout.n_readouts

    @property
    def shape(self) -> tuple[int, int, int]:
        return (self.n_readouts, self.height, self.width)

    @property
    def duration_s(self) -> float:
        return self.n_readouts / self.clock_hz if self.clock_hz > 0 else float("nan")

    @property
    def meta(self) -> dict:
        """What is known of the capture (a ``.dat`` file records no configuration)."""
        return {
            "source": "dat", "file": str(self.path), "height": self.height, "width": self.width,
            "cfa": self.cfa, "clock_hz": self.clock_hz or None, "flip": self.flip,
            "head_columns": self.head_columns, "n_readouts": self.n_readouts,
        }

    def __len__(self) -> int:
        return self.n_readouts

    def __repr__(self) -> str:
        return (
            f"DatFile({str(self.path)!r}, height={self.height}, width={self.stored_width}, "
            f"flip={self.flip}, head_columns={self.head_columns}) # {self.n_readouts} readouts"
        )

    # --- reading -----------------------------------------------------------
    def _map(self) -> np.ndarray:
        lay = self._layout
        return np.memmap(self.path, np.uint8, "r", 0, (lay.n_readouts * lay.frame_bytes,))

    def read_window(
        self, start: int = 0, length: int | None = None, crop: tuple | None = None,
        packed: bool = False,
    ) -> np.ndarray:
        """Decode readouts ``start .. start+length-1``, optionally a crop.

        Parameters
        ----------
        start, length : int
            Window in readouts (``length=None``: to the end).
        crop : (top, left, height, width), optional
            Region in output coordinates (row 0 = top after the flip, column 0
            = first column after the head columns).
        packed : bool
            Return (length, h, ceil(w/8)) packed bits (little bit order)
            instead of (length, h, w) 0/1 bytes.
        """
        packed = check_flag("packed", packed)
        lay = self._layout
        start, length = check_window(start, length, lay.n_readouts)
        top, left, h, w = check_crop(crop, lay.height, lay.width - lay.head)
        frames = decode_frames(
            self._map(), lay.frame_bytes, start, length, lay.height, lay.width, self.flip,
            lay.head, top, left, h, w,
        )
        if packed:
            return np.packbits(frames, axis=-1, bitorder="little")
        return frames

    def read(self) -> np.ndarray:
        """All frames as (T, H, W) uint8 0/1."""
        return self.read_window(0, None)


def open_dat(path: str | os.PathLike, height: int | None = None, width: int | None = None,
             flip: bool = True, head_columns: int = 0, partial: str = "error",
             cfa: str | None = None, clock_hz: float | None = None) -> DatFile:
    """Open a ``.dat`` file for windowed reading; see :class:`DatFile`."""
    return DatFile(path, height, width, flip=flip, head_columns=head_columns, partial=partial,
                   cfa=cfa, clock_hz=clock_hz)


def read_dat(
    path: str | os.PathLike,
    height: int | None = None,
    width: int | None = None,
    flip: bool = True,
    start: int = 0,
    length: int | None = None,
    head_columns: int = 0,
    partial: str = "error",
    crop: tuple | None = None,
) -> np.ndarray:
    """Read a PKU ``.dat`` file (or a window of it) as (T, H, W) uint8 0/1.

    ``height``/``width`` are the stored size (head columns included); leave
    both out to guess from :data:`KNOWN_SENSOR_SIZES` (with a warning saying
    what was assumed).  See :class:`DatFile` for the other parameters.

    Examples
    --------
    >>> spikes = read_dat("capture.dat", 250, 400)               # doctest: +SKIP
    >>> window = read_dat("capture.dat", 250, 400, start=130, length=41)  # doctest: +SKIP
    """
    dat = DatFile(path, height, width, flip=flip, head_columns=head_columns, partial=partial)
    return dat.read_window(start, length, crop)


def _as_frames(spikes: np.ndarray) -> np.ndarray:
    arr = np.asarray(spikes)
    if arr.ndim != 3:
        raise bad_value("spikes.shape", arr.shape, "(T, H, W) 0/1 frames")
    if arr.dtype.kind not in "biu":
        raise SpikeSimTypeError(f"spikes must be bool or integer 0/1, got dtype {arr.dtype}")
    if arr.size and arr.dtype != np.bool_ and (arr.min() < 0 or arr.max() > 1):
        raise bad_value("spikes", f"values in [{arr.min()}, {arr.max()}]", "0/1 values")
    return arr


def encode_dat_frames(packed: np.ndarray, width: int, flip: bool = True) -> bytes:
    """Bytes of ``.dat`` frames from (T, H, ceil(W/8)) packed rows (little bit order).

    With ``W % 8 == 0`` the stored frame is the packed rows themselves (flipped),
    so nothing is unpacked; otherwise rows are re-packed into a continuous
    bit stream per frame, padded to a whole byte.
    """
    packed = np.asarray(packed)
    if flip:
        packed = packed[:, ::-1]
    if width % 8 == 0:
        return np.ascontiguousarray(packed).tobytes()
    t, h = packed.shape[:2]
    bits = np.unpackbits(packed, axis=-1, count=width, bitorder="little").reshape(t, h * width)
    return np.packbits(bits, axis=-1, bitorder="little").tobytes()


class DatWriter:
    """Append frames to a ``.dat`` file; the file appears under its name only on success.

    Use as a context manager::

        with DatWriter("out.dat", height, width) as w:
            w.write_packed(chunk_packed)     # (t, H, ceil(W/8)) little bit order
            w.write(frames)                  # or (t, H, W) 0/1

    An exception inside the block removes the temporary file and leaves no
    file under the final name; so does a block that writes no frame (a file
    with no readout is not a spike file: readers refuse it), with an error.
    """

    def __init__(self, path: str | os.PathLike, height: int, width: int, flip: bool = True,
                 overwrite: bool = True):
        self.path = _check_dat_path(path)
        self.height = _check_dim("height", height)
        self.width = _check_dim("width", width)
        self.flip = check_flag("flip", flip)
        self.overwrite = check_flag("overwrite", overwrite)
        self.n_readouts = 0
        self._ctx = None
        self._fh = None

    def __enter__(self) -> DatWriter:
        self._ctx = atomic_path(self.path, overwrite=self.overwrite)
        tmp = self._ctx.__enter__()
        try:
            self._fh = open(tmp, "wb")  # noqa: SIM115 - closed in __exit__
            lock_temp(self._fh.fileno())
        except OSError as exc:
            err = write_error(self.path, exc)
            self._ctx.__exit__(type(err), err, None)
            raise err from None
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc is None and self.n_readouts == 0:
            exc = _nothing_written(self.path)
            self._discard(exc)
            raise exc
        if exc is None:
            try:
                self._fh.close()
            except OSError as err:  # the last buffered bytes did not fit
                failed = write_error(self.path, err)
                self._ctx.__exit__(type(failed), failed, None)
                raise failed from None
            return bool(self._ctx.__exit__(None, None, None))
        return self._discard(exc, exc_type, tb)

    def _discard(self, exc: BaseException, exc_type=None, tb=None) -> bool:
        """Close and delete the temporary file (the write failed or wrote nothing)."""
        try:
            self._fh.close()
        except OSError:
            pass
        return bool(self._ctx.__exit__(exc_type or type(exc), exc, tb))

    def write_packed(self, packed: np.ndarray) -> None:
        packed = np.asarray(packed)
        want = (self.height, (self.width + 7) // 8)
        if packed.dtype != np.uint8 or packed.ndim != 3 or packed.shape[1:] != want:
            raise bad_value(
                "packed", f"{packed.dtype} {packed.shape}", f"uint8 (t, {want[0]}, {want[1]})"
            )
        try:
            self._fh.write(encode_dat_frames(packed, self.width, self.flip))
        except OSError as exc:
            raise write_error(self.path, exc) from None
        self.n_readouts += packed.shape[0]

    def write(self, frames: np.ndarray) -> None:
        frames = _as_frames(frames)
        if frames.shape[1:] != (self.height, self.width):
            raise bad_value("frames.shape", frames.shape, f"(t, {self.height}, {self.width})")
        self.write_packed(np.packbits(frames.astype(bool), axis=-1, bitorder="little"))


def _check_dat_path(path: object) -> Path:
    """The output path of a ``.dat`` writer: any file name but an HDF5 one."""
    p = check_path_type("path", path)
    if p.suffix.lower() in (".h5", ".hdf5"):
        raise bad_value("path", str(p), "a .dat file name (for a spikesim HDF5 file: "
                        "spikesim.io.write_h5 or H5Writer)")
    return p


def _nothing_written(path: Path) -> SpikeSimValueError:
    """The error of a writer closed before any readout was written."""
    return SpikeSimValueError(
        f"no readout was written to {str(path)!r}: a spike file needs at least one readout "
        "(readers refuse an empty one), so no file was made; write frames before closing")


def write_dat(path: str | os.PathLike, spikes, flip: bool = True, overwrite: bool = True) -> int:
    """Write spikes to a PKU ``.dat`` file atomically; returns the number of readouts.

    Parameters
    ----------
    spikes : (T, H, W) array of 0/1, a ``SpikeStream``, or a ``simulate_chunks`` run
        An array is packed and written; a ``SpikeStream`` (an object with
        ``packed`` and ``width``) has its packed bits written without
        unpacking; a run (``ss.simulate_chunks(...)``, an iterable of chunks
        with a ``meta`` dict) is simulated and written chunk by chunk, so
        memory stays bounded, with the same bytes as writing
        ``ss.simulate(...)`` of the same call.  Ground truth and the clean
        twin are not stored (the format has no place for them).
    flip : bool
        Store upside down (PKU convention, default True).
    overwrite : bool
        Replace an existing file of the same name (atomically).

    The file appears under ``path`` only once complete: an error part-way
    (in the simulation too) leaves no file, and so do spikes with no readout
    (an error: readers refuse an empty ``.dat``).  A path ending in ``.h5`` or
    ``.hdf5`` is refused (use :func:`~spikesim.io.write_h5` for those).
    """
    if hasattr(spikes, "packed") and hasattr(spikes, "width"):
        packed = np.asarray(spikes.packed)
        height, width = packed.shape[1], int(spikes.width)
        with DatWriter(path, height, width, flip=flip, overwrite=overwrite) as w:
            w.write_packed(packed)
        return w.n_readouts
    meta = getattr(spikes, "meta", None)
    if isinstance(meta, dict) and hasattr(spikes, "__iter__"):
        return _write_run(path, spikes, meta, flip, overwrite)
    frames = _as_frames(spikes)
    if min(frames.shape) < 1:
        raise bad_value("spikes.shape", frames.shape,
                        "(T, H, W) with T >= 1 readout (a .dat file needs at least one), "
                        "H >= 1 and W >= 1")
    with DatWriter(path, frames.shape[1], frames.shape[2], flip=flip, overwrite=overwrite) as w:
        w.write(frames)
    return w.n_readouts


def _write_run(path: str | os.PathLike, run, meta: dict, flip: bool, overwrite: bool) -> int:
    """Stream the chunks of a ``simulate_chunks`` run into one ``.dat`` file."""
    with DatWriter(path, meta.get("height"), meta.get("width"), flip=flip,
                   overwrite=overwrite) as w:
        for chunk in contiguous_chunks(run):
            w.write_packed(chunk.packed)
    return w.n_readouts
