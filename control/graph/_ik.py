"""Analytic two-bone leg IK, vectorised over frames.

Glossary as in ``control.motion._quat``. The hip joint rotates the thigh about the hip,
the knee joint rotates the shin about the knee; the ankle keeps its world orientation so
that a planted foot does not tilt.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from ..motion import FloatArray, Skeleton, find_role, qconj, qmul, qrot, slerp

IntArray = NDArray[np.int64]

__all__ = [
    "SOFT_REACH",
    "SWING_LIMIT",
    "TURN_RATE",
    "knee_hinge",
    "leg_chain",
    "limit_turns",
    "solve_leg",
    "two_bone_ik",
]


def _unit(v: FloatArray) -> FloatArray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def _axis_angle_q(axis: FloatArray, angle: FloatArray) -> FloatArray:
    half = 0.5 * angle
    return np.concatenate((np.cos(half)[..., None], axis * np.sin(half)[..., None]), axis=-1)


def _arc_q(v1: FloatArray, v2: FloatArray) -> FloatArray:
    """Shortest rotation taking the direction of ``v1`` to that of ``v2``."""
    a, b = _unit(v1), _unit(v2)
    w = 1.0 + np.sum(a * b, axis=-1, keepdims=True)
    q = np.concatenate((w, np.cross(a, b)), axis=-1)
    return q / np.maximum(np.linalg.norm(q, axis=-1, keepdims=True), 1e-12)


#: the share of a leg's length up to which ``two_bone_ik`` reaches a target exactly
SOFT_REACH = 0.97

#: degrees: ``solve_leg`` applies its correction in full where the hip must swing the leg
#: by at most the first, none from the second, in proportion between. A folded leg
#: (a deep squat) can need a swing near a half turn to reach a target a few centimetres
#: away, and there the swing's axis flips from one frame to the next: a jump blended
#: into a squat could turn a thigh 170 degrees in one frame; the foot slides there
#: instead.
SWING_LIMIT = (40.0, 80.0)

#: degrees a second: how fast ``solve_leg``'s correction of the hip and of the knee may
#: turn from one frame to the next (with its frames given). A nearly straight knee must
#: bend tens of degrees to bring the ankle a few centimetres nearer the hip, so a blend
#: that carries the pelvis 5 cm a frame away from a planted foot would bend the knee
#: 50-88 degrees in one frame (the library's 99th percentile is 31); the foot slides
#: there instead.
TURN_RATE = 300.0


@numba.njit(cache=True)
def turn_toward(
    pw: float, px: float, py: float, pz: float, w: float, x: float, y: float, z: float, step: float
) -> tuple[float, float, float, float]:  # pragma: no cover
    """The rotation ``(w, x, y, z)``, or where it is more than ``step`` radians from
    ``(pw, px, py, pz)``, the one ``step`` of the way to it along the shorter arc (numba;
    the sign is the hemisphere of ``p``)."""
    dot = pw * w + px * x + py * y + pz * z
    if dot < 0.0:
        w, x, y, z, dot = -w, -x, -y, -z, -dot
    theta = math.acos(min(dot, 1.0))  # half the turn
    if 2.0 * theta > step:
        t = step / (2.0 * theta)
        a = math.sin((1.0 - t) * theta) / math.sin(theta)
        b = math.sin(t * theta) / math.sin(theta)
        w, x, y, z = a * pw + b * w, a * px + b * x, a * py + b * y, a * pz + b * z
        size = math.sqrt(w * w + x * x + y * y + z * z)
        w, x, y, z = w / size, x / size, y / size, z / size
    return w, x, y, z


@numba.njit(cache=True)
def _limit_turns(q: FloatArray, frames: IntArray, step: float) -> FloatArray:  # pragma: no cover
    out = q.copy()
    n = out.shape[0]
    for k in range(2 * n):  # forwards, then backwards
        i = k if k < n else 2 * n - 1 - k
        near = i - 1 if k < n else i + 1  # the frame before (after) it
        if near < 0 or near >= n or abs(frames[near] - frames[i]) != 1:
            pw, px, py, pz = 1.0, 0.0, 0.0, 0.0  # a run of frames starts (ends) uncorrected
        else:
            pw, px, py, pz = out[near, 0], out[near, 1], out[near, 2], out[near, 3]
        w, x, y, z = turn_toward(pw, px, py, pz, out[i, 0], out[i, 1], out[i, 2], out[i, 3], step)
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = w, x, y, z
    return out


def limit_turns(q: FloatArray, frames: IntArray, step: float) -> FloatArray:
    """Rotations ``q`` ``(N, 4)`` of ``frames`` ``(N,)`` (increasing), each turned from
    the one of the frame before, and from the one of the frame after, by at most ``step``
    degrees: where it would turn more, it goes ``step`` of the way (along the shorter arc;
    a pass forwards, then one backwards). A frame missing from ``frames`` has the
    identity (no correction there): a run of frames starts and ends within ``step`` of
    it."""
    q = np.ascontiguousarray(q, dtype=np.float64)
    frames = np.ascontiguousarray(frames, dtype=np.int64)
    if q.ndim != 2 or q.shape[1] != 4 or frames.shape != q.shape[:1]:
        raise ValueError(f"q must be (N, 4) with frames (N,), not {q.shape} and {frames.shape}")
    return _limit_turns(q, frames, math.radians(step))


def two_bone_ik(
    hip: FloatArray, knee: FloatArray, ankle: FloatArray, target: FloatArray, axis: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """World rotations that bring the ankle onto ``target``.

    Parameters
    ----------
    hip, knee, ankle, target : (F, 3) world positions.
    axis : (F, 3) the knee's hinge axis in world space, oriented so that a positive
        rotation about it bends the knee (see ``knee_hinge``).

    Returns
    -------
    d_knee : (F, 4) rotation about the knee, applied to the shin first.
    d_hip : (F, 4) rotation about the hip, applied to the whole leg after.
    Targets beyond ``SOFT_REACH`` of the leg's length are approached softly: the knee never
    quite straightens.
    """
    u = hip - knee
    w = ankle - knee
    l1 = np.linalg.norm(u, axis=-1)
    l2 = np.linalg.norm(w, axis=-1)
    reach = np.linalg.norm(target - hip, axis=-1)
    # soft reach: past ``SOFT_REACH`` of the leg's length the ankle comes ever closer to
    # full extension without reaching it (the exact knee angle's slope is infinite
    # there: the last millimetres of a target moving out of reach snapped the knee
    # straight)
    full = l1 + l2
    soft = SOFT_REACH * full
    over = np.maximum(reach - soft, 0.0)
    eased = soft + (full - soft) * (1.0 - np.exp(-over / np.maximum(full - soft, 1e-12)))
    d = np.clip(np.where(reach > soft, eased, reach), np.abs(l1 - l2) + 1e-6, full * (1.0 - 1e-6))
    new = np.arccos(np.clip((l1**2 + l2**2 - d**2) / np.maximum(2.0 * l1 * l2, 1e-12), -1.0, 1.0))
    # The bend axis: the knee's current bend plane oriented like the hinge; near straight,
    # where that plane is noise, the hinge itself. The knee angle is measured about that
    # oriented axis, so a slightly hyperextended knee reads as just over 180 degrees and
    # still bends the right way.
    hint = _unit(axis)
    bend = np.cross(u, w)
    straight = np.linalg.norm(bend, axis=-1) < 0.05 * l1 * l2
    n = np.where(straight[:, None], hint, bend)
    n = _unit(n * np.where(np.sum(n * hint, axis=-1) < 0.0, -1.0, 1.0)[:, None])
    cur = np.mod(np.arctan2(np.sum(bend * n, axis=-1), np.sum(u * w, axis=-1)), 2.0 * np.pi)
    d_knee = _axis_angle_q(n, new - cur)
    ankle2 = knee + qrot(d_knee, w)
    d_hip = _arc_q(ankle2 - hip, target - hip)
    return d_knee, d_hip


def knee_hinge(
    positions: FloatArray, orientations: FloatArray, chain: tuple[int, int, int]
) -> FloatArray:
    """The knee's bend axis ``(3,)`` in the thigh's own frame, from the frames where the
    knee is clearly bent (a hinge is fixed in the thigh's frame, whatever the pose)."""
    hip, knee, ankle = chain
    u = positions[:, hip] - positions[:, knee]
    w = positions[:, ankle] - positions[:, knee]
    bend = np.cross(u, w)
    size = np.linalg.norm(bend, axis=-1)
    bent = size > 0.3 * np.linalg.norm(u, axis=-1) * np.linalg.norm(w, axis=-1)
    if not bent.any():
        bent = size > 1e-9
    if not bent.any():
        return np.array([1.0, 0.0, 0.0])
    local = qrot(qconj(orientations[bent, hip]), bend[bent] / size[bent, None])
    return _unit(np.median(local, axis=0))


def leg_chain(skeleton: Skeleton, side: str) -> tuple[int, int, int]:
    """``(hip, knee, ankle)`` joint indices of ``side`` (``"left"``/``"right"``), checked to
    be a parent-child chain."""
    idx = []
    for part in ("hip", "knee", "ankle"):
        j = find_role(skeleton, f"{side}_{part}")
        if j is None:
            raise KeyError(f"skeleton has no {side} {part}")
        idx.append(j)
    hip, knee, ankle = idx
    if skeleton.parents[knee] != hip or skeleton.parents[ankle] != knee:
        raise ValueError(f"{side} hip, knee and ankle are not a parent-child chain")
    return hip, knee, ankle


def solve_leg(
    skeleton: Skeleton,
    positions: FloatArray,
    orientations: FloatArray,
    chain: tuple[int, int, int],
    target: FloatArray,
    hinge: FloatArray,
    frames: IntArray | None = None,
    step: float = 0.0,
) -> FloatArray:
    """New local rotations ``(F, 3, 4)`` of ``chain`` so the ankle reaches ``target``.

    ``positions`` / ``orientations`` are the frames' FK (``(F, J, 3)``, ``(F, J, 4)``).
    ``hinge`` is the knee's axis in the thigh's frame (``knee_hinge``). The ankle keeps its
    world orientation. A frame whose correction needs the hip to swing the leg by more
    than ``SWING_LIMIT``'s first angle gets only part of it (none past the second). With
    the rows' ``frames`` and a ``step`` (degrees), the hip's and the knee's corrections
    turn by at most ``step`` a frame (``limit_turns``; see ``TURN_RATE``).
    """
    hip, knee, ankle = chain
    axis = qrot(orientations[:, hip], np.broadcast_to(hinge, (target.shape[0], 3)))
    d_knee, d_hip = two_bone_ik(
        positions[:, hip], positions[:, knee], positions[:, ankle], target, axis
    )
    swing = np.degrees(2.0 * np.arccos(np.clip(np.abs(d_hip[:, 0]), 0.0, 1.0)))
    lo, hi = SWING_LIMIT
    weight = np.clip((hi - swing) / (hi - lo), 0.0, 1.0)
    if (weight < 1.0).any():  # (see ``SWING_LIMIT``)
        ident = np.broadcast_to(np.array([1.0, 0.0, 0.0, 0.0]), d_hip.shape)
        d_hip = slerp(ident, d_hip, weight)
        d_knee = slerp(ident, d_knee, weight)
    if frames is not None and step > 0:
        d_hip, d_knee = limit_turns(d_hip, frames, step), limit_turns(d_knee, frames, step)
    parent = skeleton.parents[hip]
    q_parent = orientations[:, parent]
    hip_w = qmul(d_hip, orientations[:, hip])
    knee_w = qmul(d_hip, qmul(d_knee, orientations[:, knee]))
    out = np.empty((target.shape[0], 3, 4))
    out[:, 0] = qmul(qconj(q_parent), hip_w)
    out[:, 1] = qmul(qconj(hip_w), knee_w)
    out[:, 2] = qmul(qconj(knee_w), orientations[:, ankle])
    return out
