"""What the vision interface takes from a motion library by default.

A performer stands on a flat floor in front of the camera, and the avatar's world has
nothing else: a clip in which the actor climbs or sits on something (the playground
takes, the blocks of the uneven-terrain walks) would show an avatar floating in the air.
So by default ``mimic perform`` leaves out clips whose feet are all off the floor for
longer than a jump's flight, and says which. Its graph uses relative coordinates (the
performer's actions are matched wherever in the room the actors recorded them), so that
takes recorded in different places reach each other.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from control.graph import longest_off_floor, lowest_foot
from control.motion import Clip

__all__ = [
    "FLOOR_ABOVE",
    "FLOOR_SECONDS",
    "VISION_COORDS",
    "floor_level",
    "on_the_floor",
]

#: the graph's root coordinates for the vision interface
VISION_COORDS = "relative"
#: a clip leaves the floor when every foot point is more than FLOOR_ABOVE metres over
#: the floor for longer than FLOOR_SECONDS (the library's jumps stay under 0.5 s)
FLOOR_ABOVE = 0.25
FLOOR_SECONDS = 0.5


def floor_level(clips: Sequence[Clip]) -> float:
    """The library's floor: the 1st percentile of its lowest foot heights."""
    return _floor([lowest_foot(c.motion) for c in clips])


def _floor(lows: Sequence[np.ndarray]) -> float:
    return float(np.percentile(np.concatenate(lows) if lows else np.zeros(1), 1))


def on_the_floor(
    clips: Sequence[Clip], above: float = FLOOR_ABOVE, seconds: float = FLOOR_SECONDS
) -> tuple[list[Clip], dict[str, float]]:
    """``(kept, left_out)``: the clips that stay on the library's floor, and for each one
    left out its longest stretch (seconds) off it."""
    lows = [lowest_foot(c.motion) for c in clips]  # (forward kinematics once a clip)
    floor = _floor(lows)
    kept: list[Clip] = []
    out: dict[str, float] = {}
    for c, low in zip(clips, lows, strict=True):
        off = longest_off_floor(low, c.motion.fps, floor, above)
        if off > seconds:
            out[c.name] = off
        else:
            kept.append(c)
    return kept, out
