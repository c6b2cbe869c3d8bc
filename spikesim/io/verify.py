"""Read every byte of spike files and report damage (``spikesim verify PATH``).

Opening a file checks its header; reading it checks each chunk against its
Fletcher-32 checksum (files written since checksums were added), each chunk
of a format-version-2 file against its CRC-32 (:mod:`spikesim.io.h5.sums`:
Fletcher-32 cannot tell a 16-bit word 0x0000 from 0xFFFF) and each
ground-truth value for NaN and infinity.  :func:`verify` does all of it for a
file or, recursively, for a folder, and also lists the temporary files that
killed writers left behind.  PKU ``.dat`` files carry no checksum: only their
length can be checked, and only at a known frame size.

Each report has a ``status``: ``"ok"`` (checked, nothing wrong), ``"damaged"``,
``"unchecked"`` (a ``.dat`` whose frame size is unknown: give ``height`` and
``width``) or ``"temp"`` (a stale temporary file).  ``ok`` is True only for
``"ok"`` and ``"temp"``: an unchecked file is not reported as ok.  A damaged
file inside a dataset built by ``spikesim dataset`` gets ``advice`` on
remaking it.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from spikesim.errors import SpikeSimError, SpikeSimFileError, SpikeSimFormatError

__all__ = ["SPIKE_SUFFIXES", "dataset_advice", "summarize", "verify", "verify_file"]

#: The file name endings of spike files, which a folder's verification checks.
SPIKE_SUFFIXES = (".h5", ".hdf5", ".dat")

#: Readouts read at a time.
BLOCK_READOUTS = 512


def _report(path: Path, kind: str, *notes: str) -> dict:
    """A new report of a file, ok until something is found."""
    return {"path": str(path), "kind": kind, "ok": True, "status": "ok", "problems": [],
            "notes": list(notes)}


def _damaged(report: dict, exc: BaseException) -> None:
    """Mark ``report`` damaged by ``exc``, with advice when the file belongs to a dataset."""
    report.update(ok=False, status="damaged")
    report["problems"].append(str(exc))
    advice = dataset_advice(Path(report["path"]))
    if advice:
        report["advice"] = advice


def _dataset_root(path: Path) -> Path | None:
    """The dataset root ``path`` belongs to: its folder or the folder above, when it holds
    the ``plan.json`` or ``build_summary.json`` of a ``spikesim dataset`` build."""
    for folder in (path.parent, path.parent.parent):
        if (folder / "plan.json").is_file() or (folder / "build_summary.json").is_file():
            return folder
    return None


def _manifest_of(root: Path) -> str:
    """The manifest a dataset was built from, as its ``plan.json`` records it."""
    try:
        manifest = json.loads((root / "plan.json").read_text()).get("manifest")
    except (OSError, ValueError, AttributeError):
        manifest = None
    return manifest if isinstance(manifest, str) and manifest else "MANIFEST"


def _planned(root: Path, path: Path) -> bool:
    """Whether the last build's ``plan.json`` makes ``path`` (True when it cannot tell)."""
    try:
        tasks = json.loads((root / "plan.json").read_text())["tasks"]
        files = {t["file"] for t in tasks}
    except (OSError, ValueError, KeyError, TypeError):
        return True
    return path.relative_to(root).as_posix() in files


def dataset_advice(path: Path) -> str | None:
    """How to remake a damaged file of a dataset folder (None for a file of no dataset)."""
    root = _dataset_root(path)
    if root is None:
        return None
    if not _planned(root, path):
        return (f"it is in the dataset folder {str(root)!r} but not in the plan of its last "
                f"build (left by an earlier manifest), so no build remakes it: delete it "
                f"(rm {str(path)!r}), or run the build with --prune")
    return (f"it belongs to the dataset built in {str(root)!r}: delete it (rm {str(path)!r}) "
            f"and run the same build again (spikesim dataset {_manifest_of(root)} --out "
            f"{str(root)!r}, with the same --set values), which remakes the missing file")


