"""Block terrain for the sketch tracker: the feet as the library was captured on its
blocks, whether a placed frame fits the environment's blocks, the start on the blocks'
grid, and how a synthesized motion stands on them."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..graph import CapturedTerrain, MotionGraph, Synthesis, captured_terrain, foot_track, rotate_y
from ..motion import Clip, foot_points
from ._files import TerrainMap
from ._ground import SketchSettings

__all__ = ["BlockFit"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


class BlockFit:
    """The library's feet on the environment's blocks (``terrain``); ``captured`` is the
    terrain the library was captured on (default: ``captured_terrain`` of the graph's
    clips)."""

    def __init__(
        self,
        graph: MotionGraph,
        clips: Sequence[Clip],
        terrain: TerrainMap,
        settings: SketchSettings,
        captured: CapturedTerrain | None = None,
    ) -> None:
        g = graph
        self.terrain = terrain
        self.settings = settings
        if g.options.coords != "terrain":
            raise ValueError(
                f"a terrain environment needs a terrain graph (coords 'terrain'), "
                f"not {g.options.coords!r}"
            )
        if abs(g.options.block - terrain.block) > 1e-6:
            raise ValueError(
                f"the environment's blocks are {terrain.block} m but the graph's are "
                f"{g.options.block} m"
            )
        chosen = g.clips_of(clips)
        feet = foot_track(chosen)
        if captured is None:
            captured = captured_terrain(chosen, terrain.block, feet=feet)
        self.captured = captured
        self.rise = g.options.rise if g.options.rise > 0 else captured.rise
        self.toe = feet.toe
        self.ankle = feet.ankle
        self.support = feet.support
        self.states = feet.states
        self.level = captured.level_of(feet.toe[..., 1])

    def fits(self, f: int, yaw: float, trans: FloatArray) -> bool:
        """Frame ``f`` placed by ``(yaw, trans)`` fits the blocks: each planted foot on a
        block of the level it was captured on (plus the avatar's lift), and each foot in
        the air above the block under it."""
        terrain, cap = self.terrain, self.captured
        c, sn = math.cos(yaw), math.sin(yaw)
        rise = self.rise
        lift = round(float(trans[1]) / rise)
        for foot in (0, 1):
            if self.states[f, foot]:
                sx, sz = self.support[f, foot]
                level = terrain.level_at_point(
                    c * sx + sn * sz + trans[0], -sn * sx + c * sz + trans[2]
                )
                if level != self.level[f, foot] + lift:
                    return False
                continue
            for pts, floor in ((self.toe, cap.toe_floor), (self.ankle, cap.ankle_floor)):
                px, py, pz = pts[f, foot]
                level = terrain.level_at_point(
                    c * px + sn * pz + trans[0], -sn * px + c * pz + trans[2]
                )
                if py + trans[1] < floor + level * rise - self.settings.foot_clearance:
                    return False
        return True

    def start(
        self,
        start: int | None,
        sketch: FloatArray,
        root: FloatArray,
        heading: FloatArray,
        ranking: Callable[[], IntArray],
    ) -> tuple[int, tuple[float, FloatArray]]:
        """The first start frame (``start``, else by ``ranking()``) with both feet
        planted that fits the blocks when turned by the quarter turn nearest the sketch's
        direction and put on the grid (block centres on block centres) as near the
        sketch's first point as the blocks allow, lifted to the level under it."""
        terrain, cap = self.terrain, self.captured
        b = terrain.block
        at, toward = sketch[0], sketch[1]
        d = toward - at
        want = math.atan2(d[0], d[1])
        centre = np.array(terrain.first_centre)
        origin = np.array([cap.origin[0], 0.0, cap.origin[1]])
        candidates = [start] if start is not None else ranking()[:400]
        for f in candidates:
            f = int(f)
            if start is None and not self.states[f].all():
                continue
            yaw = 0.5 * math.pi * round((want - float(heading[f])) / (0.5 * math.pi))
            o = rotate_y(origin, yaw)
            r = rotate_y(root[f], yaw)
            k = np.round((at - (r[[0, 2]] - o[[0, 2]] + centre)) / b)
            tries = sorted(
                (k + np.array([i, j]) for i in (-1, 0, 1) for j in (-1, 0, 1)),
                key=lambda kk: float(np.linalg.norm(centre + kk * b - o[[0, 2]] + r[[0, 2]] - at)),
            )
            for kk in tries:
                xz = centre + kk * b - o[[0, 2]]
                trans = np.array([xz[0], 0.0, xz[1]])
                planted = np.flatnonzero(self.states[f])
                if planted.size:
                    foot = int(planted[0])
                    sx, sz = self.support[f, foot]
                    p = rotate_y(np.array([sx, 0.0, sz]), yaw) + trans
                    level = terrain.level_at_point(float(p[0]), float(p[2]))
                    trans[1] = (level - int(self.level[f, foot])) * self.rise
                if self.fits(f, yaw, trans):
                    return f, (yaw, trans)
        raise ValueError(
            "no start frame fits the blocks at the sketch's first point "
            f"({at[0]:.2f}, {at[1]:.2f}); move the start onto a block"
        )

    def report(self, syn: Synthesis) -> dict[str, Any]:
        """How the synthesized, placed motion ``syn`` stands on the blocks: at planted
        frames, the toe's height above the top of the block under the foot (error:
        mean |e|, 95th percentile, max |e|; and the planted frames off by more than half
        a block), and the deepest a foot in the air goes below a block's top."""
        terrain, cap = self.terrain, self.captured
        ankle, toe = foot_points(syn.motion)
        mid = 0.5 * (ankle[..., [0, 2]] + toe[..., [0, 2]])
        top = terrain.level_at(mid.reshape(-1, 2)).reshape(mid.shape[:2]) * self.rise
        err = toe[..., 1] - cap.toe_floor - top
        planted = err[syn.states]
        tops = terrain.level_at(toe[..., [0, 2]].reshape(-1, 2)).reshape(toe.shape[:2])
        swing = (toe[..., 1] - cap.toe_floor - tops * self.rise)[~syn.states]
        a = np.abs(planted)
        return {
            "planted_frames": int(a.size),
            "foot_height_error_mean_m": round(float(a.mean()), 4) if a.size else None,
            "foot_height_error_p95_m": round(float(np.percentile(a, 95)), 4) if a.size else None,
            "foot_height_error_max_m": round(float(a.max()), 4) if a.size else None,
            "planted_off_block": int((a > 0.5 * self.rise).sum()),
            "swing_deepest_below_top_m": round(float(-min(0.0, swing.min())), 4)
            if swing.size
            else 0.0,
            "rise_m": round(self.rise, 4),
        }
