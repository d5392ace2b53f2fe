"""How natural motion looks, measured the same way on raw clips and on synthesized motion.

- foot slide: horizontal speed (m/s) of the foot's least-moving point (ankle or toe)
  while the foot is in contact, averaged over contact frames.
- joint-angle jump: per frame, the largest rotation (degrees) of any weighted joint (and
  of the root orientation) from the previous frame.
- jerk: the third time derivative of world joint positions (m/s^3), averaged over
  joints and frames.
- floor: the height of the lowest foot point (ankle or toe of either foot) per frame,
  and the longest stretch a motion spends with both feet off the floor.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from ..motion import FloatArray, Motion, foot_points, forward_kinematics, qconj, qlog, qmul
from ._features import weighted_joints

__all__ = [
    "foot_slide",
    "jerk",
    "joint_jumps",
    "lowest_foot",
    "off_floor_seconds",
    "quality_summary",
    "sole_speed",
]


def sole_speed(motion: Motion, states: NDArray[np.bool_]) -> FloatArray:
    """(F, 2) sole speed (m/s) per frame and foot; NaN where the foot is not in contact
    at both that frame and the previous one (and at frame 0)."""
    ankle, toe = foot_points(motion)
    v_a = np.linalg.norm(np.diff(ankle[..., [0, 2]], axis=0), axis=-1)
    v_t = np.linalg.norm(np.diff(toe[..., [0, 2]], axis=0), axis=-1)
    speed = np.minimum(v_a, v_t) * motion.fps
    both = states[1:] & states[:-1]
    out = np.full(states.shape, np.nan)
    out[1:] = np.where(both, speed, np.nan)
    return out


def foot_slide(motion: Motion, states: NDArray[np.bool_]) -> FloatArray:
    """Sole speed (m/s) per contact frame-and-foot, as a flat array.

    A frame counts when the foot is in contact at it and at the previous frame.
    """
    s = sole_speed(motion, states)
    return s[~np.isnan(s)]


def joint_jumps(motion: Motion) -> FloatArray:
    """(F - 1,) largest per-frame rotation (degrees) over the weighted joints and root."""
    joints = np.concatenate(([0], weighted_joints(motion.skeleton)))
    q = motion.quats[:, joints]
    d = qlog(qmul(qconj(q[:-1]), q[1:]))
    return np.degrees(np.linalg.norm(d, axis=-1).max(axis=1))


def lowest_foot(motion: Motion) -> FloatArray:
    """(F,) height (m, +Y up) of the lowest of the four foot points (ankles, toes)."""
    ankle, toe = foot_points(motion)
    return np.minimum(ankle[..., 1].min(axis=1), toe[..., 1].min(axis=1))


def off_floor_seconds(motion: Motion, floor: float = 0.0, above: float = 0.25) -> float:
    """The longest stretch (seconds) with every foot point more than ``above`` metres
    over ``floor``: a jump's flight is a fraction of a second, climbing or sitting on
    something (that the avatar's world lacks) is longer."""
    return longest_off_floor(lowest_foot(motion), motion.fps, floor, above)


def longest_off_floor(
    low: FloatArray, fps: float, floor: float = 0.0, above: float = 0.25
) -> float:
    """``off_floor_seconds`` of lowest foot heights ``low`` ``(F,)`` (``lowest_foot``) at
    ``fps``."""
    off = np.asarray(low) > floor + above
    if not off.any():
        return 0.0
    edges = np.diff(np.concatenate(([0], off.astype(np.int8), [0])))
    runs = np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)
    return float(runs.max()) / fps


def jerk(motion: Motion) -> FloatArray:
    """(F - 3,) mean over joints of the jerk magnitude (m/s^3)."""
    pos = forward_kinematics(motion).positions
    if pos.shape[0] < 4:
        return np.zeros(0)
    d3 = np.diff(pos, n=3, axis=0) * motion.fps**3
    return np.linalg.norm(d3, axis=-1).mean(axis=1)


def quality_summary(
    motions: Sequence[Motion], states: Sequence[NDArray[np.bool_]]
) -> dict[str, float]:
    """Foot slide, joint jumps and jerk pooled over several motions (e.g. raw clips)."""
    slide = np.concatenate([foot_slide(m, s) for m, s in zip(motions, states, strict=True)])
    jumps = np.concatenate([joint_jumps(m) for m in motions])
    jk = np.concatenate([jerk(m) for m in motions])
    return {
        "foot_slide_mean": float(slide.mean()) if slide.size else 0.0,
        "foot_slide_p95": float(np.percentile(slide, 95)) if slide.size else 0.0,
        "jump_p99_deg": float(np.percentile(jumps, 99)) if jumps.size else 0.0,
        "jump_max_deg": float(jumps.max()) if jumps.size else 0.0,
        "jerk_mean": float(jk.mean()) if jk.size else 0.0,
        "jerk_p99": float(np.percentile(jk, 99)) if jk.size else 0.0,
    }
