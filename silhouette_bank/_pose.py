"""The pose descriptor's bank side: the avatar's joints projected into every view.

Where a silhouette bank renders masks, a pose bank projects the 12 joints of
``POSE_JOINTS`` (found by role, so any skeleton that names them works) through each
camera of the ring and keeps ``PoseDescriptor.from_points`` of them, with the root's
projection as the origin. The root's image motion is in torso lengths, like the
descriptor's centre.

``pose_visibility`` says how much of each joint a camera sees past the body (the
capsule body in the way: ``joint_visibility``): what a pose model's visibilities say of
a real performer, for landmarks simulated from a take.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from control.motion import Motion, Skeleton, forward_kinematics, role_point

from ._body import BodyShape, capsule_body, capsule_segments
from ._camera import CameraRing
from ._descriptor import POSE_JOINTS, PoseDescriptor, get_descriptor
from ._occlusion import joint_visibility, own_bones

__all__ = ["joint_points", "motion_pose_features", "pose_point_indices", "pose_visibility"]

FloatArray = NDArray[np.float64]


def pose_point_indices(skeleton: Skeleton) -> list[tuple[str, int]]:
    """Where each of ``POSE_JOINTS`` is read: ``("joint", j)`` or ``("end", e)``; a
    ``ValueError`` names the role the skeleton lacks."""
    out = []
    for role in POSE_JOINTS:
        try:
            out.append(role_point(skeleton, role))
        except KeyError as exc:
            raise ValueError(f"the pose descriptor needs a {role} joint: {exc}") from None
    return out


def joint_points(motion: Motion, frames: NDArray[np.int64] | None = None) -> FloatArray:
    """World positions ``(F, 12, 3)`` of ``POSE_JOINTS`` at ``frames`` (default all)."""
    frames = np.arange(motion.n_frames) if frames is None else np.asarray(frames, dtype=np.int64)
    pose = forward_kinematics(motion)
    cols = []
    for kind, i in pose_point_indices(motion.skeleton):
        src = pose.positions if kind == "joint" else pose.end_positions
        cols.append(src[frames, i])
    return np.stack(cols, axis=1)


def pose_visibility(
    motion: Motion,
    poses: FloatArray,
    frames: NDArray[np.int64] | None = None,
    body: BodyShape | None = None,
) -> NDArray[np.float32]:
    """How visible each of ``POSE_JOINTS`` is ``(F, V, 12)`` at ``frames`` (default all)
    to cameras ``poses`` ``(F, V, 4, 4)`` (camera-to-world), the capsule body of
    ``body`` (default the avatar's) in the way (``joint_visibility``)."""
    frames = np.arange(motion.n_frames) if frames is None else np.asarray(frames, dtype=np.int64)
    caps = capsule_body(motion.skeleton, body)
    seg = capsule_segments(motion, caps)[frames]  # (F, B, 2, 3), the body's own proportions
    points = pose_point_indices(motion.skeleton)
    n_j = motion.skeleton.n_joints
    at = np.array([i if kind == "joint" else n_j + i for kind, i in points], dtype=np.int64)
    # each joint's place on that body: the end of a bone that ends there (a bone's start
    # where none does)
    first_end = {int(e): b for b, e in reversed(list(enumerate(caps.end)))}
    first_start = {int(a): b for b, a in reversed(list(enumerate(caps.start)))}
    where = [(first_end[i], 1) if i in first_end else (first_start[i], 0) for i in at.tolist()]
    joints = np.stack([seg[:, b, e] for b, e in where], axis=1)  # (F, 12, 3)
    own = own_bones(caps, at)
    # a joint's own radius: its thickest own bone's
    own_r = np.array([caps.radius[row].max() if row.any() else 0.0 for row in own])
    v = poses.shape[1]
    out = np.empty((frames.size, v, len(POSE_JOINTS)), dtype=np.float32)
    b_n = seg.shape[1]
    for j in range(v):
        pose = poses[:, j]
        cam_j = CameraRing.to_camera(joints, pose)
        cam_s = CameraRing.to_camera(seg.reshape(frames.size, b_n * 2, 3), pose)
        out[:, j] = joint_visibility(
            cam_j, cam_s.reshape(frames.size, b_n, 2, 3), caps.radius, own_r, own
        )
    return out


def motion_pose_features(
    motion: Motion, ring: CameraRing, frames: NDArray[np.int64] | None = None
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Pose features ``(F, V, 26)`` and the root's image motion ``(F, V, 2)`` (torso
    lengths, x right, y up; 0 at a clip's first frame) of ``frames`` seen by ``ring``."""
    frames = np.arange(motion.n_frames) if frames is None else np.asarray(frames, dtype=np.int64)
    desc = get_descriptor("pose")
    assert isinstance(desc, PoseDescriptor)
    pts = joint_points(motion, frames)  # (F, 12, 3)
    root = motion.root_pos[frames]
    poses = ring.poses(root)  # (F, V, 4, 4)
    v = ring.n_views
    world = np.concatenate((pts, root[:, None, :]), axis=1)  # (F, 13, 3)
    cam = ring.to_camera(np.broadcast_to(world[:, None], (frames.size, v, 13, 3)), poses)
    px = ring.project(cam)  # (F, V, 13, 2)
    here = px[..., 12, :]
    feats = np.empty((frames.size, v, desc.size), dtype=np.float32)
    moves = np.zeros((frames.size, v, 2), dtype=np.float32)
    for j in range(v):  # the centre relative to the root's projection
        feats[:, j] = desc.from_points(px[:, j, :12], here[:, j])
    prev = motion.root_pos[np.maximum(frames - 1, 0)]
    before = ring.project(ring.to_camera(prev[:, None, None, :], poses)[..., 0, :])  # (F, V, 2)
    d = (here - before) / desc.scale(px[..., :12, :])[..., None]  # the centre's unit
    d[..., 1] *= -1.0
    d[frames == 0] = 0.0
    moves[:] = d
    return feats, moves
