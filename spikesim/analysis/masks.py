"""The user's dark and flat masks for calibration: forms accepted, validation, names.

Users pass a dark mask and flat masks (a list of boolean masks, or one integer
label image with 0 = no region and k = flat region k): :func:`check_regions`
validates shapes, emptiness and overlap, and :func:`flat_names` is how errors
and notes call each flat region.
"""

from __future__ import annotations

import numpy as np

from spikesim.errors import SpikeSimTypeError, bad_value

__all__ = ["FLAT_FORMS", "as_mask", "check_regions", "flat_names"]


#: What the flat masks may be, for the errors that name it.
FLAT_FORMS = "an (H, W) integer label image (0 = none) or boolean (H, W) or (K, H, W) masks"


def as_mask(mask, shape: tuple[int, int], name: str,
            forms: str = "a boolean (H, W) mask") -> np.ndarray:
    """Validate one (H, W) mask (bool, or integers 0/1) and return it as bool;
    ``forms`` says what was expected in the errors."""
    arr = np.asarray(mask)
    if arr.dtype != np.bool_ and arr.dtype.kind not in "iu":
        raise SpikeSimTypeError(f"{name} must be {forms}, got dtype {arr.dtype}")
    if arr.shape != tuple(shape):
        raise bad_value(f"{name}.shape", arr.shape, f"the capture's (H, W) = {tuple(shape)}")
    if arr.dtype != np.bool_ and arr.size and (arr.min() < 0 or arr.max() > 1):
        raise bad_value(name, f"integers from {arr.min()} to {arr.max()}",
                        f"{forms}, with integers 0 and 1 at most")
    return arr.astype(bool)


def _is_label_image(arr) -> bool:
    return arr is not None and arr.ndim == 2 and arr.dtype.kind in "iu"


def flat_names(flat_masks, count: int) -> list[str]:
    """The names errors and notes give the ``count`` flat regions: ``flat_masks
    label k`` for an integer label image (labels in increasing order, the
    order of ``flat_levels``), ``flat_masks[i]`` for masks, ``detected flat
    region i`` where ``flat_masks`` is None (the regions were detected)."""
    if flat_masks is None:
        return [f"detected flat region {i}" for i in range(count)]
    arr = np.asarray(flat_masks) if not isinstance(flat_masks, (list, tuple)) else None
    if _is_label_image(arr):
        return [f"flat_masks label {k}" for k in sorted(set(np.unique(arr).tolist()) - {0})]
    if arr is not None and arr.ndim == 2:
        return ["flat_masks"]
    return [f"flat_masks[{i}]" for i in range(count)]


def check_regions(dark_mask, flat_masks, shape) -> tuple[np.ndarray | None, list[np.ndarray]]:
    """Validate the user's masks: right shape, non-empty, no overlap."""
    dark = None if dark_mask is None else as_mask(dark_mask, shape, "dark_mask")
    if dark is not None and not dark.any():
        raise bad_value("dark_mask", "an all-False mask", "a mask selecting at least one pixel")
    flats: list[np.ndarray] = []
    if flat_masks is not None:
        arr = np.asarray(flat_masks) if not isinstance(flat_masks, (list, tuple)) else None
        if _is_label_image(arr):
            if arr.shape != tuple(shape):
                raise bad_value("flat_masks.shape", arr.shape,
                                f"the capture's (H, W) = {tuple(shape)}")
            labels = arr
            flats = [labels == k for k in sorted(set(np.unique(labels).tolist()) - {0})]
            if not flats:
                raise bad_value("flat_masks", "a label image without labels > 0",
                                "labels 1..K marking the flat regions (0 = none)")
        elif arr is not None and arr.ndim == 2:  # one boolean mask
            flats = [as_mask(arr, shape, "flat_masks", FLAT_FORMS)]
        else:
            seq = list(flat_masks) if arr is None else list(arr)
            flats = [as_mask(m, shape, f"flat_masks[{i}]", FLAT_FORMS) for i, m in enumerate(seq)]
        if not flats:
            raise bad_value("flat_masks", "an empty list", "one or more masks, or None")
        for i, m in enumerate(flats):
            if not m.any():
                raise bad_value(f"flat_masks[{i}]", "an empty region",
                                "a mask selecting at least one pixel")
    masks = ([dark] if dark is not None else []) + flats
    if masks:
        overlap = np.sum(masks, axis=0) > 1
        if overlap.any():
            raise bad_value("masks", f"{int(overlap.sum())} pixels in two regions",
                            "disjoint dark and flat regions")
    return dark, flats
