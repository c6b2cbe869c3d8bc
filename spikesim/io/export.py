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

Noise folders: a named folder (``noise="phy"``, ``--noise phy``) takes every
sequence whatever its noise model (physical-mode data included).  With
``noise="auto"`` one kind of noise gives one folder (several Gaussian levels
give ``r``, physical-mode noise, which has no SJDD-Net level, ``phy``); a
**mixed** dataset (e.g. GN and GPN sequences) exports each label to its own
folder, and since the loader pairs ``spk/<noise>/<subset>``
with ``gt/<subset>`` by sorted name, each label also gets its own subset
``<subset>-<label>`` (``spk/gp/spikesim-gp`` with ``gt/spikesim-gp``, ...);
the summary lists every (noise, subset) pair to pass to the SJDD-Net scripts.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from spikesim.errors import SpikeSimFormatError, SpikeSimValueError, bad_value
from spikesim.io.atomic import atomic_path
from spikesim.io.dat import DatWriter
from spikesim.io.index import Dataset, open_dataset
from spikesim.srgb import linear_to_srgb

__all__ = ["export_sjdd", "sjdd_noise_label", "GT_ENCODINGS", "SJDD_WINDOW"]

SJDD_WINDOW = 39
GT_ENCODINGS = ("linear", "srgb")
#: The folder ``noise="auto"`` gives physical-mode sequences (a label: no SJDD-Net level).
PHYSICAL_FOLDER = "phy"


def gt_to_uint8(gt: np.ndarray, encoding: str = "linear") -> np.ndarray:
    """(H, W, 3) linear float GT -> (1, 3, H, W) uint8 0..255 (rounded, clipped)."""
    x = np.clip(np.asarray(gt, np.float64), 0.0, 1.0)
    if encoding == "srgb":
        x = linear_to_srgb(x)
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


def _bad(name: str, value, allowed: str) -> SpikeSimValueError:
    """bad_value, or for a command-line flag (``--noise``) ``--noise 'x' is invalid: ...``."""
    if name.startswith("-"):
        return SpikeSimValueError(f"{name} {value!r} is invalid: expected {allowed}")
    return bad_value(name, value, allowed)


def _gaussian_sigma(meta: dict) -> float | None:
    """σ_g (8-bit DN) of a paper-mode Gaussian or noise-free sequence, else None (no raise)."""
    noise = (meta.get("sensor") or {}).get("noise") if isinstance(meta.get("sensor"), dict) \
        else None
    if not noise:
        return 0.0
    if noise.get("type") == "paper" and float(noise.get("sigma_p", 0.0)) == 0.0:
        return float(noise.get("sigma_g", 0.0))
    return None


def _check_named_folder(noise: str, folders, seqs, flag: str) -> None:
    """A folder name the SJDD-Net scripts read a noise level from must match the data:
    an integer σ_g folder needs every sequence Gaussian at that σ_g, ``r`` needs
    Gaussian sequences (σ_g goes in each file name), ``gp`` Poisson-Gaussian ones.
    Any other name (``phy``, your own) is only a label and takes every sequence."""
    for seq, (_, sigma) in zip(seqs, folders, strict=True):
        if noise.isdigit() and (sigma is None or abs(sigma - int(noise)) > 1e-6):
            have = "no Gaussian σ_g" if sigma is None else f"σ_g {sigma:g}"
            raise _bad(flag, noise, f"sequences with Gaussian σ_g = {noise} DN ({seq.name} has "
                                    f"{have}); name another folder, or 'r' for several levels")
        if noise == "r" and sigma is None:
            raise _bad(flag, noise, f"Gaussian sequences only ({seq.name} has no σ_g); "
                                    "name another folder for it")
        if noise == "gp":
            sensor = seq.meta.get("sensor")
            model = (sensor.get("noise") if isinstance(sensor, dict) else None) or {}
            if model.get("type") != "paper" or float(model.get("sigma_p", 0.0)) == 0.0:
                raise _bad(flag, noise, f"Poisson-Gaussian paper-mode sequences only "
                                        f"({seq.name} is not); name another folder for it")


def _folders(ds: Dataset, noise: str, flag: str) -> list[tuple[str, float | None]]:
    """(noise folder, σ_g or None) per sequence; a named folder wins over the metadata."""
    if noise != "auto":
        if not isinstance(noise, str) or not noise or "/" in noise or noise in (".", ".."):
            raise _bad(flag, noise, "'auto' or a folder name such as '0', '15', 'r', 'gp', "
                            "'phy'")
        folders = [(noise, _gaussian_sigma(s.meta)) for s in ds]
        _check_named_folder(noise, folders, [s for s in ds], flag)
        return folders
    labels = []
    for s in ds:
        try:
            labels.append(sjdd_noise_label(s.meta))
        except SpikeSimValueError:  # physical mode: no SJDD-Net level, a label of its own
            labels.append((PHYSICAL_FOLDER, None))
    gaussian = {lab for lab, sigma in labels if sigma is not None}
    shared = gaussian.pop() if len(gaussian) == 1 else "r"  # several levels: in file names
    return [(lab if sigma is None else shared, sigma) for lab, sigma in labels]


