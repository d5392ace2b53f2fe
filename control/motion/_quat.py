"""Rotation kernels on unit quaternions, vectorised over any leading shape.

Glossary (used throughout ``control``):

- ``f`` frame, ``j`` joint, ``e`` end site.
- ``q`` a unit quaternion stored as ``(w, x, y, z)``, scalar first, in the last axis
  of an array of shape ``(..., 4)``. ``q`` and ``-q`` are the same rotation.
- ``R`` a 3x3 rotation matrix acting on column vectors: ``v' = R @ v``.
- Products compose like matrices: ``qmul(a, b)`` is the rotation ``R_a @ R_b`` (``b``
  is applied first).
- Angles are radians unless a name says ``deg``.

Euler angles to quaternions is a numba kernel (the motion readers' hot path: every joint
of every frame), tested against :class:`scipy.spatial.transform.Rotation`, which does the
other direction. Both take scipy's sequence strings, which say the convention:
upper-case ``"ZXY"`` is intrinsic (``R = R_z @ R_x @ R_y``, the BVH convention),
lower-case ``"xyz"`` is extrinsic (``R = R_z @ R_y @ R_x``, the Acclaim ASF/AMC
convention).
"""

from __future__ import annotations

import warnings

import numba
import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

FloatArray = NDArray[np.float64]

__all__ = [
    "euler_to_q",
    "q_to_R",
    "q_to_euler",
    "qconj",
    "qexp",
    "qlog",
    "qmul",
    "qnormalize",
    "qrot",
    "slerp",
]


def qmul(a: FloatArray, b: FloatArray) -> FloatArray:
    """Hamilton product ``a * b`` of quaternions ``(..., 4)`` (broadcasting)."""
    aw, ax, ay, az = np.moveaxis(np.asarray(a, dtype=np.float64), -1, 0)
    bw, bx, by, bz = np.moveaxis(np.asarray(b, dtype=np.float64), -1, 0)
    return np.stack(
        (
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ),
        axis=-1,
    )


def qconj(q: FloatArray) -> FloatArray:
    """Conjugate (the inverse of a unit quaternion), ``(..., 4) -> (..., 4)``."""
    out = np.array(q, dtype=np.float64, copy=True)
    out[..., 1:] *= -1.0
    return out


def qnormalize(q: FloatArray) -> FloatArray:
    """Scale ``(..., 4)`` quaternions to unit length."""
    q = np.asarray(q, dtype=np.float64)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def qrot(q: FloatArray, v: FloatArray) -> FloatArray:
    """Rotate vectors ``v (..., 3)`` by unit quaternions ``q (..., 4)`` (broadcasting)."""
    q = np.asarray(q, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def q_to_R(q: FloatArray) -> FloatArray:
    """Rotation matrices ``(..., 3, 3)`` of unit quaternions ``(..., 4)``."""
    w, x, y, z = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)
    return np.stack(
        (
            np.stack((1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)), -1),
            np.stack((2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)), -1),
            np.stack((2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)), -1),
        ),
        axis=-2,
    )


def qlog(q: FloatArray) -> FloatArray:
    """Rotation vectors ``(..., 3)`` (axis times angle, angle in ``[0, pi]``) of ``(..., 4)``.

    Sign-invariant: ``qlog(q) == qlog(-q)``.
    """
    q = np.asarray(q, dtype=np.float64)
    q = np.where(q[..., :1] < 0.0, -q, q)
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1)
    angle = 2.0 * np.arctan2(s, q[..., 0])
    scale = np.where(s > 1e-12, angle / np.maximum(s, 1e-300), 2.0)
    return v * scale[..., None]


def qexp(v: FloatArray) -> FloatArray:
    """Unit quaternions ``(..., 4)`` of rotation vectors ``(..., 3)``; inverse of ``qlog``."""
    v = np.asarray(v, dtype=np.float64)
    angle = np.linalg.norm(v, axis=-1)
    half = 0.5 * angle
    # sin(half) / angle, with its limit 1/2 near zero
    scale = np.where(angle > 1e-12, np.sin(half) / np.maximum(angle, 1e-300), 0.5)
    return np.concatenate((np.cos(half)[..., None], v * scale[..., None]), axis=-1)