def _verify_h5(path: Path) -> dict:
    from spikesim.io.h5 import open_h5
    from spikesim.io.h5.format import CRC_VERSION

    report = _report(path, "h5")
    try:
        with open_h5(path) as seq:
            f = seq._h5()
            names = ["spikes", "gt", "gt_index"] + (["clean_spikes"] if seq.has_clean else [])
            unchecked = [n for n in names if not f[n].fletcher32]
            if unchecked:
                report["notes"].append(
                    f"no checksums on {unchecked} (written by an older spikesim): damage inside "
                    "compressed chunks may go unnoticed")
            report["format_version"] = seq.format_version
            report["checksums"] = ("crc32+fletcher32" if seq.format_version >= CRC_VERSION
                                   else "fletcher32")
            if seq.format_version < CRC_VERSION and not unchecked:
                report["notes"].append(
                    f"format version {seq.format_version}: chunks checked by Fletcher-32 only, "
                    "which cannot tell a 16-bit word 0x0000 from 0xFFFF (saturated spikes read "
                    "back as zeros pass); a copy made now (spikesim convert FILE COPY.h5) "
                    "carries CRC-32 chunk checksums")
            for clean in (False, True) if seq.has_clean else (False,):
                for t in range(0, seq.n_readouts, BLOCK_READOUTS):
                    seq.read_window(t, min(BLOCK_READOUTS, seq.n_readouts - t), packed=True,
                                    clean=clean)
            for k in range(len(seq.gt_index)):
                seq.read_gt(k)
            report["readouts"] = seq.n_readouts
            report["gt_frames"] = len(seq.gt_index)
    except SpikeSimError as exc:
        _damaged(report, exc)
    return report


def _verify_dat(path: Path, height: int | None = None, width: int | None = None) -> dict:
    """Length check of a ``.dat``: whole frames of ``height`` x ``width`` (guessed from the
    size when not given; a size that fits no known sensor is unchecked, not damaged)."""
    from spikesim.io.dat import guess_dat_shape

    report = _report(path, "dat", ".dat files carry no checksum: only the length was checked")
    try:
        size = path.stat().st_size
        if size == 0:
            raise SpikeSimFileError(f"{str(path)!r} is empty (0 bytes)")
        if height is None or width is None:
            try:
                height, width, _ = guess_dat_shape(size, path)
            except SpikeSimError:
                report["notes"] = ["frame size unknown (the size fits no known sensor): not "
                                   "checked; pass --height and --width (height= and width= in "
                                   "Python) to check the length"]
                report.update(ok=False, status="unchecked", unchecked=True)
                return report
            report["notes"].append(f"frame size guessed as {height}x{width} (HxW); pass "
                                   "--height and --width if it is another")
        frame = (height * width + 7) // 8
        if size % frame:
            raise SpikeSimFormatError(
                f"{str(path)!r} is not a whole number of {height}x{width} frames ({size} bytes, "
                f"{frame} per frame): truncated, or another frame size")
        report["readouts"] = size // frame
    except (SpikeSimError, OSError) as exc:
        _damaged(report, exc)
    return report


def verify_file(path: str | os.PathLike, height: int | None = None,
                width: int | None = None) -> dict:
    """Check one ``.h5`` or ``.dat`` file (``height``/``width``: the frame size of a
    ``.dat``); returns ``{"path", "ok", "problems", "notes", ...}``."""
    path = Path(path)
    if path.suffix.lower() == ".dat":
        return _verify_dat(path, height, width)
    return _verify_h5(path)


def verify(path: str | os.PathLike, height: int | None = None,
           width: int | None = None) -> list[dict]:
    """Check a file, or every ``.h5``/``.hdf5``/``.dat`` file under a folder
    (``height``/``width``: the frame size of ``.dat`` files, guessed when not given).

    Stale temporary files (left by killed writers) appear as reports with
    ``kind="temp"``, ``status="temp"`` and ``ok=True`` (they never sit under a
    final name; the next write removes them).  A ``.dat`` of unknown frame size
    has ``status="unchecked"`` and ``ok=False`` (see :func:`summarize`).
    """
    from spikesim.io.atomic import is_stale_temp, is_temp_name

    path = Path(path)
    if not path.exists():
        raise SpikeSimFileError(f"no such file or folder: {str(path)!r}")
    if path.is_file():
        return [verify_file(path, height, width)]
    reports = []
    for p in sorted(path.rglob("*")):
        if not p.is_file():
            continue
        if is_temp_name(p):
            if is_stale_temp(p):
                reports.append(_report(p, "temp", "stale temporary file of a killed writer "
                                       "(removed by the next write into this folder)")
                               | {"status": "temp"})
            continue
        if p.suffix.lower() in SPIKE_SUFFIXES:
            reports.append(verify_file(p, height, width))
    if not reports:
        raise SpikeSimFileError(f"{str(path)!r} holds no .h5, .hdf5 or .dat file")
    return reports


def summarize(reports: list[dict]) -> dict:
    """Counts of files by status: ``files`` (temporaries left out), ``checked``, ``ok``,
    ``damaged``, ``unchecked`` and ``temp``."""
    count = {status: sum(r.get("status") == status for r in reports)
             for status in ("ok", "damaged", "unchecked", "temp")}
    files = len(reports) - count["temp"]
    return {"files": files, "checked": files - count["unchecked"], **count}
