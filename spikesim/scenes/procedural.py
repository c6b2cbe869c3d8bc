"""Procedural scenes by name: ``procedural(name, motion=..., size=..., speed=...)``.

Every scene here returns *exact* linear radiance for any time (see
:mod:`spikesim.scenes.analytic`), so it is the ground truth against which
interpolated video is scored.  :func:`list_scenes` names them with one line of
description each; :func:`list_motions` names the camera paths for pictures.
"""

from __future__ import annotations

from spikesim.errors import bad_value
from spikesim.scenes.analytic import ProceduralScene
from spikesim.scenes.fields import ColorChecker, Flat, Flicker, Ramp
from spikesim.scenes.layered import RotatingDisk, Sprites
from spikesim.scenes.paths import MOTIONS
from spikesim.scenes.picture import MovingPicture
from spikesim.scenes.sources import IMAGES

__all__ = ["procedural", "list_scenes", "list_motions", "DEFAULT_SPEED_PX_S", "DEFAULT_SIZE"]

#: Default largest content speed, pixels per second (1 px every 2 ms; 40 readouts at 20 kHz).
DEFAULT_SPEED_PX_S = 500.0
#: Default frame size (H, W) in pixels.
DEFAULT_SIZE = (256, 256)

_SPECIAL: dict[str, tuple[str, type[ProceduralScene], bool]] = {
    # name: (description, class, takes speed)
    "sprites": ("textured disks bouncing over a picture, occluding each other and it", Sprites,
                True),
    "fan": ("a four-blade fan spinning over a picture (the classic high-speed demo)",
            RotatingDisk, True),
    "disk": ("a textured disk spinning over a picture", RotatingDisk, True),
    "flat": ("uniform radiance `level` (noise and transfer-curve studies)", Flat, False),
    "ramp": ("horizontal intensity ramp `low`..`high`, linear or `log` (dynamic range)", Ramp,
             False),
    "flicker": ("mains-powered lamp: brightness pulses at 2x `mains_hz` (50 or 60 Hz)", Flicker,
                False),
    "colorchecker": ("X-Rite ColorChecker 24 patches in linear sRGB (colour-science data)",
                     ColorChecker, False),
}


def list_scenes() -> dict[str, str]:
    """Scene name → one-line description (pictures take a ``motion``, see :func:`list_motions`)."""
    out = {name: f"picture: {desc}; motion = {'|'.join(MOTIONS)}"
           for name, (_, desc) in IMAGES.items()}
    out.update({name: desc for name, (desc, _, _) in _SPECIAL.items()})
    return out


def list_motions() -> dict[str, str]:
    """Camera-motion name → one-line description (for picture scenes)."""
    return dict(MOTIONS)


def procedural(
    name: str,
    motion: str | None = None,
    size: tuple[int, int] = DEFAULT_SIZE,
    speed: float | None = None,
    **options,
) -> ProceduralScene:
    """Build the procedural scene ``name``.

    Parameters
    ----------
    name : str
        A key of :func:`list_scenes`.
    motion : str, optional
        For pictures: a key of :func:`list_motions` (default ``"pan"``).  Other
        scenes carry their own motion and accept only ``None``.
    size : (H, W)
        Frame size in pixels (default 256 × 256).
    speed : float, optional
        Largest content speed, pixels per second (default
        :data:`DEFAULT_SPEED_PX_S`); for ``fan``/``disk`` the rim speed.  Not
        accepted by still and flicker scenes.
    **options
        Scene-specific keywords (e.g. ``direction_deg``, ``background``,
        ``level``, ``mains_hz``) and the common ``max_px`` (largest
        displacement between key frames, pixels; default 1) and ``exposure``.

    Examples
    --------
    >>> scene = procedural("astronaut", motion="pan", size=(64, 64), speed=100.0)
    >>> scene.radiance(0.01).shape
    (64, 64, 3)
    """
    if not isinstance(name, str) or (name not in IMAGES and name not in _SPECIAL):
        raise bad_value("name", name, f"one of {sorted(list_scenes())}")
    if name in IMAGES:
        motion = "pan" if motion is None else motion
        if motion not in MOTIONS:
            raise bad_value("motion", motion, f"one of {sorted(MOTIONS)}")
        if motion == "static" and speed is not None:
            raise bad_value("speed", speed, "None for motion='static'")
        speed = DEFAULT_SPEED_PX_S if speed is None else speed
        _check_options(MovingPicture, options, name)
        return MovingPicture(name, motion, size, speed, **options)
    desc, cls, takes_speed = _SPECIAL[name]
    if motion is not None:
        raise bad_value("motion", motion, f"None for scene {name!r} (its motion is built in)")
    _check_options(cls, options, name)
    if takes_speed:
        options["speed"] = DEFAULT_SPEED_PX_S if speed is None else speed
    elif speed is not None:
        raise bad_value("speed", speed, f"None for scene {name!r} (nothing moves)")
    if name in ("fan", "disk"):
        options["pattern"] = name
    return cls(size, **options)


def _check_options(cls, options: dict, name: str) -> None:
    """Refuse the user's keywords the scene's class does not take, naming those it does
    (``procedural``'s own arguments are not among them)."""
    import inspect

    params = inspect.signature(cls.__init__).parameters
    if any(p.kind is p.VAR_KEYWORD for p in params.values()):
        return
    fixed = {"self", "size", "image", "motion", "speed", "pattern"}  # set by procedural
    taken = [k for k, p in params.items() if k not in fixed
             and p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]
    unknown = sorted(set(options) - (set(params) - fixed))
    if unknown:
        raise bad_value("options", unknown, f"keywords scene {name!r} takes: "
                        f"{', '.join(taken) or 'none'}")
