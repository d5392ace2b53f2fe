"""Per-frame features for the frame distance of Lee et al. eqs. 2-3.

Glossary as in ``control.motion._quat``; in addition ``a``, ``b`` are the two frames of a
pair, ``k`` a weighted joint, ``n`` the number of frames in the graph.

The distance compares frame ``a`` with frame ``b``:

``D = |p_a - p_b|^2 + sum_k w_k |log(q_bk^-1 q_ak)|^2 + nu |v_a - v_b|^2``

where ``|log(q)|`` is half the rotation angle (the paper's convention), ``p`` the root
position term, ``q`` the root orientation and the weighted joints' local rotations, and
``v`` the velocities: angular velocities (rad/s) of the weighted joints and the root's
linear (m/s) and angular (rad/s) velocity. How the root enters depends on the coordinates:

- ``fixed``: world position and orientation (transitions only between motions that are
  near each other in the capture space).
- ``relative``: root height only; orientation with the heading (rotation about Y)
  removed; root velocities expressed in the heading frame. Horizontal translation and
  rotation about the vertical axis are ignored.
- ``terrain``: world orientation and horizontal position, but frame ``b`` may be turned
  by a multiple of 90 degrees and shifted by whole blocks; vertical translation is
  ignored (Lee et al. §4.1.2, uneven terrain).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..motion import Clip, FloatArray, Skeleton, find_role, qconj, qlog, qmul

__all__ = [
    "COORDS",
    "FrameFeatures",
    "frame_features",
    "leg_length",
    "q_embed",
    "root_scales",
    "weighted_joints",
    "yaw_of",
    "yaw_q",
]

COORDS = ("fixed", "relative", "terrain")

_LIMB_ROLES = (
    "left_hip",
    "right_hip",
    "left_knee",
    "right_knee",
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
)


def weighted_joints(skeleton: Skeleton) -> NDArray[np.int64]:
    """Non-root joints of weight 1: hips, knees, shoulders, elbows and the spine.

    The spine is every joint on the chain from the root up to the chest (CMU:
    ``lowerback``, ``upperback``, ``thorax``). The root (pelvis) is weighted too but is
    handled separately because its treatment depends on the coordinates. Neck, head,
    clavicles, wrists, hands, ankles and toes have weight 0.

    Raises ``KeyError`` naming the role when the skeleton lacks a limb joint.
    """
    out: list[int] = []
    for role in _LIMB_ROLES:
        j = find_role(skeleton, role)
        if j is None:
            raise KeyError(f"skeleton has no joint for role {role!r}: {', '.join(skeleton.names)}")
        out.append(j)
    top = find_role(skeleton, "chest")
    if top is None:
        top = find_role(skeleton, "spine")
    spine: list[int] = []
    while top is not None and top > 0:
        spine.append(top)
        top = int(skeleton.parents[top])
    return np.array(sorted(set(out) | set(spine)), dtype=np.int64)


def leg_length(skeleton: Skeleton) -> float:
    """Thigh plus shin length (metres), averaged over both legs."""
    total = []
    for side in ("left", "right"):
        for part in ("knee", "ankle"):
            j = find_role(skeleton, f"{side}_{part}")
            if j is None:
                raise KeyError(f"skeleton has no joint for role {side}_{part!r}")
            total.append(float(np.linalg.norm(skeleton.offsets[j])))
    return sum(total) / 2.0


def root_scales(clips: Sequence[Clip]) -> FloatArray:
    """(C,) factor per clip that retargets its root translation to the first clip's body.

    Clips of other subjects have other leg lengths; played on one skeleton, their root
    would travel too far or too little for the feet (they would slide). Scaling the root
    translation by the ratio of leg lengths is the simplest retargeting that fixes this.
    """
    ref = leg_length(clips[0].motion.skeleton)
    return np.array([ref / leg_length(c.motion.skeleton) for c in clips])


def yaw_of(q: FloatArray) -> FloatArray:
    """Heading angle (rotation about +Y, radians) of orientations ``(..., 4) -> (...)``.

    The twist of the swing-twist decomposition about Y: ``q = yaw_q(yaw) * tilt``.
    """
    return 2.0 * np.arctan2(q[..., 2], q[..., 0])


def yaw_q(angle: FloatArray | float) -> FloatArray:
    """Quaternions ``(..., 4)`` of rotations by ``angle`` about +Y."""
    a = np.asarray(angle, dtype=np.float64) * 0.5
    z = np.zeros_like(a)
    return np.stack((np.cos(a), z, np.sin(a), z), axis=-1)


def rotate_y(v: FloatArray, angle: FloatArray | float) -> FloatArray:
    """Rotate vectors ``(..., 3)`` by ``angle`` (broadcast) about +Y."""
    one = isinstance(v, np.ndarray) and v.shape == (3,) and v.dtype == np.float64
    if one and isinstance(angle, float | int):  # one point: the sketch planners place millions
        ca, sa = math.cos(angle), math.sin(angle)
        px, py, pz = v.tolist()
        return np.array((ca * px + sa * pz, py, -sa * px + ca * pz))
    c, s = np.cos(angle), np.sin(angle)
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    return np.stack((c * x + s * z, y, -s * x + c * z), axis=-1)


def q_embed(q: FloatArray) -> FloatArray:
    """10-D embedding ``e(q)`` with ``e(q) . e(p) == (q . p)^2``; ``(..., 4) -> (..., 10)``.

    The upper triangle of ``q q^T`` with off-diagonal terms scaled by sqrt(2). It lets a
    matrix product compute ``1 - (q . p)^2 = sin^2(half angle)`` for all pairs at once, a
    lower bound of the squared geodesic ``|log(p^-1 q)|^2``.
    """
    iu, ju = np.triu_indices(4)
    scale = np.where(iu == ju, 1.0, np.sqrt(2.0))
    return q[..., iu] * q[..., ju] * scale


@dataclass(frozen=True, eq=False)
class FrameFeatures:
    """Everything the distance needs, for ``n`` frames of several clips end to end.

    Attributes
    ----------
    coords : ``"fixed"``, ``"relative"`` or ``"terrain"``.
    clip_start : (C + 1,) first frame of each clip, then ``n``.
    joint_q : (n, K, 4) local rotations of the weighted non-root joints.
    root_q : (n, 4) root orientation term (world, or tilt only for ``relative``).
    root_p : (n, 3) root position term (world; ``(0, y, 0)`` for ``relative``).
    vel : (n, 3K + 6) angular velocities of the weighted joints, then the root's linear
        and angular velocity (world; heading frame for ``relative``).
    world_p : (n, 3) world root position. ``yaw`` : (n,) world root heading.
    states : (n, 2) bool foot contacts (left, right).
    """

    coords: str
    clip_start: NDArray[np.int64]
    joint_q: FloatArray
    root_q: FloatArray
    root_p: FloatArray
    vel: FloatArray
    world_p: FloatArray
    yaw: FloatArray
    states: NDArray[np.bool_]

    @property
    def n(self) -> int:
        return int(self.clip_start[-1])

    @property
    def last_in_clip(self) -> NDArray[np.bool_]:
        """(n,) True for the last frame of each clip (no playback successor)."""
        out = np.zeros(self.n, dtype=bool)
        out[self.clip_start[1:] - 1] = True
        return out


def _angular_velocity(q: FloatArray, fps: float, world: bool) -> FloatArray:
    """Central-difference angular velocity ``(F, ..., 4) -> (F, ..., 3)`` in rad/s.

    ``world=False``: in the rotating body's own frame (``log(q_prev^-1 q_next)``);
    ``world=True``: in the parent frame (``log(q_next q_prev^-1)``).
    """
    n = q.shape[0]
    if n < 2:
        return np.zeros((*q.shape[:-1], 3))
    lo = np.concatenate(([0], np.arange(n - 1)))
    hi = np.concatenate((np.arange(1, n), [n - 1]))
    dt = (hi - lo) / fps
    d = qmul(q[hi], qconj(q[lo])) if world else qmul(qconj(q[lo]), q[hi])
    w = qlog(d)
    return w / dt.reshape(-1, *([1] * (w.ndim - 1)))


def _linear_velocity(p: FloatArray, fps: float) -> FloatArray:
    n = p.shape[0]
    if n < 2:
        return np.zeros_like(p)
    return np.gradient(p, 1.0 / fps, axis=0)


def frame_features(clips: Sequence[Clip], coords: str = "fixed") -> FrameFeatures:
    """Features of every frame of ``clips`` (all with the same joint names), end to end.

    Root translations are retargeted to the first clip's body (``root_scales``).
    """
    if coords not in COORDS:
        raise ValueError(f"coords must be one of {', '.join(COORDS)}, not {coords!r}")
    if not clips:
        raise ValueError("no clips")
    joints = weighted_joints(clips[0].motion.skeleton)
    scales = root_scales(clips)
    parts: dict[str, list[FloatArray]] = {k: [] for k in ("jq", "rq", "rp", "vel", "wp", "yaw")}
    states: list[NDArray[np.bool_]] = []
    starts = [0]
    for clip, scale in zip(clips, scales, strict=True):
        m = clip.motion
        root_pos = m.root_pos * scale
        jq = m.quats[:, joints]
        q0 = m.quats[:, 0]
        yaw = yaw_of(q0)
        ang = _angular_velocity(jq, m.fps, world=False).reshape(m.n_frames, -1)
        lin = _linear_velocity(root_pos, m.fps)
        rang = _angular_velocity(q0, m.fps, world=True)
        if coords == "relative":
            tilt = qmul(yaw_q(-yaw), q0)
            rq = tilt
            rp = np.zeros_like(root_pos)
            rp[:, 1] = root_pos[:, 1]
            lin = rotate_y(lin, -yaw)
            rang = rotate_y(rang, -yaw)
        else:
            rq = q0
            rp = root_pos
        parts["jq"].append(jq)
        parts["rq"].append(rq)
        parts["rp"].append(rp)
        parts["vel"].append(np.concatenate((ang, lin, rang), axis=1))
        parts["wp"].append(root_pos)
        parts["yaw"].append(yaw)
        states.append(clip.contacts.states)
        starts.append(starts[-1] + m.n_frames)
    cat = {k: np.ascontiguousarray(np.concatenate(v)) for k, v in parts.items()}
    return FrameFeatures(
        coords=coords,
        clip_start=np.array(starts, dtype=np.int64),
        joint_q=cat["jq"],
        root_q=cat["rq"],
        root_p=cat["rp"],
        vel=cat["vel"],
        world_p=cat["wp"],
        yaw=cat["yaw"],
        states=np.concatenate(states).astype(bool),
    )