def export_sjdd(
    source: str | os.PathLike | Dataset,
    out_dir: str | os.PathLike,
    subset: str = "spikesim",
    noise: str = "auto",
    gt_encoding: str = "linear",
    flip: bool = False,
    progress: bool = False,
    option_names: dict | None = None,
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
        configuration (mixed datasets: one folder and subset per label, see
        the module doc); any other string is the folder of every sequence.
    gt_encoding : {"linear", "srgb"}
    flip : bool
        Store frames upside down (False: what the SJDD-Net scripts read).
    option_names : dict, optional
        How error messages name the options (the CLI passes its flags,
        e.g. ``{"noise": "--noise"}``); default: the keyword names.

    Returns a summary dict (samples written, skipped GT readouts, folders;
    ``exports`` lists each (noise folder, subset) written).
    """
    from tqdm.auto import tqdm

    names = {"noise": "noise", "subset": "subset", "gt_encoding": "gt_encoding",
             **(option_names or {})}
    if gt_encoding not in GT_ENCODINGS:
        raise _bad(names["gt_encoding"], gt_encoding, f"one of {GT_ENCODINGS}")
    if not isinstance(subset, str) or not subset or "/" in subset or subset in (".", ".."):
        raise _bad(names["subset"], subset, "a non-empty folder name")
    ds = source if isinstance(source, Dataset) else open_dataset(source)
    half = SJDD_WINDOW // 2
    cfas = {s.cfa for s in ds}
    if None in cfas or len(cfas) != 1:
        raise SpikeSimFormatError(
            "SJDD-Net export needs Bayer sequences sharing one CFA pattern; found "
            f"{sorted(c or 'mono' for c in cfas)}"
        )
    for s in ds:
        if (s.height * s.width) % 8:
            raise bad_value(f"{s.name}: height*width", s.height * s.width,
                            "a multiple of 8 (the SJDD-Net .dat decoder needs whole bytes)")
    folders = _folders(ds, noise, names["noise"])
    groups = sorted({f for f, _ in folders})
    out = Path(out_dir)
    exports = []
    written, skipped, samples = 0, [], []
    jobs = [(s, f, sigma, k, int(n)) for s, (f, sigma) in zip(ds, folders, strict=True)
            for k, n in enumerate(s.gt_index)]
    for folder in groups:
        sub = subset if len(groups) == 1 else f"{subset}-{folder}"
        spk_dir = out / "spk" / folder / sub
        gt_dir = out / "gt" / sub
        spk_dir.mkdir(parents=True, exist_ok=True)
        gt_dir.mkdir(parents=True, exist_ok=True)
        count = 0
        mine = [j for j in jobs if j[1] == folder]
        for seq, _, sigma, k, n in tqdm(mine, disable=not progress, desc=f"export {folder}",
                                        unit="sample"):
            if n - half < 0 or n + half >= seq.n_readouts:
                skipped.append(f"{seq.name}@{n}")
                continue
            stem = f"{seq.name}_{n:06d}"
            dat_name = stem + (f"-{sigma:g}" if folder == "r" else "") + ".dat"
            with DatWriter(spk_dir / dat_name, seq.height, seq.width, flip=flip) as w:
                w.write_packed(seq.read_window(n - half, SJDD_WINDOW, packed=True))
            with atomic_path(gt_dir / f"{stem}.npy") as tmp, open(tmp, "wb") as fh:
                np.save(fh, gt_to_uint8(seq.read_gt(k), gt_encoding))
            samples.append({"sequence": seq.name, "readout": n, "dat": dat_name,
                            "gt": f"{stem}.npy", "sigma": sigma, "noise_folder": folder,
                            "subset": sub})
            count += 1
        _check_pairing(spk_dir, gt_dir, strip_sigma=folder == "r")
        exports.append({"noise_folder": folder, "subset": sub, "spk_dir": str(spk_dir),
                        "gt_dir": str(gt_dir), "samples": count})
        written += count
    cfa = cfas.pop()
    first = exports[0]
    summary = {
        "samples": written, "skipped": skipped, "spk_dir": first["spk_dir"],
        "gt_dir": first["gt_dir"], "noise_folder": first["noise_folder"] if len(groups) == 1
        else "mixed", "exports": exports, "cfa": cfa, "color_mode": cfa.lower(), "flip": flip,
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
