"""Silhouettes and features of a motion seen by the camera ring."""

from __future__ import annotations

import errno
import os
import shutil
import tempfile
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from control.artifacts import current_umask
from control.motion import Motion

from ._body import CapsuleBody, capsule_segments
from ._camera import CameraRing
from ._descriptor import get_descriptor, mask_extents
from ._features import feature_size
from ._gl import GLRenderer
from ._raster import rasterize

__all__ = [
    "gl_features",
    "gl_silhouettes",
    "motion_features",
    "motion_features_both",
    "motion_silhouettes",
    "render_motion_video",
    "shaded_frames",
    "write_mp4",
]

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


#: radius (metres) of the shadow blob drawn on the ground below the root
SHADOW_RADIUS = 0.35


def draw_ground_shadow(
    mask: NDArray[np.uint8], ring: CameraRing, ground_cam: FloatArray, radius: float = SHADOW_RADIUS
) -> None:
    """Draw (in place, value 1) a flat ellipse on ``mask`` where the ground point below
    the root, ``ground_cam`` (3,) in camera coordinates, is seen: ``radius`` metres wide,
    a quarter as high (a shadow at the feet, as segmenters often leave one)."""
    import cv2

    x, y = ring.project(np.asarray(ground_cam, dtype=np.float64)[None])[0]
    w = ring.focal * radius / max(-float(ground_cam[2]), 0.1)
    cv2.ellipse(
        mask, (round(x), round(y)), (max(2, round(w)), max(1, round(w / 4))), 0, 0, 360, 1, -1
    )


