"""Export a spikesim dataset to the directory layout the SJDD-Net training code reads.

The published SJDD-Net code (Dong et al., AAAI 2024; ``utils/jdd_dataset.py``,
``JDDDataset``) reads, under a root such as ``data/train`` or ``data/eval``::

    spk/<noise>/<subset>/*.dat     spike windows, PKU .dat, 39 readouts each
    gt/<subset>/*.npy              (1, 3, H, W) uint8 ground truth, 0..255

pairing the two lists **by sorted file name**.  ``<noise>`` is the Gaussian
noise level as an integer (``0``, ``5``, ``10``, ``15``), ``r`` for random
levels, where the level is parsed from the file name after its last ``-``
(``name-7.25.dat``), or ``gp`` for Poisson-Gaussian noise.  Details of that
code this export follows:

* frames are read with ``upside_down=False`` (the training and evaluation
  scripts never set it), so windows are written **without the flip**
  (``flip=False``) — unlike real captures;
* the loader builds the Bayer mask from its ``color_mode`` argument
  (``'rggb'`` by default), so every exported sequence must share one CFA
  pattern; it is recorded in ``spikesim_export.json`` and must be passed as
  ``color_mode`` when it is not RGGB;
* ``H·W`` must be a multiple of 8 (its decoder splits the file into frames of
  ``H·W/8`` bytes);
* the ground truth is divided by 255 and compared with the network output,
  and the noise map target is ``σ/255`` with σ in 8-bit DN of the same light
  that drove the sensor.  The GT is therefore exported in **linear light**
  (``round(255·clip(gt, 0, 1))``), the quantity the spikes measure and the
  one paper-mode σ refers to; ``gt_encoding="srgb"`` writes display-referred
  sRGB instead, for users who trained on sRGB targets.

Each ground-truth readout ``n`` of a sequence with ``n - 19 >= 0`` and
``n + 19 < T`` gives one sample ``<sequence>_<n:06d>``: readouts ``n-19 ..
n+19`` (39, centred on ``n``) and the GT of readout ``n``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from spikesim.errors import SpikeSimFormatError, bad_value
from spikesim.io._atomic import atomic_path
from spikesim.io.dat import DatWriter
from spikesim.io.index import Dataset, open_dataset
from spikesim.io.preview import srgb_encode

__all__ = ["export_sjdd", "sjdd_noise_label", "GT_ENCODINGS", "SJDD_WINDOW"]

SJDD_WINDOW = 39
GT_ENCODINGS = ("linear", "srgb")


def gt_to_uint8(gt: np.ndarray, encoding: str = "linear") -> np.ndarray:
    """(H, W, 3) linear float GT -> (1, 3, H, W) uint8 0..255 (rounded, clipped)."""
    x = np.clip(np.asarray(gt, np.float64), 0.0, 1.0)
    if encoding == "srgb":
        x = srgb_encode(x)
    return np.rint(x * 255.0).astype(np.uint8).transpose(2, 0, 1)[None]


def sjdd_noise_label(meta: dict) -> tuple[str, float | None]:
    """SJDD-Net noise folder of a sequence, and its Gaussian σ (8-bit DN) if it has one.

    No noise -> ``("0", 0.0)``; paper-mode Gaussian -> ``(str(σ_g), σ_g)``;
    paper-mode Poisson-Gaussian -> ``("gp", None)``.  Physical-mode noise has
    no SJDD-Net level and raises.
    """
    sensor = meta.get("sensor") or {}
    noise = sensor.get("noise") if isinstance(sensor, dict) else None
    if not noise:
        return "0", 0.0
    kind = noise.get("type")
    if kind == "paper":
        sg, sp = float(noise.get("sigma_g", 0.0)), float(noise.get("sigma_p", 0.0))
        if sp > 0:
            return "gp", None
        return (str(int(sg)) if sg == int(sg) else f"{sg:g}"), sg
    raise bad_value(
        "noise", kind, "paper-mode or no noise for an automatic SJDD-Net label (pass noise=NAME)"
    )


def _folder_label(labels: list[tuple[str, float | None]], noise: str) -> str:
    if noise != "auto":
        if not isinstance(noise, str) or not noise or "/" in noise or noise in (".", ".."):
            raise bad_value("noise", noise, "'auto' or a folder name such as '0', '15', 'r', 'gp'")
        return noise
    kinds = {lab for lab, _ in labels}
    if len(kinds) == 1:
        return kinds.pop()
    if "gp" in kinds:
        raise bad_value("noise", sorted(kinds), "one noise kind per export (GN or GPN, not both)")
    return "r"  # Gaussian at several levels: the level goes in the file name


def export_sjdd(
    source: str | os.PathLike | Dataset,
    out_dir: str | os.PathLike,
    subset: str = "spikesim",
    noise: str = "auto",
    gt_encoding: str = "linear",
    flip: bool = False,
    progress: bool = False,
) -> dict:
    """Write the SJDD-Net layout under ``out_dir`` (see the module docstring).

    Parameters
    ----------
    source : path or Dataset
        A spikesim file or dataset folder (:func:`~spikesim.io.open_dataset`).
    out_dir : path
        The SJDD-Net root for one split, e.g. ``data/train`` or ``data/eval``.
    subset : str
        Sub-folder name (``--eval_set`` of the SJDD-Net scripts).
    noise : str
        ``"auto"`` derives the noise folder from the sequences' noise
        configuration; any other string is used as the folder name.
    gt_encoding : {"linear", "srgb"}
    flip : bool
        Store frames upside down (False: what the SJDD-Net scripts read).

    Returns a summary dict (samples written, skipped GT readouts, folders).
    """
    from tqdm.auto import tqdm

    if gt_encoding not in GT_ENCODINGS:
        raise bad_value("gt_encoding", gt_encoding, f"one of {GT_ENCODINGS}")
    if not isinstance(subset, str) or not subset or "/" in subset or subset in (".", ".."):
        raise bad_value("subset", subset, "a non-empty folder name")
    ds = source if isinstance(source, Dataset) else open_dataset(source)
    half = SJDD_WINDOW // 2
    cfas = {s.cfa for s in ds}
    if None in cfas or len(cfas) != 1:
        raise SpikeSimFormatError(
            "SJDD-Net export needs Bayer sequences sharing one CFA pattern; found "
            f"{sorted(map(str, cfas))}"
        )
    for s in ds:
        if (s.height * s.width) % 8:
            raise bad_value(f"{s.name}: height*width", s.height * s.width,
                            "a multiple of 8 (the SJDD-Net .dat decoder needs whole bytes)")
    labels = [sjdd_noise_label(s.meta) for s in ds]
    folder = _folder_label(labels, noise)
    out = Path(out_dir)
    spk_dir = out / "spk" / folder / subset
    gt_dir = out / "gt" / subset
    spk_dir.mkdir(parents=True, exist_ok=True)
    gt_dir.mkdir(parents=True, exist_ok=True)
    written, skipped, samples = 0, [], []
    jobs = [(s, lab, k, int(n)) for s, lab in zip(ds, labels, strict=True)
            for k, n in enumerate(s.gt_index)]
    for seq, (_, sigma), k, n in tqdm(jobs, disable=not progress, desc="export", unit="sample"):
        if n - half < 0 or n + half >= seq.n_readouts:
            skipped.append(f"{seq.name}@{n}")
            continue
        stem = f"{seq.name}_{n:06d}"
        dat_name = stem + (f"-{sigma:g}" if folder == "r" and sigma is not None else "") + ".dat"
        if folder == "r" and sigma is None:
            raise bad_value("noise", "r", f"Gaussian sequences only ({seq.name} has no σ_g)")
        with DatWriter(spk_dir / dat_name, seq.height, seq.width, flip=flip) as w:
            w.write_packed(seq.read_window(n - half, SJDD_WINDOW, packed=True))
        with atomic_path(gt_dir / f"{stem}.npy") as tmp, open(tmp, "wb") as fh:
            np.save(fh, gt_to_uint8(seq.read_gt(k), gt_encoding))
        samples.append({"sequence": seq.name, "readout": n, "dat": dat_name, "gt": f"{stem}.npy",
                        "sigma": sigma})
        written += 1
    _check_pairing(spk_dir, gt_dir, strip_sigma=folder == "r")
    cfa = cfas.pop()
    summary = {
        "samples": written, "skipped": skipped, "spk_dir": str(spk_dir), "gt_dir": str(gt_dir),
        "noise_folder": folder, "cfa": cfa, "color_mode": cfa.lower(), "flip": flip,
        "gt_encoding": gt_encoding, "window": SJDD_WINDOW,
    }
    with atomic_path(out / "spikesim_export.json") as tmp:
        tmp.write_text(json.dumps({**summary, "sample_list": samples}, indent=1))
    return summary


def _check_pairing(spk_dir: Path, gt_dir: Path, strip_sigma: bool) -> None:
    """The SJDD-Net loader pairs sorted lists: check that sorting keeps pairs together."""
    dats = sorted(p.name for p in spk_dir.glob("*.dat"))
    gts = sorted(p.name for p in gt_dir.glob("*.npy"))
    stems_d = [d[:-4].rsplit("-", 1)[0] if strip_sigma else d[:-4] for d in dats]
    stems_g = [g[:-4] for g in gts]
    if stems_d != stems_g:
        raise SpikeSimFormatError(
            f"{spk_dir} and {gt_dir} do not pair one to one by sorted name (other files in the "
            "folders, or names that sort differently): clean the folders or use another subset"
        )
