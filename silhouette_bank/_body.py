"""The avatar's body: a capsule per bone, sized from the skeleton.

A capsule is every point within ``radius`` of a segment. Bones run from a joint to each
child joint and end site; their radii come from the joint roles (thigh, shin, upper arm,
torso, head, ...). ``BodyShape`` scales the radii (thinner or heavier) and the skeleton
(shorter or taller), because performers differ from the captured subject.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np
from numpy.typing import NDArray

from control.motion import ROLE_ALIASES, Motion, Skeleton, find_role, forward_kinematics

__all__ = [
    "BodyShape",
    "CapsuleBody",
    "capsule_body",
    "capsule_segments",
    "face_marks",
    "with_proportions",
]

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
    """``width`` scales every radius, ``height`` the skeleton (about the floor below the
    root); ``legs`` and ``arms`` scale the bones below the hips and below the shoulders
    against the torso (another person's proportions)."""

    width: float = 1.0
    height: float = 1.0
    legs: float = 1.0
    arms: float = 1.0

    def __post_init__(self) -> None:
        if not (0.2 <= self.width <= 5.0 and 0.2 <= self.height <= 5.0):
            raise ValueError(f"body width and height must lie in 0.2..5, got {self}")
        if not (0.5 <= self.legs <= 2.0 and 0.5 <= self.arms <= 2.0):
            raise ValueError(f"body legs and arms must lie in 0.5..2, got {self}")

    def to_dict(self) -> dict[str, float]:
        """Its fields; ``legs`` and ``arms`` only where they are not 1 (so the settings of
        a body without them, and the artifacts keyed by them, stay as they were)."""
        d = asdict(self)
        for k in ("legs", "arms"):
            if d[k] == 1.0:
                del d[k]
        return d


@dataclass(frozen=True, eq=False)
class CapsuleBody:
    """Bones as index pairs into the point table ``[joints..., end sites...]``.

    Attributes
    ----------
    start, end : (B,) point indices of each bone's ends.
    radius : (B,) metres (``BodyShape.width`` applied).
    height : the ``BodyShape.height`` factor to apply to positions.
    scale : ``None``, or ``(J + E,)`` factors of each joint's and end site's rest offset
        (``BodyShape.legs`` and ``arms``).
    """

    start: NDArray[np.int64]
    end: NDArray[np.int64]
    radius: FloatArray
    height: float
    scale: FloatArray | None = None


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
        _limb_scale(skeleton, shape),
    )


def _limb_scale(skeleton: Skeleton, shape: BodyShape) -> FloatArray | None:
    """Factors ``(J + E,)`` of the rest offsets: ``legs`` for every joint and end site
    below a hip joint, ``arms`` below a shoulder; ``None`` when both are 1."""
    if shape.legs == 1.0 and shape.arms == 1.0:
        return None
    n_j = skeleton.n_joints
    scale = np.ones(n_j + skeleton.end_parents.size)
    for part, factor in (("hip", shape.legs), ("shoulder", shape.arms)):
        for side in ("left", "right"):
            top = find_role(skeleton, f"{side}_{part}")
            if top is None:
                raise ValueError(f"skeleton has no {side} {part} joint to scale the {part}s from")
            below = np.zeros(n_j, dtype=bool)
            for j in range(top + 1, n_j):  # parents come first
                below[j] = below[skeleton.parents[j]] or skeleton.parents[j] == top
            scale[:n_j][below] = factor
            scale[n_j:][below[skeleton.end_parents] | (skeleton.end_parents == top)] = factor
    return scale


def _points(motion: Motion) -> FloatArray:
    pose = forward_kinematics(motion)
    return np.concatenate((pose.positions, pose.end_positions), axis=1)


