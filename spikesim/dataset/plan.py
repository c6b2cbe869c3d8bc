"""Expand a manifest into one task per sequence, each with its own derived seed.

The seed of a sequence is a hash of the global seed and the sequence id, so a
sequence's content does not depend on how many others there are, on the
order of execution, or on which machine runs it; it is recorded in the file.
"""

from __future__ import annotations

import hashlib
import json
import re
import warnings
from dataclasses import asdict, dataclass

import numpy as np

from spikesim.dataset.manifest import Manifest, SourceSpec
from spikesim.errors import bad_value
from spikesim.scenes.video import ASPECT_TOLERANCE, AspectWarning, aspect_change
from spikesim.sensor import Sensor

__all__ = ["SequenceTask", "plan_tasks", "derive_seed", "DuplicateClipWarning"]


class DuplicateClipWarning(UserWarning):
    """Clips of a dataset that show the same part of the same video (same start time and
    crop box): their spikes differ by noise only."""


def derive_seed(global_seed: int, sequence_id: str) -> int:
    """64-bit seed of one sequence (BLAKE2b of the global seed and the id)."""
    digest = hashlib.blake2b(f"{global_seed}:{sequence_id}".encode(), digest_size=8).digest()
    return int.from_bytes(digest, "little") >> 1  # non-negative int64


@dataclass(frozen=True)
class SequenceTask:
    """Everything a worker needs to produce one sequence file (JSON-able)."""

    id: str
    split: str
    file: str  # relative to the output folder
    seed: int
    n_readouts: int
    gt_readouts: tuple
    sensor: dict
    scene: dict
    noise_label: str
    compression: str | None
    clean_twin: bool
    manifest: str

    def to_dict(self) -> dict:
        return asdict(self)


def _slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-")


def _draw_noise(manifest: Manifest, rng: np.random.Generator, labels: tuple = ()):
    noises = [n for n in manifest.noises if not labels or n.label in labels]
    weights = np.array([n.weight for n in noises], np.float64)
    spec = noises[int(rng.choice(len(weights), p=weights / weights.sum()))]
    if spec.mode == "none":
        return None, spec.label
    params = {}
    for k, d in spec.params.items():
        v = d.sample(rng)
        params[k] = int(v) if k == "fpn_seed" else v
    return {"type": spec.mode, **params}, spec.label


