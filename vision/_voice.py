"""The landmarks a pose model reads from a silhouette, as a second voice in the
silhouette's ballot.

A silhouette of another person than the library's performer looks unlike the
library's own at the same action (one person's knee raise or twist fills the grid's
cells otherwise than another's), while body landmarks carry over from one person to
another. A silhouette is also a picture: painted dark on light, it is one a pose model
reads, and it finds a body in nearly every frame. What it finds is what the outline
shows: arms circled in front of the body seen from the front are read as nothing in
particular, so its landmarks alone follow the library's own performer worse than the
silhouette does (``benchmarks/HISTORY.md``, "Views and people").

So the silhouette matcher decides and lands, and ``PoseVoice`` weighs in where the
silhouette is unsure: a second matcher on a pose bank of the same clips scores every
action from the landmarks read from the last window of silhouettes, and the silhouette's
ballot takes the mean of the two descriptors' action scores (``vision._vote.fused``),
the landmarks' weighing as much as the silhouette's where its best two actions tie and
nothing where its best leads (``vision._vote.unsure``). Their fits are on scales of
their own, so neither is weighed by its fit. Both cast their vote into one
``ActionVote``.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np
from numpy.typing import NDArray

from control.clusters import HigherLayer
from control.motion import Clip
from silhouette_bank import Bank

from ._landmarks import PoseReader
from ._matcher import Matcher
from ._person import PersonSegmenter
from ._search import Bars
from ._second import SecondMatcher
from ._vote import ActionVote, Evidence

__all__ = ["PoseVoice", "paint"]

FloatArray = NDArray[np.float64]

#: the grey of the figure and of the ground a silhouette is painted in (BGR alike)
FIGURE, GROUND = 0, 255
#: the blur a painted silhouette gets, in pixels per 160 pixels of frame height: a
#: hard-edged silhouette with ragged edges is unlike the pictures the model learned from,
#: and softened a little (and in full contrast) it found a body in more of the frames
#: tried (``benchmarks/HISTORY.md``, "Views and people")
BLUR_PER_160 = 1.0


def paint(mask: NDArray[np.bool_]) -> NDArray[np.uint8]:
    """A picture ``(H, W, 3)`` of ``mask``: the person dark on a light ground, softened
    by a blur that grows with the frame's height, for a pose model to read."""
    img = np.full((*mask.shape, 3), GROUND, dtype=np.uint8)
    img[mask] = FIGURE
    sigma = max(1.0, BLUR_PER_160 * mask.shape[0] / 160.0)
    return np.asarray(cv2.GaussianBlur(img, (0, 0), sigma), dtype=np.uint8)


class PoseVoice(SecondMatcher[FloatArray]):
    """The pose matcher beside a silhouette matcher ``main`` of the same graph, with its
    settings: ``bank`` a pose bank of the graph's ``clips``, for a loop deciding every
    ``period`` seconds. ``see`` each frame's mask, ``tick`` at the library's rate, and
    ``evidence`` at each decision (the silhouette's ballot's ``Partner``). Its history
    holds the landmark features read from the masks."""

    def __init__(
        self,
        layer: HigherLayer,
        bank: Bank,
        clips: Sequence[Clip],
        main: Matcher,
        period: float,
        bars: Bars | None = None,
    ) -> None:
        super().__init__(layer, bank, main, "pose", "the landmarks' voice")
        self.latest = self.blank
        self.matcher.windows.open(bars, "search (landmarks of the silhouette)")
        self.matcher.ready(clips, period)
        self.model = PersonSegmenter("pose", masks=False)  # (the silhouette is the mask)
        self.reader = PoseReader()
        #: silhouettes read since ``read_share`` was last asked, and those with a body
        #: found in them
        self._seen = self._read = 0

    def see(self, mask: NDArray[np.bool_] | None) -> None:
        """The latest frame's silhouette (``None``: none), its landmarks read now. Every
        frame is read, not only those the library's rate keeps: the pose model tracks
        the body from one frame to the next, and a take of the library's own performer
        read at 15 frames a second was followed a little worse (``benchmarks/HISTORY.md``)."""
        self.latest = self.blank
        if mask is None or not mask.any():
            return
        image = paint(mask)
        landmarks = self.model.landmarks_of(image)
        vec = self.reader.read(landmarks, (image.shape[1], image.shape[0]))
        self._seen += 1
        if np.isfinite(vec).all():
            self.latest = vec
            self._read += 1

    def read_share(self) -> float:
        """The share of the silhouettes read since the last ask in which the model
        found a body (NaN: none read), for the decision log."""
        share = self._read / self._seen if self._seen else float("nan")
        self._seen = self._read = 0
        return share

    def evidence(self, vote: ActionVote) -> Evidence | None:
        """The landmarks' action scores for ``vote`` over the last window, no fit (the
        two descriptors weigh alike) and a weight of 1; ``None`` while the window is
        not full or holds too few frames with a body read."""
        if not self.full:
            return None
        got = self.matcher.action_scores(vote, np.array(self.last(self.matcher.n)))
        if got is None:
            return None
        return got[0], None, 1.0
