"""A capsule silhouette rasterizer in numba: the bank's hot path.

A pixel belongs to the silhouette when its viewing ray passes within ``radius`` of some
bone segment (a capsule is exactly the set of points within ``radius`` of its segment,
so this is the exact silhouette of the capsule body under perspective). Each capsule
only tests the pixels of its projected bounding box. The pyrender renderer (``_gl``)
draws the same body as a triangle mesh; tests compare the two.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from ._camera import CameraRing

__all__ = ["rasterize"]

_NEAR = 0.05
_FAR = 1000.0


@numba.njit(cache=True, inline="always")
def _ray_segment_dist2(
    dx: float,
    dy: float,
    dz: float,
    ax: float,
    ay: float,
    az: float,
    ex: float,
    ey: float,
    ez: float,
) -> float:
    """Squared distance between the ray ``s * d`` (0 <= s <= 1) and ``A + t * e`` (0..1)."""
    # Ericson, Real-Time Collision Detection, 5.1.9, with p1 = 0, d1 = d, p2 = A, d2 = e
    rx, ry, rz = -ax, -ay, -az
    a = dx * dx + dy * dy + dz * dz
    e2 = ex * ex + ey * ey + ez * ez
    f = ex * rx + ey * ry + ez * rz
    c = dx * rx + dy * ry + dz * rz
    if e2 <= 1e-18:
        t = 0.0
        s = min(max(-c / a, 0.0), 1.0)
    else:
        b = dx * ex + dy * ey + dz * ez
        denom = a * e2 - b * b
        s = min(max((b * f - c * e2) / denom, 0.0), 1.0) if denom > 1e-18 else 0.0
        t = (b * s + f) / e2
        if t < 0.0:
            t = 0.0
            s = min(max(-c / a, 0.0), 1.0)
        elif t > 1.0:
            t = 1.0
            s = min(max((b - c) / a, 0.0), 1.0)
    qx = s * dx - (ax + t * ex)
    qy = s * dy - (ay + t * ey)
    qz = s * dz - (az + t * ez)
    return qx * qx + qy * qy + qz * qz


@numba.njit(cache=True, parallel=True)
def _raster_kernel(
    seg: np.ndarray, radius: np.ndarray, f: float, cx: float, cy: float, out: np.ndarray
) -> None:
    n, n_bones = seg.shape[0], seg.shape[1]
    h, w = out.shape[1], out.shape[2]
    for i in numba.prange(n):
        for b in range(n_bones):
            ax, ay, az = seg[i, b, 0, 0], seg[i, b, 0, 1], seg[i, b, 0, 2]
            bx, by, bz = seg[i, b, 1, 0], seg[i, b, 1, 1], seg[i, b, 1, 2]
            r = radius[b]
            za, zb = -az, -bz
            if za < _NEAR - r and zb < _NEAR - r:
                continue
            if za > _NEAR and zb > _NEAR:
                ua, va = cx + f * ax / za, cy - f * ay / za
                ub, vb = cx + f * bx / zb, cy - f * by / zb
                ext = r * f / (min(za, zb) - r) + 1.0 if min(za, zb) > r + _NEAR else w + h
                u0 = max(0, math.floor(min(ua, ub) - ext))
                u1 = min(w - 1, math.ceil(max(ua, ub) + ext))
                v0 = max(0, math.floor(min(va, vb) - ext))
                v1 = min(h - 1, math.ceil(max(va, vb) + ext))
            else:  # crosses the camera plane: test the whole image
                u0, u1, v0, v1 = 0, w - 1, 0, h - 1
            r2 = r * r
            ex, ey, ez = bx - ax, by - ay, bz - az
            for v in range(v0, v1 + 1):
                dy = -(v + 0.5 - cy) / f * _FAR
                for u in range(u0, u1 + 1):
                    if out[i, v, u]:
                        continue
                    dx = (u + 0.5 - cx) / f * _FAR
                    if _ray_segment_dist2(dx, dy, -_FAR, ax, ay, az, ex, ey, ez) <= r2:
                        out[i, v, u] = 1


def rasterize(
    segments_cam: NDArray[np.float64], radius: NDArray[np.float64], ring: CameraRing
) -> NDArray[np.uint8]:
    """Silhouettes ``(N, H, W)`` uint8 of capsule bodies given in camera coordinates.

    Parameters
    ----------
    segments_cam : (N, B, 2, 3) bone end points in each image's camera frame.
    radius : (B,) capsule radii.
    ring : image size and intrinsics.
    """
    seg = np.ascontiguousarray(segments_cam, dtype=np.float64)
    if seg.ndim != 4 or seg.shape[2:] != (2, 3) or seg.shape[1] != radius.shape[0]:
        raise ValueError("segments must be (N, B, 2, 3) with one radius per bone")
    out = np.zeros((seg.shape[0], ring.height_px, ring.width), dtype=np.uint8)
    cx, cy = ring.centre
    _raster_kernel(seg, np.ascontiguousarray(radius, dtype=np.float64), ring.focal, cx, cy, out)
    return out
