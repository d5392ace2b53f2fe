"""``mimic record``: a clip rendered as a performer's video, with ground truth.

The performer is not the avatar: another body shape, a camera at a height and azimuth
that the bank's ring does not contain, a static camera (the performer moves across the
image). Two kinds of video:

- silhouettes (the default), with the flaws of real masks: ragged edges, small holes, a
  shadow blob at the feet; white on black;
- ``colour``: the shaded capsule body (a mannequin with a face) on a plain background,
  drawn by pyrender. MediaPipe Pose finds this body from every side, and gives the far
  limbs of a side view the low visibilities real footage gives them, so the whole
  landmark path (model, visibilities, the loop) can be tested on a performer whose
  truth is known, from any azimuth.

The video is lossless (FFV1 in Matroska); a JSON sidecar gives, per video frame, the
source clip's frame (at the source rate) and its action label where the clip has labels.
"""

from __future__ import annotations

import dataclasses
import json
import math
import shlex
import sys
from collections.abc import Iterable, Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from control.artifacts import atomic_write
from control.motion import Clip, Motion
from silhouette_bank import (
    BodyShape,
    CameraRing,
    capsule_body,
    capsule_segments,
    draw_ground_shadow,
    rasterize,
    shaded_frames,
)

__all__ = [
    "RECORDING_FOURCC",
    "RecordSettings",
    "add_mask_noise",
    "camera_poses",
    "performer_images",
    "performer_masks",
    "record_clip",
]

FloatArray = NDArray[np.float64]

#: the codec a recording is written in: lossless (FFV1), so that its silhouettes are
#: read back as they were rendered (its container is chosen by the file's suffix)
RECORDING_FOURCC = "FFV1"


@dataclass(frozen=True)
class RecordSettings:
    """How the performer is filmed. Defaults differ from the bank's on purpose."""

    body: BodyShape = field(default_factory=lambda: BodyShape(width=1.15, height=0.97))
    azimuth: float = 10.0  # degrees: half-way between two ring views
    camera_height: float = 1.0
    target_height: float = 0.9
    distance: float = 3.5
    fov_y: float = 50.0
    width: int = 320
    height: int = 240
    edge_noise: float = 1.0  # pixels of ragged edge
    holes: int = 3  # small holes per frame
    shadow: bool = True
    seed: int = 0
    #: a colour video of the shaded body (``performer_images``) instead of silhouettes
    colour: bool = False
    #: the colour video's background (BGR)
    background: tuple[int, int, int] = (100, 110, 90)
    #: degrees the camera moves round the performer over the recording (a performer who
    #: turns from facing it to showing it their side: 90)
    turn: float = 0.0

    def __post_init__(self) -> None:
        for name in ("azimuth", "turn", "camera_height", "target_height", "distance"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(
                    f"the recording's {name} must be a finite number, not {getattr(self, name)}"
                )
        if len(self.background) != 3 or not all(0 <= v <= 255 for v in self.background):
            raise ValueError(f"the background must be 3 values 0-255 (BGR), not {self.background}")

    def ring(self) -> CameraRing:
        return CameraRing(
            n_views=1,
            distance=self.distance,
            height=self.camera_height,
            target_height=self.target_height,
            fov_y=self.fov_y,
            width=self.width,
            height_px=self.height,
            azimuth_offset=self.azimuth,
        )

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["body"] = self.body.to_dict()
        return d


def add_mask_noise(
    mask: NDArray[np.uint8], rng: np.random.Generator, edge: float, holes: int
) -> NDArray[np.uint8]:
    """A clean mask made real: ragged edges and holes (the shadow is drawn before)."""
    m = mask.copy()
    if edge > 0:
        k = max(1, round(edge))
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * k + 1, 2 * k + 1))
        band = cv2.dilate(m, kernel) != cv2.erode(m, kernel)
        flip = band & (rng.random(m.shape) < 0.35)
        m = np.where(flip, 1 - m, m).astype(np.uint8)
    ys, xs = np.nonzero(m)
    for _ in range(holes if ys.size else 0):
        i = int(rng.integers(0, ys.size))
        cv2.circle(m, (int(xs[i]), int(ys[i])), int(rng.integers(1, 3)), 0, -1)
    return m


