"""The avatar's body: a capsule per bone, sized from the skeleton.

A capsule is every point within ``radius`` of a segment. Bones run from a joint to each
child joint and end site; their radii come from the joint roles (thigh, shin, upper arm,
torso, head, ...). ``BodyShape`` scales the radii (thinner or heavier) and the skeleton
(shorter or taller), because performers differ from the captured subject.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from control.motion import ROLE_ALIASES, Motion, Skeleton, find_role, forward_kinematics

__all__ = ["BodyShape", "CapsuleBody", "capsule_body", "capsule_segments"]

FloatArray = NDArray[np.float64]

# radius (metres) of the bone that ends at a joint of this role
_RADIUS = {
    "hip": 0.085,  # pelvis side (root -> hip)
    "knee": 0.07,  # thigh
    "ankle": 0.05,  # shin
    "toe": 0.04,  # foot
    "collar": 0.06,
    "shoulder": 0.055,
    "elbow": 0.045,  # upper arm
    "wrist": 0.038,  # forearm
    "spine": 0.12,
    "chest": 0.13,
    "neck": 0.06,
    "head": 0.05,  # neck bone up to the head joint
}
_HEAD = 0.1  # the head itself: the bone from the head joint to its end site
_DEFAULT = 0.03  # hands, fingers, anything else


@dataclass(frozen=True)
class BodyShape:
    """``width`` scales every radius, ``height`` the skeleton (about the floor below the root)."""

    width: float = 1.0
    height: float = 1.0

    def __post_init__(self) -> None:
        if not (0.2 <= self.width <= 5.0 and 0.2 <= self.height <= 5.0):
            raise ValueError(f"body width and height must lie in 0.2..5, got {self}")

    def to_dict(self) -> dict[str, float]:
        return asdict(self)


@dataclass(frozen=True, eq=False)
class CapsuleBody:
    """Bones as index pairs into the point table ``[joints..., end sites...]``.

    Attributes
    ----------
    start, end : (B,) point indices of each bone's ends.
    radius : (B,) metres (``BodyShape.width`` applied).
    height : the ``BodyShape.height`` factor to apply to positions.
    """

    start: NDArray[np.int64]
    end: NDArray[np.int64]
    radius: FloatArray
    height: float


def _roles(skeleton: Skeleton) -> dict[int, str]:
    out: dict[int, str] = {}
    for role in ROLE_ALIASES:
        j = find_role(skeleton, role)
        if j is not None and j not in out:
            out[j] = role.split("_", 1)[1] if "_" in role else role
    # joints between the root and the chest are torso too (CMU: upperback)
    chest = find_role(skeleton, "chest")
    while chest is not None and chest > 0:
        out.setdefault(chest, "spine")
        chest = int(skeleton.parents[chest])
    return out


def capsule_body(skeleton: Skeleton, shape: BodyShape | None = None) -> CapsuleBody:
    """Capsules for every bone of ``skeleton``."""
    shape = shape or BodyShape()
    roles = _roles(skeleton)
    start, end, radius = [], [], []
    for j in range(1, skeleton.n_joints):
        start.append(int(skeleton.parents[j]))
        end.append(j)
        role = roles.get(j)
        if role is None and roles.get(int(skeleton.parents[j])) == "root":
            role = "hip"  # CMU's hipjoint bones: the pelvis
        radius.append(_RADIUS.get(role or "", _DEFAULT))
    n_j = skeleton.n_joints
    for e, p in enumerate(skeleton.end_parents):
        start.append(int(p))
        end.append(n_j + e)
        radius.append(_HEAD if roles.get(int(p)) == "head" else _DEFAULT)
    return CapsuleBody(
        np.array(start, dtype=np.int64),
        np.array(end, dtype=np.int64),
        np.array(radius) * shape.width,
        shape.height,
    )


def capsule_segments(motion: Motion, body: CapsuleBody) -> FloatArray:
    """World-space bone segments ``(F, B, 2, 3)`` of every frame of ``motion``."""
    pose = forward_kinematics(motion)
    pts = np.concatenate((pose.positions, pose.end_positions), axis=1)
    if body.height != 1.0:
        base = motion.root_pos.copy()
        base[:, 1] = 0.0
        pts = base[:, None, :] + (pts - base[:, None, :]) * body.height
    return np.stack((pts[:, body.start], pts[:, body.end]), axis=2)
