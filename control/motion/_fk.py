"""Forward kinematics, vectorised over frames."""

from __future__ import annotations

from dataclasses import dataclass

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


def _fk(
    skeleton: Skeleton, root_pos: FloatArray, quats: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
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
