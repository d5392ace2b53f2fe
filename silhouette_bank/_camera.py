"""The ring of cameras around the avatar (Lee et al. §5.3: 18 views, every 20 degrees).

Glossary as in ``control.motion._quat``; cameras follow the OpenGL convention: a camera
looks down its -Z axis with +Y up; image pixels have x right and y down.

Every camera looks at a point ``target_height`` above the floor below the avatar's root,
from ``distance`` metres away horizontally and ``height`` metres above the floor, like a
webcam on a tripod. View ``v`` sits at azimuth ``v * 360 / n_views`` degrees about +Y,
measured from +Z. The ring follows the root horizontally, so the avatar stays in view;
the root's own image motion is kept separately in the bank.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["CameraRing"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class CameraRing:
    """Camera settings shared by every view.

    Attributes
    ----------
    n_views : cameras on the ring (18).
    distance : metres from the root, horizontally (3.5).
    height : camera height above the floor, metres (1.2).
    target_height : the point looked at, metres above the floor (0.9).
    fov_y : vertical field of view, degrees (50).
    width, height_px : image size in pixels (160 x 120).
    azimuth_offset : degrees added to every view's azimuth (0: view 0 on +Z).
    """

    n_views: int = 18
    distance: float = 3.5
    height: float = 1.2
    target_height: float = 0.9
    fov_y: float = 50.0
    width: int = 160
    height_px: int = 120
    azimuth_offset: float = 0.0

    def __post_init__(self) -> None:
        if self.n_views < 1 or self.width < 8 or self.height_px < 8:
            raise ValueError("a ring needs at least one view and images of 8 x 8 or more")
        if not (self.distance > 0 and 1.0 <= self.fov_y <= 170.0):
            raise ValueError("distance must be positive and fov_y in 1..170 degrees")

    def to_dict(self) -> dict[str, float]:
        return asdict(self)

    @property
    def focal(self) -> float:
        """Focal length in pixels."""
        return 0.5 * self.height_px / np.tan(np.radians(self.fov_y) / 2.0)

    @property
    def centre(self) -> tuple[float, float]:
        """Principal point in pixels."""
        return 0.5 * self.width, 0.5 * self.height_px

    def azimuths(self) -> FloatArray:
        return np.radians(np.arange(self.n_views) * 360.0 / self.n_views + self.azimuth_offset)

    def poses(self, root: FloatArray) -> FloatArray:
        """Camera-to-world transforms ``(..., V, 4, 4)`` for root positions ``(..., 3)``."""
        root = np.asarray(root, dtype=np.float64)
        az = self.azimuths()
        lead = root.shape[:-1]
        eye = np.zeros((*lead, self.n_views, 3))
        eye[..., 0] = root[..., None, 0] + self.distance * np.sin(az)
        eye[..., 1] = self.height
        eye[..., 2] = root[..., None, 2] + self.distance * np.cos(az)
        target = np.zeros((*lead, 1, 3))
        target[..., 0] = root[..., None, 0]
        target[..., 1] = self.target_height
        target[..., 2] = root[..., None, 2]
        back = eye - target  # camera +Z points away from the target
        back /= np.linalg.norm(back, axis=-1, keepdims=True)
        right = np.cross(np.array([0.0, 1.0, 0.0]), back)
        right /= np.linalg.norm(right, axis=-1, keepdims=True)
        up = np.cross(back, right)
        out = np.zeros((*lead, self.n_views, 4, 4))
        out[..., :3, 0] = right
        out[..., :3, 1] = up
        out[..., :3, 2] = back
        out[..., :3, 3] = eye
        out[..., 3, 3] = 1.0
        return out

    @staticmethod
    def to_camera(points: FloatArray, pose: FloatArray) -> FloatArray:
        """World points ``(..., N, 3)`` in the frame of camera ``pose`` (``(..., 4, 4)``)."""
        r = pose[..., :3, :3]
        t = pose[..., :3, 3]
        return np.einsum("...ji,...nj->...ni", r, points - t[..., None, :])

    def project(self, cam_points: FloatArray) -> FloatArray:
        """Pixel coordinates ``(..., 2)`` of camera-frame points ``(..., 3)`` (z < 0)."""
        f = self.focal
        cx, cy = self.centre
        z = -cam_points[..., 2]
        return np.stack((cx + f * cam_points[..., 0] / z, cy - f * cam_points[..., 1] / z), -1)
