"""Body landmarks on the live side: MediaPipe Pose's 33 points to the pose descriptor.

MediaPipe Pose (the legacy ``solutions.pose`` model, bundled in the wheel) gives 33
landmarks per frame, each with x, y in image fractions and a visibility in [0, 1]. The
pose descriptor uses 12 of them (``silhouette_bank.POSE_JOINTS``: shoulders, elbows,
wrists, hips, knees, ankles). MediaPipe's left and right are the person's own, as the
library's joints are.

Low confidence is handled per landmark (``PoseReader``):

- the torso (both shoulders and both hips) must be seen, else the frame has no pose;
- a limb landmark of low visibility is information, not a reason to give the frame up:
  the model still places it (where the body it sees implies it is), and that place is
  used. A performer seen from the side hides the far arm and leg for the whole take, a
  bend hides the legs, a turn hides one side after the other; all are matched.
  ``visibility`` keeps each landmark's confidence and ``hidden`` names those under
  ``min_visibility``, for the decision log;
- ``upright`` says whether the shoulders are above the hips in the image: where the
  landmarks match nothing, a silhouette (which cannot tell up from down) may decide only
  for an upright body (``vision._fallback``);
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
_TORSO_NAMES = frozenset(POSE_JOINTS[j] for j in _TORSO)
_LIMBS = len(POSE_JOINTS) - len(_TORSO)

FloatArray = NDArray[np.float64]


class PoseReader:
    """Pose-descriptor vectors from landmark arrays, one frame after another.

    ``min_visibility``: a landmark below it is of low confidence (the torso's must not
    be; a limb's is named in ``hidden``).
    """

    def __init__(self, min_visibility: float = 0.5) -> None:
        if not 0.0 <= min_visibility < 1.0:
            raise ValueError("min_visibility must lie in [0, 1)")
        desc = get_descriptor("pose")
        assert isinstance(desc, PoseDescriptor)
        self.desc = desc
        self.min_visibility = min_visibility
        #: the last frame's visibility of each of ``POSE_JOINTS`` ``(12,)`` (NaN: nobody)
        self.visibility = np.full(len(POSE_JOINTS), np.nan)
        #: ``POSE_JOINTS`` of the last frame under ``min_visibility``
        self.hidden: tuple[str, ...] = ()
        #: whether the last frame's shoulders are above its hips in the image
        self.upright = False
        self.why = ""

    @property
    def limbs_hidden(self) -> float:
        """The share of the last frame's limb landmarks (those past the torso) of low
        confidence; 1 where the frame has no pose."""
        if self.why or not np.isfinite(self.visibility).all():
            return 1.0
        return sum(1 for j in self.hidden if j not in _TORSO_NAMES) / _LIMBS

    def read(self, landmarks: FloatArray | None, size: tuple[int, int]) -> FloatArray:
        """The pose vector ``(26,)`` of one frame's landmarks ``(33, 3)`` (x, y as image
        fractions, visibility; ``None``: nobody found) in an image of ``size`` (width,
        height); all NaN when the frame has no usable pose (``why`` says why)."""
        blank = np.full(self.desc.size, np.nan)
        self.visibility[:] = np.nan
        self.hidden = ()
        self.upright = False
        if landmarks is None:
            self.why = "nobody in view"
            return blank
        lm = np.asarray(landmarks, dtype=np.float64)
        if lm.ndim != 2 or lm.shape[0] < 33 or lm.shape[1] < 3:
            raise ValueError(f"landmarks must be (33, 3) (x, y, visibility), got {lm.shape}")
        pick = lm[list(MEDIAPIPE_INDEX)]
        self.visibility[:] = pick[:, 2]
        seen = pick[:, 2] >= self.min_visibility
        self.hidden = tuple(POSE_JOINTS[j] for j in np.flatnonzero(~seen))
        if not seen[list(_TORSO)].all():
            self.why = "torso landmarks of low confidence"
            return blank
        pts = pick[:, :2] * np.array([size[0], size[1]], dtype=np.float64)
        self.upright = bool(pts[[0, 1], 1].mean() < pts[[6, 7], 1].mean())  # (y downwards)
        vec = self.desc.from_points(pts)
        if not np.isfinite(vec).all():
            self.why = "degenerate torso"
            return blank
        self.why = ""
        return vec
