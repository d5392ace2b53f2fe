"""Silhouettes and features of a motion seen by the camera ring."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from control.motion import Motion

from ._body import CapsuleBody, capsule_segments
from ._camera import CameraRing
from ._features import N_FEATURES, silhouette_features
from ._raster import rasterize

__all__ = ["motion_features", "motion_silhouettes"]

FloatArray = NDArray[np.float64]


def _camera_segments(
    motion: Motion, body: CapsuleBody, ring: CameraRing, frames: NDArray[np.int64]
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Segments per (frame, view) in camera coordinates, the camera poses, world roots."""
    seg = capsule_segments(motion, body)[frames]  # (F, B, 2, 3)
    root = motion.root_pos[frames]
    poses = ring.poses(root)  # (F, V, 4, 4)
    f, b = seg.shape[:2]
    flat = seg.reshape(f, 1, b * 2, 3)
    cam = ring.to_camera(np.broadcast_to(flat, (f, ring.n_views, b * 2, 3)), poses)
    return cam.reshape(f, ring.n_views, b, 2, 3), poses, root


def motion_silhouettes(
    motion: Motion, body: CapsuleBody, ring: CameraRing, frames: NDArray[np.int64] | None = None
) -> NDArray[np.uint8]:
    """Masks ``(F, V, H, W)`` of ``frames`` (default all) from every view of the ring."""
    frames = np.arange(motion.n_frames) if frames is None else np.asarray(frames, dtype=np.int64)
    cam, _, _ = _camera_segments(motion, body, ring, frames)
    f, v = cam.shape[:2]
    masks = rasterize(cam.reshape(f * v, *cam.shape[2:]), body.radius, ring)
    return masks.reshape(f, v, ring.height_px, ring.width)


def motion_features(
    motion: Motion,
    body: CapsuleBody,
    ring: CameraRing,
    frames: NDArray[np.int64] | None = None,
    chunk: int = 64,
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Features ``(F, V, 9)`` and root image motion ``(F, V, 2)`` of ``frames``.

    The centre features are relative to the projection of the root; the root motion is
    the root's displacement since the previous frame as the current frame's camera sees
    it, in the same units (silhouette heights, x right, y up); 0 at a clip's first frame.
    """
    frames = np.arange(motion.n_frames) if frames is None else np.asarray(frames, dtype=np.int64)
    feats = np.empty((frames.size, ring.n_views, N_FEATURES), dtype=np.float32)
    moves = np.zeros((frames.size, ring.n_views, 2), dtype=np.float32)
    for s in range(0, frames.size, chunk):
        fr = frames[s : s + chunk]
        cam, poses, root = _camera_segments(motion, body, ring, fr)
        n, v = cam.shape[:2]
        masks = rasterize(cam.reshape(n * v, *cam.shape[2:]), body.radius, ring).reshape(
            n, v, ring.height_px, ring.width
        )
        here = ring.project(ring.to_camera(root[:, None, None, :], poses)[..., 0, :])  # (n, v, 2)
        prev_root = motion.root_pos[np.maximum(fr - 1, 0)]
        before = ring.project(ring.to_camera(prev_root[:, None, None, :], poses)[..., 0, :])
        for i in range(n):
            for j in range(v):
                x = silhouette_features(masks[i, j], (float(here[i, j, 0]), float(here[i, j, 1])))
                feats[s + i, j] = x
                rows = np.flatnonzero(masks[i, j].any(axis=1))
                if rows.size and fr[i] > 0:
                    hgt = float(rows[-1] - rows[0] + 1)
                    d = (here[i, j] - before[i, j]) / hgt
                    moves[s + i, j] = (d[0], -d[1])
    return feats, moves
