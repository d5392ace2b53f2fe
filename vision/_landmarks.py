"""Body landmarks on the live side: MediaPipe Pose's 33 points to the pose descriptor.

MediaPipe Pose (the legacy ``solutions.pose`` model, bundled in the wheel) gives 33
landmarks per frame, each with x, y in image fractions and a visibility in [0, 1]. The
pose descriptor uses 12 of them (``silhouette_bank.POSE_JOINTS``: shoulders, elbows,
wrists, hips, knees, ankles). MediaPipe's left and right are the person's own, as the
library's joints are.

Low confidence is handled per landmark (``PoseReader``):

- the torso (both shoulders and both hips) must be seen, else the frame has no pose;
- a limb landmark of low visibility takes its last confident place relative to the torso
  (a wrist behind the back for a moment); once more than ``hold`` seconds of frames in a
  row lack one, the frame has no pose ("half a body in view");
- ``why`` says, for the last frame, why it has no pose.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from silhouette_bank import POSE_JOINTS, PoseDescriptor, get_descriptor

__all__ = ["MEDIAPIPE_INDEX", "PoseReader"]

#: MediaPipe Pose's landmark index of each of ``POSE_JOINTS``
MEDIAPIPE_INDEX = (11, 12, 13, 14, 15, 16, 23, 24, 25, 26, 27, 28)
_TORSO = (0, 1, 6, 7)  # shoulders and hips, in POSE_JOINTS order

FloatArray = NDArray[np.float64]


class PoseReader:
    """Pose-descriptor vectors from landmark arrays, one frame after another.

    ``min_visibility``: a landmark below it is of low confidence; ``hold``: frames a limb
    landmark may be missing in a row before the frame is given up (default: half a
    second at 30 frames/s).
    """

    def __init__(self, min_visibility: float = 0.5, hold: int = 15) -> None:
        if not 0.0 <= min_visibility < 1.0:
            raise ValueError("min_visibility must lie in [0, 1)")
        desc = get_descriptor("pose")
        assert isinstance(desc, PoseDescriptor)
        self.desc = desc
        self.min_visibility = min_visibility
        self.hold = hold
        self._last: FloatArray | None = None  # the last confident normalised landmarks
        self._missing = np.zeros(len(POSE_JOINTS), dtype=np.int64)
        self.why = ""

    def read(self, landmarks: FloatArray | None, size: tuple[int, int]) -> FloatArray:
        """The pose vector ``(26,)`` of one frame's landmarks ``(33, 3)`` (x, y as image
        fractions, visibility; ``None``: nobody found) in an image of ``size`` (width,
        height); all NaN when the frame has no usable pose (``why`` says why)."""
        blank = np.full(self.desc.size, np.nan)
        if landmarks is None:
            self.why = "nobody in view"
            self._missing += 1
            return blank
        lm = np.asarray(landmarks, dtype=np.float64)
        if lm.ndim != 2 or lm.shape[0] < 33 or lm.shape[1] < 3:
            raise ValueError(f"landmarks must be (33, 3) (x, y, visibility), got {lm.shape}")
        pick = lm[list(MEDIAPIPE_INDEX)]
        pts = pick[:, :2] * np.array([size[0], size[1]], dtype=np.float64)
        seen = pick[:, 2] >= self.min_visibility
        if not seen[list(_TORSO)].all():
            self.why = "torso landmarks of low confidence"
            self._missing += 1
            return blank
        vec = self.desc.from_points(pts)
        if not np.isfinite(vec).all():
            self.why = "degenerate torso"
            return blank
        shape = vec[: self.desc.n_shape].reshape(-1, 2)
        self._missing = np.where(seen, 0, self._missing + 1)
        lost = ~seen
        if lost.any():
            if self._last is None or (self._missing[lost] > self.hold).any():
                self.why = "half a body in view (limb landmarks of low confidence)"
                return blank
            shape[lost] = self._last[lost]
        self._last = shape.copy()
        vec[: self.desc.n_shape] = shape.ravel()
        self.why = ""
        return vec
