"""Which of the pose descriptor's joints the body itself hides from a camera.

A pose model seeing a performer from the side gives the far elbow, wrist, knee and ankle
a low visibility: the body is in the way. The same can be said of any motion and camera:
a joint is hidden when the ray from the camera to the joint's near surface (the joint
moved towards the camera by its limb's radius) passes through another capsule of the
body (not the limb's own bones). How far inside the capsule the ray passes makes the
visibility soft: 1 clear of it by half its radius or more, 0 within half its radius of
the capsule's axis, linear between, the least over every capsule.

Landmarks simulated from a take (the benchmarks' performers) carry it, so that what a
side view hides reaches the loop as it does from a real pose model.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from ._body import CapsuleBody
from ._raster import _ray_segment_dist2

__all__ = ["joint_visibility", "own_bones"]

FloatArray = NDArray[np.float64]


def own_bones(body: CapsuleBody, points: NDArray[np.int64]) -> NDArray[np.bool_]:
    """``(K, B)``: whether bone ``b`` starts or ends at ``points[k]`` (indices into the
    body's point table, joints then end sites): the limb's own capsules, which never
    hide the joint."""
    idx = np.asarray(points, dtype=np.int64)
    return (body.start[None, :] == idx[:, None]) | (body.end[None, :] == idx[:, None])


def joint_visibility(
    joints_cam: FloatArray,
    segments_cam: FloatArray,
    radius: FloatArray,
    own_radius: FloatArray,
    own: NDArray[np.bool_],
) -> NDArray[np.float32]:
    """Visibility ``(N, K)`` in [0, 1] of joints ``(N, K, 3)`` in camera coordinates
    (the camera at the origin looking down -z), among capsules ``(N, B, 2, 3)`` of
    ``radius`` ``(B,)``; ``own_radius`` ``(K,)`` is each joint's limb radius and ``own``
    ``(K, B)`` its own bones (skipped)."""
    j = np.ascontiguousarray(joints_cam, dtype=np.float64)
    s = np.ascontiguousarray(segments_cam, dtype=np.float64)
    if j.ndim != 3 or j.shape[2] != 3 or s.ndim != 4 or s.shape[:1] != j.shape[:1]:
        raise ValueError(f"joints (N, K, 3) and segments (N, B, 2, 3), got {j.shape}, {s.shape}")
    out = np.empty(j.shape[:2], dtype=np.float32)
    _visibility_kernel(
        j,
        s,
        np.asarray(radius, dtype=np.float64),
        np.asarray(own_radius, dtype=np.float64),
        np.asarray(own, dtype=np.bool_),
        out,
    )
    return out


@numba.njit(cache=True, parallel=True)
def _visibility_kernel(
    joints: np.ndarray,
    seg: np.ndarray,
    radius: np.ndarray,
    own_radius: np.ndarray,
    own: np.ndarray,
    out: np.ndarray,
) -> None:
    n, k_n, b_n = joints.shape[0], joints.shape[1], seg.shape[1]
    for i in numba.prange(n):
        for k in range(k_n):
            px, py, pz = joints[i, k, 0], joints[i, k, 1], joints[i, k, 2]
            dist = math.sqrt(px * px + py * py + pz * pz)
            pull = 1.0 - own_radius[k] / dist if dist > own_radius[k] else 0.0
            px, py, pz = px * pull, py * pull, pz * pull  # the joint's near surface
            vis = 1.0
            for b in range(b_n):
                if own[k, b]:
                    continue
                ax, ay, az = seg[i, b, 0, 0], seg[i, b, 0, 1], seg[i, b, 0, 2]
                ex, ey, ez = seg[i, b, 1, 0] - ax, seg[i, b, 1, 1] - ay, seg[i, b, 1, 2] - az
                d = math.sqrt(_ray_segment_dist2(px, py, pz, ax, ay, az, ex, ey, ez))
                r = radius[b]
                v = min(max((d - 0.5 * r) / r, 0.0), 1.0)
                vis = min(vis, v)
            out[i, k] = vis