def _features_of(
    masks: NDArray[np.uint8],
    here: FloatArray,
    before: FloatArray,
    first: NDArray[np.bool_],
    descriptor: str = "hu",
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Features and root motion of masks ``(n, V, H, W)`` given the root's projection
    now and at the previous frame ``(n, V, 2)``; ``first`` marks clip starts."""
    n, v = masks.shape[:2]
    flat = masks.reshape(n * v, *masks.shape[2:])
    extents = mask_extents(flat)
    desc = get_descriptor(descriptor)
    feats = desc.from_masks(flat, here.reshape(n * v, 2), extents).astype(np.float32)
    height = (extents[:, 4] - extents[:, 3]).reshape(n, v, 1).astype(np.float64)
    moves = np.zeros((n, v, 2), dtype=np.float32)
    seen = (extents[:, 0] > 0).reshape(n, v) & ~np.asarray(first, dtype=bool)[:, None]
    d = (here - before)[seen] / height[seen]
    moves[seen] = np.stack((d[:, 0], -d[:, 1]), axis=1)
    return feats.reshape(n, v, desc.size), moves


def _root_pixels(
    motion: Motion, ring: CameraRing, fr: NDArray[np.int64], poses: FloatArray
) -> tuple[FloatArray, FloatArray]:
    root = motion.root_pos[fr]
    here = ring.project(ring.to_camera(root[:, None, None, :], poses)[..., 0, :])
    prev = motion.root_pos[np.maximum(fr - 1, 0)]
    before = ring.project(ring.to_camera(prev[:, None, None, :], poses)[..., 0, :])
    return here, before


def motion_features(
    motion: Motion,
    body: CapsuleBody,
    ring: CameraRing,
    frames: NDArray[np.int64] | None = None,
    chunk: int = 64,
    shadow: bool = False,
    descriptor: str = "hu",
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Features ``(F, V, feature_size(descriptor))`` and root image motion ``(F, V, 2)``
    of ``frames``, rasterized (``shadow``: with a shadow blob at the feet,
    ``draw_ground_shadow``).

    The centre features are relative to the projection of the root; the root motion is
    the root's displacement since the previous frame as the current frame's camera sees
    it, in the same units (silhouette heights, x right, y up); 0 at a clip's first frame.
    """
    return motion_features_both(motion, body, ring, frames, chunk, descriptor, (shadow,))[0]


def motion_features_both(
    motion: Motion,
    body: CapsuleBody,
    ring: CameraRing,
    frames: NDArray[np.int64] | None = None,
    chunk: int = 64,
    descriptor: str = "hu",
    shadows: tuple[bool, ...] = (False, True),
) -> list[tuple[NDArray[np.float32], NDArray[np.float32]]]:
    """``motion_features`` with each of ``shadows``, rasterizing each frame once: the
    silhouettes with a shadow are those without plus the blob."""
    frames = np.arange(motion.n_frames) if frames is None else np.asarray(frames, dtype=np.int64)
    size = (frames.size, ring.n_views)
    out = {
        sh: (
            np.empty((*size, feature_size(descriptor)), dtype=np.float32),
            np.zeros((*size, 2), dtype=np.float32),
        )
        for sh in shadows
    }
    for s in range(0, frames.size, chunk):
        fr = frames[s : s + chunk]
        cam, poses, _ = _camera_segments(motion, body, ring, fr)
        n, v = cam.shape[:2]
        masks = rasterize(cam.reshape(n * v, *cam.shape[2:]), body.radius, ring).reshape(
            n, v, ring.height_px, ring.width
        )
        here, before = _root_pixels(motion, ring, fr, poses)
        for sh in sorted(out):  # without the shadow first: it is drawn into the masks
            if sh:
                ground = motion.root_pos[fr].copy()
                ground[:, 1] = 0.0
                g_cam = ring.to_camera(ground[:, None, None, :], poses)[..., 0, :]  # (n, V, 3)
                for i in range(n):
                    for j in range(v):
                        draw_ground_shadow(masks[i, j], ring, g_cam[i, j])
            feats, moves = out[sh]
            feats[s : s + n], moves[s : s + n] = _features_of(
                masks, here, before, fr == 0, descriptor
            )
    return [out[sh] for sh in shadows]


def gl_silhouettes(
    gl: GLRenderer, motion: Motion, body: CapsuleBody, ring: CameraRing, frames: NDArray[np.int64]
) -> NDArray[np.uint8]:
    """Masks ``(F, V, H, W)`` drawn by pyrender (the body as one mesh per frame)."""
    seg = capsule_segments(motion, body)[frames]
    poses = ring.poses(motion.root_pos[frames])
    out = np.empty((frames.size, ring.n_views, ring.height_px, ring.width), dtype=np.uint8)
    for i in range(frames.size):
        gl.set_body(seg[i], body.radius)
        for j in range(ring.n_views):
            out[i, j] = gl.render(poses[i, j])
    return out


def gl_features(
    gl: GLRenderer,
    motion: Motion,
    body: CapsuleBody,
    ring: CameraRing,
    frames: NDArray[np.int64],
    descriptor: str = "hu",
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """As ``motion_features``, drawn by pyrender."""
    masks = gl_silhouettes(gl, motion, body, ring, frames)
    here, before = _root_pixels(motion, ring, frames, ring.poses(motion.root_pos[frames]))
    return _features_of(masks, here, before, frames == 0, descriptor)


def shaded_frames(
    motion: Motion,
    ring: CameraRing,
    views: Sequence[int] | int = 0,
    body: CapsuleBody | None = None,
    scenery: tuple[NDArray[np.float64], NDArray[np.int64]] | None = None,
    camera_poses: FloatArray | None = None,
    face: bool = True,
) -> Iterator[NDArray[np.uint8]]:
    """BGR images ``(H, W, 3)`` of the shaded capsule body, one per frame, each seen by
    the camera ``views[i]`` (or one view for all) of ``ring``, which follows the root, or
    by ``camera_poses[i]`` (``(F, 4, 4)`` camera-to-world) when given; ``scenery``
    ``(vertices, faces)`` is a static mesh shown with it (obstacles, blocks); with
    ``face``, the head has eyes and a nose (``face_marks``: which way the body faces).
    The background is black."""
    from ._body import capsule_body, face_marks

    body = body or capsule_body(motion.skeleton)
    seg = capsule_segments(motion, body)
    marks = face_marks(motion, body) if face else None
    poses = ring.poses(motion.root_pos) if camera_poses is None else None
    with GLRenderer(ring) as gl:
        if scenery is not None:
            gl.set_scenery(*scenery)
        for i in range(motion.n_frames):
            gl.set_body(seg[i], body.radius)
            if marks is not None:
                gl.set_face(marks[0][i], marks[1])
            if camera_poses is not None:
                pose = camera_poses[min(i, len(camera_poses) - 1)]
            else:
                assert poses is not None
                v = views if isinstance(views, int) else views[min(i, len(views) - 1)]
                pose = poses[i, v]
            yield np.ascontiguousarray(gl.render_shaded(pose)[..., ::-1])


#: the codec ``write_mp4`` writes (its container is chosen by the file's suffix)
MP4_FOURCC = "mp4v"


def write_mp4(path: str | Path, frames: Iterable[NDArray[np.uint8]], fps: float) -> None:
    """Write BGR frames (all of one size) to an MP4, through a temporary file."""
    import cv2

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # a new file of our own (O_EXCL: never a planted name or symlink), beside the target
    fd, name = tempfile.mkstemp(
        prefix=f".{path.stem}.", suffix=f".tmp{path.suffix}", dir=path.parent
    )
    os.close(fd)
    tmp = Path(name)
    os.chmod(tmp, 0o666 & ~current_umask())
    writer = None
    n = 0
    try:
        for img in frames:
            if writer is None:
                h, w = img.shape[:2]
                writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter.fourcc(*MP4_FOURCC), fps, (w, h))
                if not writer.isOpened():
                    raise OSError(f"{path}: cannot write an MP4 here")
            writer.write(img)
            n += 1
        if writer is None:
            raise ValueError(f"{path}: no frames to write")
        writer.release()
        _check_written(tmp, path, n)
        tmp.replace(path)
    except BaseException:
        if writer is not None:
            writer.release()
        tmp.unlink(missing_ok=True)
        raise


def _check_written(tmp: Path, path: Path, n: int) -> None:
    """Raise ``OSError`` unless the MP4 ``tmp`` reads back with all ``n`` frames:
    OpenCV's writer says nothing when a frame fails (a full disk: it only prints a
    warning, and the file it leaves has no index and plays nowhere)."""
    import cv2

    cap = cv2.VideoCapture(str(tmp))
    try:
        got = int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) if cap.isOpened() else 0
    finally:
        cap.release()
    if got != n:
        full = shutil.disk_usage(tmp.parent).free < 16 * 2**20
        raise OSError(
            errno.ENOSPC if full else errno.EIO,
            f"the video was not written whole ({got} of {n} frames read back)",
            str(path),
        )


def render_motion_video(
    motion: Motion,
    path: str | Path,
    ring: CameraRing | None = None,
    view: int = 0,
    body: CapsuleBody | None = None,
    scenery: tuple[NDArray[np.float64], NDArray[np.int64]] | None = None,
) -> None:
    """An MP4 of ``motion``: the shaded body (and ``scenery``, a static mesh) seen by one
    camera of ``ring`` (default: a 320x240 ring), which follows the root."""
    ring = ring or CameraRing(width=320, height_px=240)
    write_mp4(path, shaded_frames(motion, ring, view, body, scenery), motion.fps)