def slerp(a: FloatArray, b: FloatArray, t: FloatArray) -> FloatArray:
    """Spherical linear interpolation along the shorter arc.

    Parameters
    ----------
    a, b : (..., 4) unit quaternions
    t : (...) or scalar in [0, 1]; ``t == 0`` gives ``a``, ``t == 1`` gives ``b`` (up to sign).

    Returns
    -------
    (..., 4) unit quaternions.
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)[..., None]
    dot = np.sum(a * b, axis=-1, keepdims=True)
    b = np.where(dot < 0.0, -b, b)
    dot = np.clip(np.abs(dot), 0.0, 1.0)
    theta = np.arccos(dot)
    sin_theta = np.sin(theta)
    near = sin_theta < 1e-9
    safe = np.where(near, 1.0, sin_theta)
    wa = np.where(near, 1.0 - t, np.sin((1.0 - t) * theta) / safe)
    wb = np.where(near, t, np.sin(t * theta) / safe)
    return qnormalize(wa * a + wb * b)


def _xyzw_to_wxyz(q: FloatArray) -> FloatArray:
    return np.concatenate((q[..., 3:], q[..., :3]), axis=-1)


def _wxyz_to_xyzw(q: FloatArray) -> FloatArray:
    return np.concatenate((q[..., 1:], q[..., :1]), axis=-1)


def euler_to_q(angles: FloatArray, seq: str) -> FloatArray:
    """Quaternions ``(..., 4)`` of Euler angles ``(..., len(seq))`` in radians.

    ``seq`` follows scipy: upper case intrinsic, lower case extrinsic, 1 to 3 axes. The
    result is scipy's ``from_euler(seq, angles).as_quat()``, sign included, scalar first.
    """
    if not (1 <= len(seq) <= 3) or not (seq.isupper() or seq.islower()):
        raise ValueError(f"Euler sequence {seq!r}: 1 to 3 axes, all upper or all lower case")
    if any(a not in "xyz" for a in seq.lower()):
        raise ValueError(f"Euler sequence {seq!r}: axes are x, y and z")
    angles = np.asarray(angles, dtype=np.float64)
    if angles.shape[-1:] != (len(seq),):
        raise ValueError(f"Euler angles of shape {angles.shape} for the sequence {seq!r}")
    lead = angles.shape[:-1]
    flat = np.ascontiguousarray(angles.reshape(-1, len(seq)))
    axes = np.array(["xyz".index(a) for a in seq.lower()], dtype=np.int64)
    return _euler_q(flat, axes, seq.isupper()).reshape(*lead, 4)


@numba.njit(cache=True, nogil=True)
def _euler_q(angles: FloatArray, axes: NDArray[np.int64], intrinsic: bool) -> FloatArray:
    """Compose the elementary rotations in scipy's order: ``q = e_0 e_1 e_2`` intrinsic,
    ``q = e_2 e_1 e_0`` extrinsic (``e_k`` about ``axes[k]`` by ``angles[:, k]``)."""
    n, k = angles.shape
    out = np.empty((n, 4))
    for f in range(n):
        w, x, y, z = 1.0, 0.0, 0.0, 0.0
        for i in range(k):
            h = 0.5 * angles[f, i]
            c, s = np.cos(h), np.sin(h)
            a = axes[i]
            bx = s if a == 0 else 0.0
            by = s if a == 1 else 0.0
            bz = s if a == 2 else 0.0
            if intrinsic:  # q = q * e
                w, x, y, z = (
                    w * c - x * bx - y * by - z * bz,
                    w * bx + x * c + y * bz - z * by,
                    w * by - x * bz + y * c + z * bx,
                    w * bz + x * by - y * bx + z * c,
                )
            else:  # q = e * q
                w, x, y, z = (
                    c * w - bx * x - by * y - bz * z,
                    c * x + bx * w + by * z - bz * y,
                    c * y - bx * z + by * w + bz * x,
                    c * z + bx * y - by * x + bz * w,
                )
        out[f, 0], out[f, 1], out[f, 2], out[f, 3] = w, x, y, z
    return out


def q_to_euler(q: FloatArray, seq: str) -> FloatArray:
    """Euler angles ``(..., 3)`` in radians of unit quaternions ``(..., 4)``.

    ``seq`` is a 3-axis scipy sequence (upper case intrinsic). Near gimbal lock scipy
    picks one of the equivalent solutions; the rotation is always reproduced.
    """
    q = np.asarray(q, dtype=np.float64)
    lead = q.shape[:-1]
    flat = _wxyz_to_xyzw(q.reshape(-1, 4))
    with warnings.catch_warnings():
        # Gimbal lock is expected for some frames; the rotation is still exact.
        warnings.simplefilter("ignore", UserWarning)
        e = Rotation.from_quat(flat).as_euler(seq)
    return np.asarray(e).reshape(*lead, 3)
