"""Foot contacts from ankle and toe height and speed (Lee et al. §3).

A foot is on the ground when its ankle or its toe is close to the ground and slow. The
ground is estimated from the data: for each kind of point (ankle, toe) the height it has
when resting on the floor is a low percentile of its heights over the frames where it is
slow. With ``floor="local"`` that reference is taken per cell of a horizontal grid, so
feet planted on blocks or a platform count as contacts too (terrain, playground).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ._fk import Pose, forward_kinematics
from ._names import role_point
from ._quat import FloatArray
from ._types import Motion

__all__ = ["FEET", "Contacts", "contact_events", "detect_contacts", "foot_points"]

FEET = ("left", "right")
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True, eq=False)
class Contacts:
    """Contact state of each foot.

    Attributes
    ----------
    states : (F, 2) bool, ``[:, 0]`` left foot, ``[:, 1]`` right foot.
    ankle_rest, toe_rest : metres, the estimated height of the ankle and toe points when
        resting on the floor (the floor itself is a few centimetres below the toe's).
    """

    states: BoolArray
    ankle_rest: float
    toe_rest: float

    def events(self) -> NDArray[np.int64]:
        """``(N, 3)`` int rows ``(frame, foot, +1 touch down | -1 lift off)``."""
        return contact_events(self.states)


def foot_points(motion: Motion, pose: Pose | None = None) -> tuple[FloatArray, FloatArray]:
    """Ankle and toe trajectories, each ``(F, 2, 3)`` (left, right)."""
    pose = forward_kinematics(motion) if pose is None else pose
    out = []
    for part in ("ankle", "toe"):
        cols = []
        for side in FEET:
            kind, k = role_point(motion.skeleton, f"{side}_{part}")
            src = pose.positions if kind == "joint" else pose.end_positions
            cols.append(src[:, k])
        out.append(np.stack(cols, axis=1))
    return out[0], out[1]


def _speed(points: FloatArray, fps: float) -> FloatArray:
    if points.shape[0] < 2:
        return np.zeros(points.shape[:-1])
    return np.linalg.norm(np.gradient(points, axis=0), axis=-1) * fps


def _rest_height(
    points: FloatArray, slow: BoolArray, percentile: float, floor: str, cell: float
) -> FloatArray:
    """Per point (F, 2) the height it has when resting on the ground below it."""
    heights = points[..., 1]
    pool = heights[slow] if slow.any() else heights.ravel()
    global_ref = float(np.percentile(pool, percentile))
    if floor == "global":
        return np.full(heights.shape, global_ref)
    keys = np.floor(points[..., [0, 2]] / cell).astype(np.int64).reshape(-1, 2)
    keys -= keys.min(axis=0)  # one number a cell (x major: the rows' order), sorted fast
    _, inverse = np.unique(keys[:, 0] * (keys[:, 1].max() + 1) + keys[:, 1], return_inverse=True)
    inverse = inverse.reshape(-1)
    ref = np.full(inverse.max() + 1, global_ref)
    slow_at = np.flatnonzero(slow.ravel())
    cells, ref_heights = _group_percentiles(inverse[slow_at], heights.ravel()[slow_at], percentile)
    ref[cells] = ref_heights
    return ref[inverse].reshape(heights.shape)


def _group_percentiles(
    groups: NDArray[np.int64], values: FloatArray, percentile: float
) -> tuple[NDArray[np.int64], FloatArray]:
    """``np.percentile(values[groups == g], percentile)`` for every group ``g`` of at least
    3 values, all at once (a clip's cells number in the hundreds): the groups' labels and
    their percentiles, computed as numpy's default ("linear") method computes them, in
    the same floating-point operations (tested against ``np.percentile``)."""
    order = np.lexsort((values, groups))
    groups, values = groups[order], values[order]
    starts = np.flatnonzero(np.r_[True, groups[1:] != groups[:-1]]) if groups.size else groups
    counts = np.diff(np.r_[starts, groups.size])
    keep = counts >= 3
    starts, counts = starts[keep], counts[keep]
    virtual = (counts - 1).astype(np.float64) * (percentile / 100.0)
    below = np.floor(virtual)
    t = virtual - below
    last = virtual >= counts - 1  # (percentile 100) the largest value
    a = values[np.where(last, starts + counts - 1, starts + below.astype(np.int64))]
    b = values[np.where(last, starts + counts - 1, starts + below.astype(np.int64) + 1)]
    diff = b - a
    out = np.where(t >= 0.5, b - diff * (1 - t), a + diff * t)
    return groups[starts], out


def _clean(states: BoolArray, min_frames: int) -> BoolArray:
    """Drop contact runs and gaps shorter than ``min_frames`` (flicker at thresholds)."""
    out = states.copy()
    if min_frames <= 1:
        return out
    for foot in range(out.shape[1]):
        for value in (False, True):  # fill short gaps, then remove short contacts
            col = out[:, foot]
            change = np.flatnonzero(np.diff(col.astype(np.int8))) + 1
            starts = np.concatenate(([0], change))
            ends = np.concatenate((change, [col.size]))
            for s, e in zip(starts, ends, strict=True):
                inner = s > 0 and e < col.size
                if col[s] == value and inner and e - s < min_frames:
                    col[s:e] = not value
    return out


def detect_contacts(
    motion: Motion,
    pose: Pose | None = None,
    height_tolerance: float = 0.05,
    speed_threshold: float = 0.4,
    min_duration: float = 0.05,
    floor: str = "local",
    cell: float = 0.5,
    percentile: float = 5.0,
) -> Contacts:
    """Contact state per foot and frame.

    Parameters
    ----------
    motion : any clip with recognisable feet (see ``role_point``).
    pose : its forward kinematics, if already computed.
    height_tolerance : metres above the point's resting height that still count as close.
    speed_threshold : metres/second below which a point counts as still.
    min_duration : seconds; shorter contacts and gaps are treated as noise.
    floor : ``"local"`` (default: a reference height per grid cell, so uneven ground,
        blocks and platforms work) or ``"global"`` (one floor for the whole clip).
    cell : metres, the grid cell for ``floor="local"``.
    percentile : of a slow point's heights taken as its resting height.
    """
    if floor not in ("global", "local"):
        raise ValueError("floor must be 'global' or 'local'")
    ankle, toe = foot_points(motion, pose)
    states = np.zeros((motion.n_frames, 2), dtype=bool)
    rests = []
    for pts in (ankle, toe):
        speed = _speed(pts, motion.fps)
        slow = speed < speed_threshold
        rest = _rest_height(pts, slow, percentile, floor, cell)
        rests.append(float(np.median(rest)))
        states |= slow & (pts[..., 1] - rest < height_tolerance)
    min_frames = round(min_duration * motion.fps) + 1
    return Contacts(_clean(states, min_frames), rests[0], rests[1])


def contact_events(states: BoolArray) -> NDArray[np.int64]:
    """``(N, 3)`` rows ``(frame, foot, +1 | -1)``: at ``frame`` the foot touches down (+1,
    in contact at ``frame`` but not at ``frame - 1``) or lifts off (-1). Sorted by frame."""
    states = np.asarray(states, dtype=np.int8)
    d = np.diff(states, axis=0)
    frames, feet = np.nonzero(d)
    rows = np.stack((frames + 1, feet, d[frames, feet]), axis=1).astype(np.int64)
    return rows.reshape(-1, 3)