def _scene_specs(src: SourceSpec, manifest: Manifest):
    """(short name, scene spec without random draws, video) for each sequence of a source."""
    from spikesim.scenes.sources import IMAGES

    h, w = manifest.size
    if src.kind == "procedural":
        motions = src.motions or (None,)
        for k in range(src.count):
            scene = src.scenes[k % len(src.scenes)]
            # animated scenes have their motion built in: the motions apply to pictures
            motion = motions[(k // len(src.scenes)) % len(motions)] if scene in IMAGES else None
            name = f"{scene}-{motion}-{k:04d}" if motion else f"{scene}-{k:04d}"
            spec = {"kind": "procedural", "name": scene, "motion": motion, "size": [h, w]}
            yield name, spec, None
    elif src.kind == "python":
        for k in range(src.count):
            yield f"{_slug(src.factory.split(':')[1])}-{k:04d}", {
                "kind": "python", "factory": src.factory, "index": k, "size": [h, w]}, None
    else:
        layout = {"reds": "reds", "davis": "davis", "video": "auto"}[src.kind]
        for video in src.videos:
            n = src.clips.clips_of(video)
            for k in range(n):
                spec = {"kind": "video", "path": src.path, "layout": layout, "fps": src.fps,
                        "size": [h, w]}
                if src.kind != "video":
                    spec["sequence"] = video.name
                name = _slug(video.name) if n == 1 else f"{_slug(video.name)}-c{k:03d}"
                yield name, spec, (video, k, n)


def _draw_clip(src: SourceSpec, spec: dict, clip: tuple, clip_s: float,
               rng: np.random.Generator) -> None:
    """Start time and crop box of clip ``k`` of ``n`` of a video, from the sequence's rng."""
    video, k, n = clip
    c = src.clips
    latest = video.duration_s - clip_s
    if c.min_gap_s is not None:
        # n equal slots over the allowed range; clip k starts anywhere in its slot that
        # leaves the clip and the gap inside it, so clips never come closer than the gap
        lo, hi = c.start_s.args if c.start_s is not None else (0.0, latest)
        slot = (hi - lo + clip_s + c.min_gap_s) / n
        start = lo + k * slot + rng.uniform(0.0, max(slot - clip_s - c.min_gap_s, 0.0))
    elif c.start_s is not None:
        start = float(c.start_s.sample(rng))
    else:
        start = float(rng.uniform(0.0, latest))
    spec["start_s"] = round(min(max(start, 0.0), latest), 9)
    spec["clip"] = k  # not n: a clip stays the same when more are asked for (without min_gap_s)
    if c.crop_size is not None:
        ch, cw = c.crop_size
        if c.crop_position == "random":
            top = int(rng.integers(0, video.height - ch + 1))
            left = int(rng.integers(0, video.width - cw + 1))
        elif c.crop_position == "center":
            top, left = (video.height - ch) // 2, (video.width - cw) // 2
        else:
            top, left = c.crop_position
        spec["crop"] = [top, left, ch, cw]


def _warn_duplicate_clips(tasks: list[SequenceTask]) -> None:
    """One warning, with the count, when video clips repeat an earlier clip exactly
    (same video, start time, crop box and every other scene setting)."""
    seen: dict[str, str] = {}
    repeats = []
    for t in tasks:
        if t.scene.get("kind") != "video":
            continue
        key = json.dumps({k: v for k, v in t.scene.items() if k != "clip"}, sort_keys=True)
        if key in seen:
            repeats.append((t.id, seen[key]))
        else:
            seen[key] = t.id
    if repeats:
        first, same = repeats[0]
        warnings.warn(
            f"{len(repeats)} video clip(s) repeat another clip exactly (same video, start time "
            f"and crop box; e.g. {first} = {same}): they differ by noise only; draw start_s or "
            "the crop at random, or ask for fewer clips per video",
            DuplicateClipWarning, stacklevel=3)


def plan_tasks(manifest: Manifest) -> list[SequenceTask]:
    """All sequence tasks of a manifest, in a stable order."""
    tasks = []
    for src in manifest.sources:
        for short, spec, clip in _scene_specs(src, manifest):
            seq_id = f"{src.index:02d}-{short}"
            seed = derive_seed(manifest.seed, f"{src.split}/{seq_id}")
            rng = np.random.default_rng(seed)
            if src.speed is not None:
                spec["speed"] = src.speed.sample(rng)
            spec["options"] = {k: d.sample(rng) for k, d in src.options.items()}
            noise, label = _draw_noise(manifest, rng, src.noise)
            if clip is not None:
                _draw_clip(src, spec, clip, manifest.n_readouts / manifest.sensor.clock_hz, rng)
            sensor = manifest.sensor.to_dict()
            sensor["noise"] = noise
            sensor = Sensor.from_dict(sensor).to_dict()  # canonical: every field, as stored
            tasks.append(SequenceTask(
                id=seq_id, split=src.split, file=f"{src.split}/{seq_id}.h5", seed=seed,
                n_readouts=manifest.n_readouts, gt_readouts=tuple(manifest.gt_readouts),
                sensor=sensor, scene=spec, noise_label=label, compression=manifest.compression,
                clean_twin=manifest.clean_twin, manifest=manifest.name,
            ))
    _warn_duplicate_clips(tasks)
    _warn_squashed(manifest)
    _check_unique_ids(tasks)
    return tasks


def _warn_squashed(manifest: Manifest) -> None:
    """One :class:`~spikesim.scenes.video.AspectWarning` per video source whose
    frames (or crop boxes) are resized to ``[dataset].size`` with another aspect."""
    h, w = manifest.size
    for src in manifest.sources:
        if src.clips is None:
            continue
        crop = src.clips.crop_size
        boxes = [crop] if crop is not None else [(v.height, v.width) for v in src.videos]
        off = [box for box in boxes if abs(aspect_change((h, w), box)) > ASPECT_TOLERANCE]
        if off:
            bh, bw = off[0]
            what = (f"its crop.size {bh}x{bw} is" if crop is not None else
                    f"{len(off)} of its {len(boxes)} video(s) (e.g. {bh}x{bw} frames) are")
            warnings.warn(
                f"sources[{src.index}]: {what} resized to the dataset size {h}x{w} with another "
                "aspect ratio, squashing the content; give crop.size the aspect of "
                "[dataset].size to keep its shape", AspectWarning, stacklevel=3)


def _check_unique_ids(tasks: list[SequenceTask]) -> None:
    """Refuse two sequences of one file name: videos whose names differ only in
    case or punctuation (ids are :func:`_slug` of the name, which stays as it is
    so that ids, seeds and resumes of existing datasets do not change)."""
    first: dict[str, SequenceTask] = {}
    for t in tasks:
        other = first.setdefault(t.file, t)
        if other is t:
            continue
        names = [x.scene.get("sequence", x.id) for x in (other, t)]
        src = int(t.id.split("-", 1)[0])
        raise bad_value(f"sources[{src}]", f"videos {names[0]!r} and {names[1]!r}",
                        f"video names that stay distinct as sequence ids: both become "
                        f"{t.id!r} (ids are lower-case, other characters than a-z and 0-9 "
                        "made '-'); rename one of the two")
