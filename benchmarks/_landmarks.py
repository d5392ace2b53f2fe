"""A performer's body landmarks as a pose model would give them, for the pose descriptor's
benchmarks: the take's 12 joints (``silhouette_bank.POSE_JOINTS``) on the recording's
body (its proportions), projected by the recording's camera (``vision.RecordSettings``:
the same cameras ``mimic record`` films with), with landmark noise of a fraction of
the torso length, and each joint's visibility, that of the recording's body
(``silhouette_bank.pose_visibility``: what it hides from that camera).

These see every joint, hidden or not, where the model guesses: ``benchmarks/bench_views``
runs the real model on rendered video instead."""

from __future__ import annotations

import numpy as np

from control.motion import Motion
from silhouette_bank import pose_visibility, with_proportions
from silhouette_bank._pose import joint_points
from vision import MEDIAPIPE_INDEX, Frame, RecordSettings, camera_poses

__all__ = ["LandmarkSource", "landmark_points", "simulated_landmarks"]

#: the shoulders and hips in ``POSE_JOINTS``
TORSO = (0, 1, 6, 7)
#: landmark noise, in torso lengths (what the recognition benchmark's folds use)
NOISE = 0.03


def simulated_landmarks(
    motion: Motion,
    rs: RecordSettings,
    rng: np.random.Generator,
    noise: float = NOISE,
    frames: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Image points ``(F, 12, 2)`` (pixels, x right, y down) of the performer's joints
    at ``frames`` (default all) seen by ``rs``'s camera (``vision.camera_poses``), with
    Gaussian noise of ``noise`` torso lengths, and their visibility ``(F, 12)``."""
    frames = np.arange(motion.n_frames) if frames is None else np.asarray(frames)
    ring = rs.ring()
    pts = joint_points(with_proportions(motion, rs.body), frames)  # (another person's limbs)
    poses = camera_poses(motion, rs, frames)
    cam = ring.to_camera(pts, poses)
    px = ring.project(cam)
    torso = np.linalg.norm(px[:, :2].mean(axis=1) - px[:, 6:8].mean(axis=1), axis=-1)
    vis = pose_visibility(motion, poses[:, None], frames, rs.body)[:, 0]
    # a pose model sees the torso from every side (MediaPipe gave the shoulders and hips
    # of our rendered performers a visibility of 1.00 from 0 to 180 degrees): only the
    # limbs' visibility follows the body's
    vis[:, list(TORSO)] = 1.0
    noisy = px + rng.normal(0.0, noise, px.shape) * torso[:, None, None]
    return np.asarray(noisy), np.asarray(vis, dtype=np.float64)


def landmark_points(
    motion: Motion,
    rs: RecordSettings,
    rng: np.random.Generator,
    noise: float = NOISE,
    frames: np.ndarray | None = None,
) -> np.ndarray:
    """The image points ``(F, 12, 2)`` of ``simulated_landmarks``."""
    return simulated_landmarks(motion, rs, rng, noise, frames)[0]


class LandmarkSource:
    """Frames that carry landmarks ``(33, 3)`` (MediaPipe Pose's layout) instead of
    pictures: ``points`` ``(F, 12, 2)`` at ``fps``, with their ``visibility`` ``(F, 12)``
    (default: every landmark seen), and with ``masks`` (at ``mask_fps``) the person's
    mask too, as a pose model gives both in one pass."""

    def __init__(
        self,
        points: np.ndarray,
        fps: float,
        name: str = "landmarks",
        visibility: np.ndarray | None = None,
        masks: list[np.ndarray] | None = None,
        mask_fps: float = 0.0,
    ) -> None:
        self.points, self.fps, self.name = np.asarray(points, dtype=np.float64), fps, name
        n = self.points.shape[0]
        self.visibility = np.ones((n, 12)) if visibility is None else np.asarray(visibility)
        self.masks, self.mask_fps = masks, mask_fps
        self.i = 0

    def read(self) -> Frame | None:
        if self.i >= self.points.shape[0]:
            return None
        lm = np.zeros((33, 3))
        lm[list(MEDIAPIPE_INDEX), :2] = self.points[self.i]
        lm[list(MEDIAPIPE_INDEX), 2] = self.visibility[self.i]
        mask = None
        if self.masks:  # the mask shown at this frame's time
            k = min(int(self.i / self.fps * self.mask_fps + 1e-6), len(self.masks) - 1)
            mask = self.masks[k]
        frame = Frame(t=self.i / self.fps, index=self.i, landmarks=lm, mask=mask)
        self.i += 1
        return frame

    def close(self) -> None:
        pass
