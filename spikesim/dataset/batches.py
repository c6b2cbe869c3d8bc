"""Group the tasks of a process-pool build so that clips of one video share their frames.

A pool hands each task to whichever worker is free, so consecutive clips of a
video would alternate between workers and every worker would decode nearly
every frame of every video.  Video clips are therefore sent in batches: the
clips of one video, ordered by start time, cut into runs of a few clips, so a
worker decodes a run's frames once (:mod:`spikesim.scenes.frame_cache`) and
reuses them for the neighbouring clips.  Other tasks stay one per batch.  The
batches only change which process makes a sequence and when; every file is
the same (a sequence's content depends on its task alone).
"""

from __future__ import annotations

__all__ = ["MAX_BATCH", "pool_batches"]

#: Most clips in one batch (a worker that dies loses at most this many results,
#: which are then checked or made again one by one).
MAX_BATCH = 8


def _video_of(task: dict):
    scene = task["scene"]
    if scene.get("kind") != "video":
        return None
    return (scene["path"], scene.get("sequence"))


def pool_batches(tasks: list[dict], workers: int) -> list[list[dict]]:
    """The tasks as batches for ``workers`` processes, in plan order of their videos.

    Runs hold up to ``len(tasks) // (2 * workers)`` clips (at least 1, at most
    :data:`MAX_BATCH`), so every worker still gets about two batches or more
    and none waits long for the last one.
    """
    size = max(1, min(MAX_BATCH, len(tasks) // (2 * max(workers, 1))))
    groups: dict = {}
    batches: list[list[dict]] = []
    for t in tasks:
        video = _video_of(t)
        if video is None:
            batches.append([t])
        else:
            if video not in groups:
                groups[video] = []
                batches.append(groups[video])  # placeholder: this video's clips, split below
            groups[video].append(t)
    out: list[list[dict]] = []
    for b in batches:
        if len(b) == 1 or _video_of(b[0]) is None:
            out.append(b)
            continue
        clips = sorted(b, key=lambda t: (t["scene"].get("start_s", 0.0), t["file"]))
        n = -(-len(clips) // size)  # runs of nearly equal length
        bounds = [round(k * len(clips) / n) for k in range(n + 1)]
        out += [clips[bounds[k]:bounds[k + 1]] for k in range(n)]
    return out