def _rescaled(motion: Motion, scale: FloatArray) -> tuple[Motion, FloatArray]:
    """``motion`` on its skeleton with each rest offset times ``scale`` ``(J + E,)``,
    each frame raised or lowered so that its lowest point stays at the height it had
    (the feet on the floor, not through it), and its points ``(F, J + E, 3)``."""
    sk = motion.skeleton
    n_j = sk.n_joints
    sk = replace(
        sk,
        offsets=sk.offsets * scale[:n_j, None],
        end_offsets=sk.end_offsets * scale[n_j:, None],
    )
    low = _points(motion)[:, :, 1].min(axis=1)
    out = replace(motion, skeleton=sk)
    pts = _points(out)
    rise = low - pts[:, :, 1].min(axis=1)
    pts[:, :, 1] += rise[:, None]  # (the root raised as well: every point moves with it)
    root = motion.root_pos.copy()
    root[:, 1] += rise
    return replace(out, root_pos=root), pts


def with_proportions(motion: Motion, shape: BodyShape) -> Motion:
    """``motion`` with ``shape``'s legs and arms (``BodyShape.legs``, ``arms``), its
    lowest point kept at each frame's height; ``motion`` itself when both are 1."""
    scale = _limb_scale(motion.skeleton, shape)
    return motion if scale is None else _rescaled(motion, scale)[0]


def capsule_segments(motion: Motion, body: CapsuleBody) -> FloatArray:
    """World-space bone segments ``(F, B, 2, 3)`` of every frame of ``motion``, with
    ``body``'s limbs (``with_proportions``) and height."""
    if body.scale is not None:
        motion, pts = _rescaled(motion, body.scale)
    else:
        pts = _points(motion)
    if body.height != 1.0:
        base = motion.root_pos.copy()
        base[:, 1] = 0.0
        pts = base[:, None, :] + (pts - base[:, None, :]) * body.height
    return np.stack((pts[:, body.start], pts[:, body.end]), axis=2)


#: the face's marks: (forward, right, up) offsets from the head's centre in head radii,
#: and each mark's radius in head radii: two eyes and a nose
_FACE = ((0.82, -0.36, 0.15, 0.17), (0.82, 0.36, 0.15, 0.17), (0.98, 0.0, -0.15, 0.2))


def face_marks(motion: Motion, body: CapsuleBody) -> tuple[FloatArray, FloatArray] | None:
    """Two eyes and a nose on the head's front: centres ``(F, 3, 3)`` (world) and radii
    ``(3,)``, where the head is the capsule above the head joint and its front the
    horizontal direction the shoulders face; ``None`` when the skeleton lacks a head or
    shoulders. Shaded renders draw them: a faceless body looks the same from the front
    and, mirrored, from behind, and a pose model then takes one for the other."""
    sk = motion.skeleton
    head = find_role(sk, "head")
    left, right = find_role(sk, "left_shoulder"), find_role(sk, "right_shoulder")
    if head is None or left is None or right is None:
        return None
    bone = np.flatnonzero(body.start == head)
    if bone.size == 0:
        return None
    b = int(bone[np.argmax(body.radius[bone])])  # the head itself: its thickest bone
    ends = [np.flatnonzero(body.end == j) for j in (left, right)]
    if not all(e.size for e in ends):
        return None
    seg = capsule_segments(motion, body)  # (F, B, 2, 3), the body's own proportions
    centre = seg[:, b].mean(axis=1)
    r = float(body.radius[b])
    # the shoulders: where the bones that end at them end
    across = seg[:, ends[0][0], 1] - seg[:, ends[1][0], 1]  # the performer's right to left
    across[:, 1] = 0.0
    up = np.array([0.0, 1.0, 0.0])
    forward = np.cross(across, up)
    forward /= np.maximum(np.linalg.norm(forward, axis=1, keepdims=True), 1e-9)
    to_right = -across / np.maximum(np.linalg.norm(across, axis=1, keepdims=True), 1e-9)
    marks = np.stack(
        [centre + r * (f * forward + s * to_right + u * up) for f, s, u, _ in _FACE], axis=1
    )
    return marks, np.array([r * k for *_, k in _FACE])
