"""A performer's body landmarks as a pose model would give them, for the pose descriptor's
benchmarks: the take's 12 joints (``silhouette_bank.POSE_JOINTS``) on the recording's
body (its proportions), projected by the recording's camera (``vision.RecordSettings``:
the same static camera ``mimic record`` films with), with landmark noise of a fraction of
the torso length."""

from __future__ import annotations

import numpy as np

from control.motion import Motion
from silhouette_bank import with_proportions
from silhouette_bank._pose import joint_points
from vision import MEDIAPIPE_INDEX, Frame, RecordSettings

__all__ = ["LandmarkSource", "landmark_points"]

#: landmark noise, in torso lengths (what the recognition benchmark's folds use)
NOISE = 0.03


def landmark_points(
    motion: Motion,
    rs: RecordSettings,
    rng: np.random.Generator,
    noise: float = NOISE,
    frames: np.ndarray | None = None,
) -> np.ndarray:
    """Image points ``(F, 12, 2)`` (pixels, x right, y down) of the performer's joints
    at ``frames`` (default all) seen by ``rs``'s camera (static, on the middle of those
    frames), with Gaussian noise of ``noise`` torso lengths."""
    frames = np.arange(motion.n_frames) if frames is None else np.asarray(frames)
    ring = rs.ring()
    pts = joint_points(with_proportions(motion, rs.body), frames)  # (another person's limbs)
    pose = ring.poses(motion.root_pos[frames].mean(axis=0))[0]
    px = ring.project(ring.to_camera(pts, np.broadcast_to(pose, (pts.shape[0], 4, 4))))
    torso = np.linalg.norm(px[:, :2].mean(axis=1) - px[:, 6:8].mean(axis=1), axis=-1)
    return np.asarray(px + rng.normal(0.0, noise, px.shape) * torso[:, None, None])


class LandmarkSource:
    """Frames that carry landmarks ``(33, 3)`` (MediaPipe Pose's layout, every landmark
    seen) instead of pictures: ``points`` ``(F, 12, 2)`` at ``fps``."""

    def __init__(self, points: np.ndarray, fps: float, name: str = "landmarks") -> None:
        self.points, self.fps, self.name = np.asarray(points, dtype=np.float64), fps, name
        self.i = 0

    def read(self) -> Frame | None:
        if self.i >= self.points.shape[0]:
            return None
        lm = np.zeros((33, 3))
        lm[list(MEDIAPIPE_INDEX), :2] = self.points[self.i]
        lm[list(MEDIAPIPE_INDEX), 2] = 1.0
        frame = Frame(t=self.i / self.fps, index=self.i, landmarks=lm)
        self.i += 1
        return frame

    def close(self) -> None:
        pass
