"""The tracker's settings, and the sketch on the ground: resampling, a path's deviation
from it, a graph path placed on the ground, and the map that starts the avatar on it."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..graph import rotate_y, segment_maps

__all__ = ["SketchSettings", "ground_path", "path_deviation", "resample_polyline", "start_map"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class SketchSettings:
    """``c`` weighs facing the goal against nearing it (metres; 0 drops the facing term);
    ``step_frames`` frames are committed per search; goals lie ``spacing`` metres apart
    and count as reached within ``reach``; ``body_radius`` metres are kept from
    obstacles; a search expands at most ``max_expansions`` partial paths; dead ends are
    backed out of at most ``max_backtracks`` times; on terrain a foot in the air may dip
    ``foot_clearance`` metres below a block's top (marker noise)."""

    c: float = 0.5
    step_frames: int = 8
    spacing: float = 0.5
    reach: float = 0.5
    body_radius: float = 0.3
    max_expansions: int = 1000
    max_backtracks: int = 40
    #: terrain: how far (metres) a foot in the air may dip below the top of a block
    foot_clearance: float = 0.03
    #: first approach: cluster paths reached within ``lookahead`` seconds are candidates
    lookahead: float = 3.0
    #: first approach: root path and sketch are compared every ``dtw_spacing`` metres
    dtw_spacing: float = 0.1
    #: first approach: at most this many actions (an even spread) are compared per choice
    max_actions: int = 128


def resample_polyline(points: FloatArray, spacing: float) -> FloatArray:
    """Points ``spacing`` apart along a polyline ``(n, 2)``, the last point included."""
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    s = np.concatenate(([0.0], np.cumsum(seg)))
    n = max(1, math.ceil(s[-1] / spacing))
    at = np.linspace(0.0, s[-1], n + 1)[1:]
    return np.stack([np.interp(at, s, points[:, k]) for k in range(2)], axis=1)


def path_deviation(xz: FloatArray, sketch: FloatArray) -> FloatArray:
    """Distance ``(n,)`` of each ground point to the nearest point of the sketch."""
    a = sketch[:-1]
    ab = np.diff(sketch, axis=0)
    ap = xz[:, None, :] - a[None]
    t = np.clip((ap * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-12), 0.0, 1.0)
    return np.asarray(np.linalg.norm(ap - t[..., None] * ab, axis=-1).min(axis=1))


def ground_path(
    root: FloatArray,
    heading: FloatArray,
    align: FloatArray,
    frames: IntArray,
    edges: IntArray,
    yaw: float,
    trans: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Root on the ground ``(T, 2)`` and facing angles ``(T,)`` of a graph path
    (``edges[i]`` leads into ``frames[i + 1]``, -1 for playback) placed by the map
    ``p -> R_y(yaw) p + trans``."""
    edges = np.asarray(edges)
    jumps = np.flatnonzero(edges >= 0)  # frames[jumps + 1] begin new segments
    yaws, moves = segment_maps(align[edges[jumps]], yaw, trans)
    seg = np.searchsorted(jumps + 1, np.arange(len(frames)), side="right")
    out = np.empty((len(frames), 2))
    facing = np.empty(len(frames))
    for t, f in enumerate(frames):
        p = rotate_y(root[f], float(yaws[seg[t]])) + moves[seg[t]]
        out[t] = (p[0], p[2])
        facing[t] = yaws[seg[t]] + heading[f]
    return out, facing


def start_map(
    root: FloatArray, heading: FloatArray, frame: int, at: FloatArray, toward: FloatArray
) -> tuple[float, FloatArray]:
    """The map ``(yaw, trans)`` that puts ``frame``'s root on the ground point ``at``,
    facing ``toward``."""
    d = np.asarray(toward, dtype=np.float64) - at
    yaw = math.atan2(d[0], d[1]) - float(heading[frame])  # facing (sin a, cos a)
    r = rotate_y(root[frame], yaw)
    return yaw, np.array([at[0] - r[0], 0.0, at[1] - r[2]])
