"""The silhouette when the landmarks fail (issue 59): one pass of the pose model gives
both a person mask and landmarks, and the landmarks can fail while the mask is good (the
torso hidden or cut by the frame's edge, too dark to read, the limbs misplaced). A
performer the camera sees is then matched by their silhouette rather than left
unfollowed.

``SilhouetteFallback`` keeps the performer's silhouette features at the library's rate
beside the landmark features, and a second matcher on a silhouette bank of the same
clips. The landmark matcher decides whenever it can; when it cannot for want of a pose
(fewer than half the window's frames with a usable one), or its landmarks match nothing
(``no match``) while the last frame's body is upright (shoulders above hips:
``PoseReader.upright``), the silhouette matcher decides from the same avatar frame, with
its own reject threshold: a silhouette that matches nothing real is still refused. The
pose model misplaces limbs now and then (for a second at a time, from some views) where
the mask stays whole. Landmarks of a body upside down are not overruled: a silhouette,
which cannot tell up from down, matched upside-down jumping jacks at half the decision
points where the landmarks refused them (``tests/vision/test_views.py``). Both matchers
cast their votes into one ``ActionVote``, so that the avatar's action does not restart
when the evidence changes hands. The decision log says which decided (``by``). With
``ActionSettings.fuse`` (the default) the silhouette also speaks at the landmark
decisions whose window has limb landmarks of low confidence: its action scores are
weighed into the landmarks' ballot, the more the more limbs are hidden (``evidence``,
``vision._vote.fused``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from control.avatar import Avatar, JumpCosts
from control.clusters import HigherLayer
from control.motion import Clip
from silhouette_bank import Bank, silhouette_features

from ._decision import Decision
from ._matcher import Matcher
from ._person import MAX_SIDE
from ._search import Bars
from ._second import SecondMatcher
from ._vote import ActionVote

__all__ = ["FALLBACK_REASONS", "UPRIGHT_REASONS", "SilhouetteFallback"]

#: the landmark matcher's reasons (``Matcher.why``, up to " (") after which the
#: silhouette is tried: a person may be in view, and nothing was read of them
FALLBACK_REASONS = ("no pose",)
#: those after which it is tried only for an upright body (``PoseReader.upright``)
UPRIGHT_REASONS = ("no match",)

#: the share of a window's limb landmarks of low confidence at which the silhouette's
#: evidence weighs in full beside the landmarks (``SilhouetteFallback.evidence``): a
#: performer seen from the side, the far arm and leg hidden, is at about a half
HIDDEN_FULL = 0.25

FloatArray = NDArray[np.float64]


class SilhouetteFallback(SecondMatcher["_Seen"]):
    """The silhouette matcher beside a landmark matcher ``main`` of the same graph, with
    its settings, for the ``avatar`` (``costs``: its jump costs) of a loop deciding every
    ``period`` seconds. ``bank``: a silhouette bank of the graph's ``clips``. Made
    before the first frame, as ``main`` is (its search index, classifier and kernels
    warmed up), so that the first frame without landmarks does not stall the loop;
    ``bars``: progress bars for its search's tables and index (``WindowSearch.open``).
    Its history holds the performer's masks, in step with the landmark features'."""

    def __init__(
        self,
        layer: HigherLayer,
        bank: Bank,
        clips: Sequence[Clip],
        main: Matcher,
        avatar: Avatar,
        costs: JumpCosts,
        period: float,
        bars: Bars | None = None,
    ) -> None:
        super().__init__(layer, bank, main, "silhouette", "the fallback")
        self.latest = _Seen(None)
        matcher = self.matcher
        if matcher.settings.landing.jumps:
            matcher.windows.open(bars, "search (fallback)")
            matcher.warm_up(avatar.frame, avatar.recent(matcher.recent_frames), costs)
        matcher.ready(clips, period)
        #: the history held under a window at the last ``decide``
        self.filling = False
        #: the weight of the evidence given since ``weight_given`` was last asked
        self._weighed = 0.0

    def see(self, mask: NDArray[np.bool_] | None, hidden: float = 1.0) -> None:
        """The latest frame's person mask (``None``: none), and the share of the limb
        landmarks the pose model saw it with that were of low confidence (1: no pose)."""
        self.latest = _Seen(mask if mask is not None and mask.any() else None, hidden)

    def features(self, last: int | None = None) -> FloatArray:
        """The silhouette features ``(m, F)`` of the history (its ``last`` frames)."""
        return np.array([s.features(self.matcher.desc, self.blank) for s in self.last(last)])

    def decide(
        self, frame: int, recent: NDArray[np.int64] | None, costs: JumpCosts | None
    ) -> Decision | None:
        """The silhouette matcher's decision from the avatar at ``frame`` (``None``, and
        ``why``, without one)."""
        matcher = self.matcher
        self.filling = not self.full
        if self.filling:
            return None
        if matcher.settings.landing.jumps:
            return matcher.decide(frame, self.features(), recent, costs)
        return matcher.decide(frame, self.features(matcher.n))

    def hidden(self, last: int) -> float:
        """The share of limb landmarks of low confidence over the history's ``last``
        frames (``see``)."""
        seen = self.last(last)
        return float(np.mean([s.hidden for s in seen])) if seen else 1.0

    def evidence(self, vote: ActionVote) -> tuple[FloatArray, float, float] | None:
        """The silhouette's action scores for ``vote`` over its last window, its fit
        (``ActionChoice.scores``) and its weight: what the landmarks' ballot weighs
        beside its own with ``ActionSettings.fuse``. The weight grows with the window's
        share of limb landmarks of low confidence, to 1 at ``HIDDEN_FULL``: the pose
        model's limbs are then guesses and the mask shows them; with every limb seen
        (a performer facing the camera) the silhouette does not speak (``None``), nor
        while the window is not yet full or its silhouettes are too few."""
        n = self.matcher.n
        if not self.full or (weight := min(1.0, self.hidden(n) / HIDDEN_FULL)) <= 0:
            return None
        got = self.matcher.action_scores(vote, self.features(n))
        if got is None:
            return None
        self._weighed = weight
        return (*got, weight)

    def weight_given(self) -> float:
        """The weight of the evidence given to the landmarks' ballot since the last ask
        (0: none; the decision log's ``silhouette_weight``)."""
        weight, self._weighed = self._weighed, 0.0
        return weight

    @property
    def why(self) -> str:
        """Why the last ``decide`` gave nothing ("" when it gave a decision)."""
        return "filling buffer" if self.filling else self.matcher.why


def _at_most(mask: NDArray[np.bool_], side: int) -> NDArray[np.bool_]:
    """``mask`` scaled down (by area) to at most ``side`` pixels on its longest side: the
    person model's own resolution. A silhouette's features are taken from its bounding
    box in cells, so they hardly change, and a 720x1280 mask's cost 10 ms a frame
    against 2 ms (with ``ActionSettings.fuse``, every frame's are taken while limbs are
    hidden)."""
    h, w = mask.shape
    if max(h, w) <= side:
        return mask
    f = side / max(h, w)
    size = (max(1, round(w * f)), max(1, round(h * f)))
    small = cv2.resize(mask.astype(np.uint8) * 255, size, interpolation=cv2.INTER_AREA)
    return np.asarray(small >= 128)  # (a pixel at least half covered)


class _Seen:
    """A frame's person mask, and its silhouette features, made on first use: the
    features cost 1-3 ms a frame (the mask scaled to at most 640 pixels first:
    ``_at_most``), and while the landmarks serve alone (every limb seen, or
    ``ActionSettings.fuse`` off) they are never needed. ``hidden``: the share of the
    frame's limb landmarks of low confidence. A frame ticked twice into the history is
    one object, its features made once."""

    __slots__ = ("_features", "hidden", "mask")

    def __init__(self, mask: NDArray[np.bool_] | None, hidden: float = 1.0) -> None:
        self.mask, self.hidden = mask, hidden
        self._features: FloatArray | None = None

    def features(self, desc: Any, blank: FloatArray) -> FloatArray:
        if self._features is None:
            mask = None if self.mask is None else _at_most(self.mask, MAX_SIDE)
            made = blank if mask is None else silhouette_features(mask, descriptor=desc)
            self._features, self.mask = made, None  # (the mask is not needed again)
        return self._features
