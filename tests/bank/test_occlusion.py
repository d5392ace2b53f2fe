"""Which joints the body hides from a camera: the kernel against a slow reference, and
the bank's side views against what a side view hides."""

from __future__ import annotations

import numpy as np
import pytest

from control.motion import Library
from silhouette_bank import POSE_JOINTS, CameraRing, joint_visibility, pose_visibility

#: elbows, wrists, knees and ankles in ``POSE_JOINTS``
LIMBS = [2, 3, 4, 5, 8, 9, 10, 11]


def _slow_visibility(
    joints: np.ndarray, seg: np.ndarray, radius: np.ndarray, own_r: np.ndarray, own: np.ndarray
) -> np.ndarray:
    """The same by brute force: the ray and each bone sampled densely."""
    s = np.linspace(0.0, 1.0, 801)
    out = np.ones(joints.shape[:2])
    for i in range(joints.shape[0]):
        for k in range(joints.shape[1]):
            p = joints[i, k]
            p = p * (1.0 - own_r[k] / np.linalg.norm(p))
            ray = s[:, None] * p
            for b in range(seg.shape[1]):
                if own[k, b]:
                    continue
                bone = seg[i, b, 0] + s[:, None] * (seg[i, b, 1] - seg[i, b, 0])
                d = np.sqrt(((ray[:, None] - bone[None]) ** 2).sum(-1).min())
                out[i, k] = min(out[i, k], np.clip((d - 0.5 * radius[b]) / radius[b], 0, 1))
    return out


@pytest.mark.slow
def test_a_joint_behind_a_capsule_is_hidden_and_beside_it_seen(rng: np.random.Generator) -> None:
    # the camera at 0 looking down -z; a torso capsule 3 m away, a wrist behind it
    torso = np.array([[[0.0, -0.3, -3.0], [0.0, 0.3, -3.0]]])
    radius, own_r, own = np.array([0.15]), np.array([0.04]), np.zeros((1, 1), dtype=bool)
    behind = np.array([[[0.0, 0.0, -3.4]]])
    beside = np.array([[[0.5, 0.0, -3.4]]])
    front = np.array([[[0.0, 0.0, -2.6]]])
    for joint, want in ((behind, 0.0), (beside, 1.0), (front, 1.0)):
        assert joint_visibility(joint, torso[None], radius, own_r, own)[0, 0] == want
    # a joint's own bones never hide it
    assert joint_visibility(behind, torso[None], radius, own_r, ~own)[0, 0] == 1.0
    # random scenes: the kernel agrees with brute force (to the sampling's precision)
    n, k, b = 4, 5, 6
    joints = rng.normal(0, 0.4, (n, k, 3)) + np.array([0.0, 0.0, -3.0])
    seg = rng.normal(0, 0.4, (n, b, 2, 3)) + np.array([0.0, 0.0, -3.0])
    radius = rng.uniform(0.05, 0.2, b)
    own_r = rng.uniform(0.02, 0.06, k)
    own = rng.random((k, b)) < 0.2
    got = joint_visibility(joints, seg, radius, own_r, own)
    np.testing.assert_allclose(got, _slow_visibility(joints, seg, radius, own_r, own), atol=0.02)


def test_a_side_view_hides_the_far_limbs(lib: Library) -> None:
    m = lib.clip("02_01").motion  # a walk
    ring = CameraRing(n_views=4)  # front, the performer's left side, behind, right side
    frames = np.arange(m.n_frames)
    facing = np.arctan2(*(m.root_pos[-1, [0, 2]] - m.root_pos[0, [0, 2]]))  # where it walks
    poses = CameraRing(n_views=4, azimuth_offset=float(np.degrees(facing))).poses(
        m.root_pos[frames]
    )
    vis = pose_visibility(m, poses, frames).mean(axis=0)  # (4 views, 12)
    assert vis.shape == (ring.n_views, len(POSE_JOINTS))
    left_arm, right_arm = [2, 4], [3, 5]  # elbow and wrist
    # from the front every limb is mostly in view (the feet pass behind each other);
    # from the left the torso hides the right arm, and from the right the left arm
    assert vis[0, LIMBS].min() > 0.7 and vis[2, LIMBS].min() > 0.7
    assert vis[1, right_arm].mean() < 0.4 and vis[1, left_arm].min() > 0.95
    assert vis[3, left_arm].mean() < 0.4 and vis[3, right_arm].min() > 0.95