def performer_masks(
    motion: Motion, settings: RecordSettings | None = None, frames: NDArray[np.int64] | None = None
) -> NDArray[np.uint8]:
    """The performer's masks ``(F, H, W)`` (0/1) of ``frames`` (default all) of
    ``motion``, filmed as ``settings`` says: a static camera on the middle of the action,
    the performer's body, a shadow at the feet, ragged edges and holes."""
    settings = settings or RecordSettings()
    m = motion
    frames = np.arange(m.n_frames) if frames is None else np.asarray(frames, dtype=np.int64)
    ring = settings.ring()
    body = capsule_body(m.skeleton, settings.body)
    seg = capsule_segments(m, body)[frames]
    poses = camera_poses(m, settings, frames)
    b = seg.shape[1]
    cam = ring.to_camera(seg.reshape(-1, b * 2, 3), poses)
    masks = rasterize(cam.reshape(frames.size, b, 2, 3), body.radius, ring)
    ground = m.root_pos[frames].copy()
    ground[:, 1] = 0.0
    ground_cam = ring.to_camera(ground[:, None, :], poses)
    rng = np.random.default_rng(settings.seed)
    out = np.empty_like(masks)
    for i in range(frames.size):
        if settings.shadow:  # the same blob the bank's shadow variants draw
            draw_ground_shadow(masks[i], ring, ground_cam[i, 0])
        out[i] = add_mask_noise(masks[i], rng, settings.edge_noise, settings.holes)
    return out


def camera_poses(motion: Motion, settings: RecordSettings, frames: NDArray[np.int64]) -> FloatArray:
    """The camera's camera-to-world poses ``(F, 4, 4)`` at ``frames``: static, aimed at
    the middle of the action; with ``settings.turn``, it moves round the performer
    (the same as a performer who turns the other way) from ``azimuth`` to ``azimuth +
    turn`` over the frames."""
    centre = motion.root_pos[frames].mean(axis=0)
    if settings.turn == 0.0:
        pose = settings.ring().poses(centre)[0]
        return np.ascontiguousarray(np.broadcast_to(pose, (frames.size, 4, 4)))
    az = settings.azimuth + settings.turn * np.linspace(0.0, 1.0, frames.size)
    return np.array(
        [dataclasses.replace(settings.ring(), azimuth_offset=float(a)).poses(centre)[0] for a in az]
    )


def performer_images(
    motion: Motion, settings: RecordSettings | None = None, frames: NDArray[np.int64] | None = None
) -> Iterator[NDArray[np.uint8]]:
    """BGR images ``(H, W, 3)`` of ``frames`` (default all) of ``motion``: the shaded
    body of ``settings.body``, with a face, seen by the camera (``camera_poses``), on
    ``settings.background``."""
    settings = settings or RecordSettings()
    frames = np.arange(motion.n_frames) if frames is None else np.asarray(frames, dtype=np.int64)
    poses = camera_poses(motion, settings, frames)
    sub = dataclasses.replace(motion, root_pos=motion.root_pos[frames], quats=motion.quats[frames])
    body = capsule_body(motion.skeleton, settings.body)
    back = np.array(settings.background, dtype=np.uint8)
    for img in shaded_frames(sub, settings.ring(), body=body, camera_poses=poses):
        out = img.copy()
        out[~img.any(axis=2)] = back
        yield out


def record_clip(
    clip: Clip,
    out: str | Path,
    settings: RecordSettings | None = None,
    start: int = 0,
    stop: int | None = None,
) -> dict[str, Any]:
    """Render frames ``[start, stop)`` of ``clip`` (already at the recording's rate) to
    ``out`` (``.mkv``) and ``out`` + ``.json``; returns the sidecar."""
    settings = settings or RecordSettings()
    out = Path(out)
    m = clip.motion
    stop = m.n_frames if stop is None else stop
    if not 0 <= start < stop <= m.n_frames:
        raise ValueError(f"frame range {start}..{stop} is not inside {clip.name} (0..{m.n_frames})")
    ring = settings.ring()
    frames = np.arange(start, stop)
    images: Iterable[NDArray[np.uint8]]
    if settings.colour:
        images = performer_images(m, settings, frames)
    else:
        images = (x * 255 for x in performer_masks(m, settings, frames))
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.stem}.tmp{out.suffix or '.mkv'}")
    size = (ring.width, ring.height_px)
    writer = cv2.VideoWriter(
        str(tmp), cv2.VideoWriter.fourcc(*RECORDING_FOURCC), m.fps, size, settings.colour
    )
    if not writer.isOpened():
        raise OSError(f"{out}: cannot write an FFV1 video here")
    try:
        for img in images:
            writer.write(img)
    except BaseException:
        writer.release()
        tmp.unlink(missing_ok=True)
        raise
    writer.release()
    tmp.replace(out)
    sidecar = {
        "video": out.name,
        "clip": clip.name,
        "source": Path(clip.path).name,
        "fps": m.fps,
        "frames": frames.tolist(),
        "source_frames": [round(float(x), 3) for x in clip.source_frames[frames]],
        "labels": [clip.label_at(int(f)) for f in frames],
        "settings": settings.to_dict(),
        "command": "mimic " + " ".join(shlex.quote(a) for a in sys.argv[1:]) if sys.argv else "",
    }
    with atomic_write(out.with_suffix(out.suffix + ".json")) as fh:
        json.dump(sidecar, fh, indent=1)
    return sidecar
