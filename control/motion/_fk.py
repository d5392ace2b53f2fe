"""Forward kinematics: a numba kernel over frames and joints (``_fk``), tested against the
numpy reference vectorised over frames (``_fk_numpy``), whose float operations it
repeats in the same order (the same numbers, bit for bit)."""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from ._quat import FloatArray, qmul, qrot
from ._types import Motion, Skeleton

__all__ = ["Pose", "forward_kinematics", "rest_positions"]


@dataclass(frozen=True, eq=False)
class Pose:
    """World-space result of forward kinematics.

    Attributes
    ----------
    positions : (F, J, 3) metres, every joint.
    orientations : (F, J, 4) unit quaternions (w, x, y, z), every joint's world rotation.
    end_positions : (F, E, 3) metres, every end site.
    """

    positions: FloatArray
    orientations: FloatArray
    end_positions: FloatArray


@numba.njit(cache=True, nogil=True, inline="always")
def _rotate(q: np.ndarray, v: np.ndarray, out: np.ndarray) -> None:
    """``out = qrot(q, v)``: ``t = 2 u x v``, ``v + w t + u x t``, as ``qrot`` does."""
    w, ux, uy, uz = q[0], q[1], q[2], q[3]
    tx = 2.0 * (uy * v[2] - uz * v[1])
    ty = 2.0 * (uz * v[0] - ux * v[2])
    tz = 2.0 * (ux * v[1] - uy * v[0])
    out[0] = v[0] + w * tx + (uy * tz - uz * ty)
    out[1] = v[1] + w * ty + (uz * tx - ux * tz)
    out[2] = v[2] + w * tz + (ux * ty - uy * tx)


@numba.njit(cache=True, nogil=True)
def _fk_kernel(
    parents: np.ndarray,
    offsets: np.ndarray,
    end_parents: np.ndarray,
    end_offsets: np.ndarray,
    root_pos: np.ndarray,
    quats: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n_frames, n_joints = quats.shape[0], quats.shape[1]
    pos = np.empty((n_frames, n_joints, 3))
    rot = np.empty((n_frames, n_joints, 4))
    ends = np.empty((n_frames, end_parents.size, 3))
    r = np.empty(3)
    for f in range(n_frames):
        pos[f, 0] = root_pos[f]
        rot[f, 0] = quats[f, 0]
        for j in range(1, n_joints):
            p = parents[j]
            _rotate(rot[f, p], offsets[j], r)
            for k in range(3):
                pos[f, j, k] = pos[f, p, k] + r[k]
            aw, ax, ay, az = rot[f, p, 0], rot[f, p, 1], rot[f, p, 2], rot[f, p, 3]
            bw, bx, by, bz = quats[f, j, 0], quats[f, j, 1], quats[f, j, 2], quats[f, j, 3]
            rot[f, j, 0] = aw * bw - ax * bx - ay * by - az * bz
            rot[f, j, 1] = aw * bx + ax * bw + ay * bz - az * by
            rot[f, j, 2] = aw * by - ax * bz + ay * bw + az * bx
            rot[f, j, 3] = aw * bz + ax * by - ay * bx + az * bw
        for e in range(end_parents.size):
            p = end_parents[e]
            _rotate(rot[f, p], end_offsets[e], r)
            for k in range(3):
                ends[f, e, k] = pos[f, p, k] + r[k]
    return pos, rot, ends


def _fk(
    skeleton: Skeleton, root_pos: FloatArray, quats: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``(positions, orientations, end_positions)`` by the kernel."""
    return _fk_kernel(
        np.ascontiguousarray(skeleton.parents, dtype=np.int64),
        np.ascontiguousarray(skeleton.offsets, dtype=np.float64).reshape(-1, 3),
        np.ascontiguousarray(skeleton.end_parents, dtype=np.int64),
        np.ascontiguousarray(skeleton.end_offsets, dtype=np.float64).reshape(-1, 3),
        np.ascontiguousarray(root_pos, dtype=np.float64),
        np.ascontiguousarray(quats, dtype=np.float64),
    )


def _fk_numpy(
    skeleton: Skeleton, root_pos: FloatArray, quats: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The reference: vectorised over frames, a joint at a time."""
    n_frames, n_joints = quats.shape[:2]
    pos = np.empty((n_frames, n_joints, 3))
    rot = np.empty((n_frames, n_joints, 4))
    pos[:, 0] = root_pos
    rot[:, 0] = quats[:, 0]
    parents = skeleton.parents
    offsets = skeleton.offsets
    for j in range(1, n_joints):
        p = parents[j]
        pos[:, j] = pos[:, p] + qrot(rot[:, p], offsets[j])
        rot[:, j] = qmul(rot[:, p], quats[:, j])
    ends = np.empty((n_frames, skeleton.end_parents.size, 3))
    for e, p in enumerate(skeleton.end_parents):
        ends[:, e] = pos[:, p] + qrot(rot[:, p], skeleton.end_offsets[e])
    return pos, rot, ends


def forward_kinematics(motion: Motion) -> Pose:
    """Global joint positions and orientations of every frame.

    Returns
    -------
    Pose with ``positions (F, J, 3)``, ``orientations (F, J, 4)``, ``end_positions (F, E, 3)``.
    """
    pos, rot, ends = _fk(motion.skeleton, motion.root_pos, motion.quats)
    return Pose(pos, rot, ends)


def rest_positions(skeleton: Skeleton) -> tuple[FloatArray, FloatArray]:
    """Joint ``(J, 3)`` and end-site ``(E, 3)`` positions at rest with the root at the origin."""
    ident = np.zeros((1, skeleton.n_joints, 4))
    ident[..., 0] = 1.0
    pos, _, ends = _fk(skeleton, np.zeros((1, 3)), ident)
    return pos[0], ends[0]
