"""Light sources for the simulator: still images, procedural scenes, and video."""

from spikesim.scenes.analytic import ProceduralScene
from spikesim.scenes.base import Scene, uniform_key_times
from spikesim.scenes.keyframes import Keyframes
from spikesim.scenes.procedural import list_motions, list_scenes, procedural
from spikesim.scenes.static import Static, validate_radiance
from spikesim.scenes.video import VideoScene, as_video, video

__all__ = [
    "Scene",
    "Static",
    "Keyframes",
    "uniform_key_times",
    "validate_radiance",
    "ProceduralScene",
    "procedural",
    "list_scenes",
    "list_motions",
    "video",
    "as_video",
    "VideoScene",
]
