"""The record of one sequence of a build: what happened to it, its size and its timing.

One definition of the key set, written into ``build_summary.json`` and the
index: :class:`TaskRecord` makes the record of a sequence built, skipped
(valid from an earlier run) or failed, whichever process makes it.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

__all__ = ["TaskRecord", "STAGES"]

#: Timed stages of a sequence (seconds): scene (decoding, cropping), optical flow,
#: warping (interpolated key frames), kernel (simulation), HDF5 writing, and the total.
STAGES = ("scene", "flow", "warp", "kernel", "write", "total")


@dataclass
class TaskRecord:
    """The outcome of task ``id`` (file ``file`` of split ``split``).

    ``status`` is ``"done"``, ``"skipped"`` or ``"failed"`` (``error`` then says
    why); ``bytes`` is the file size, ``px_readouts`` the pixel-readouts
    simulated, ``seconds`` the time per stage (:data:`STAGES`),
    ``frames_decoded`` the video frames this process decoded for it (those
    another clip had decoded already are not counted), ``clip`` the clip
    record of a video sequence.
    """

    id: str
    file: str
    split: str
    status: str = "done"
    bytes: int = 0
    error: str | None = None
    px_readouts: int = 0
    seconds: dict = field(default_factory=lambda: dict.fromkeys(STAGES, 0.0))
    frames_decoded: int = 0
    clip: dict | None = None

    @classmethod
    def of(cls, task: dict, **fields) -> TaskRecord:
        """A record for ``task`` (a ``SequenceTask.to_dict()``) with ``fields`` set."""
        return cls(id=task["id"], file=task["file"], split=task["split"], **fields)

    def to_dict(self) -> dict:
        """The JSON form (no ``clip`` key for sequences that are not video clips)."""
        out = asdict(self)
        if out["clip"] is None:
            del out["clip"]
        return out
