"""A second matcher beside the performance's own, on a bank of the other descriptor.

Both ``SilhouetteFallback`` (the silhouette beside a camera's landmarks) and
``PoseVoice`` (the landmarks read from a silhouette video's masks) are this: a matcher on
the same graph and settings as the performance's, casting its votes into the same
``ActionVote`` (so that the avatar's action does not restart when the evidence changes
hands), with the performer's features of its own descriptor kept at the library's rate,
in step with the main matcher's history.
"""

from __future__ import annotations

import itertools
from collections import deque
from typing import Generic, TypeVar

import numpy as np
from numpy.typing import NDArray

from control.clusters import HigherLayer
from silhouette_bank import Bank

from ._matcher import Matcher

__all__ = ["SecondMatcher"]

FloatArray = NDArray[np.float64]
#: what each library frame of the history holds
Seen = TypeVar("Seen")


class SecondMatcher(Generic[Seen]):
    """The matcher on ``bank`` (of the descriptor kind ``kind``: "pose" or "silhouette",
    else a ``ValueError`` that names ``what`` needs it) beside ``main``, and the history
    of what was seen, one entry a library frame: ``latest`` (which the subclass sets
    from each frame) until the next ``tick``."""

    #: what the latest frame showed
    latest: Seen

    def __init__(self, layer: HigherLayer, bank: Bank, main: Matcher, kind: str, what: str) -> None:
        if bank.settings.features.kind != kind:
            raise ValueError(
                f"{what} needs a {kind} bank, not one of the "
                f"{bank.settings.descriptor!r} descriptor"
            )
        self.matcher = Matcher(layer, bank, main.settings, vote=main.vote)
        #: a frame's features where nothing was seen
        self.blank: FloatArray = np.full(self.matcher.n_features, np.nan)
        #: what was seen at the library's rate, in step with the main matcher's history
        self.history: deque[Seen] = deque(maxlen=self.matcher.history_frames)

    def tick(self) -> None:
        """One library frame on: the latest seen into the history."""
        self.history.append(self.latest)

    def last(self, n: int | None = None) -> list[Seen]:
        """The history's last ``n`` frames (``None``: all of it)."""
        size = len(self.history)
        start = 0 if n is None else max(0, size - n)
        return list(itertools.islice(self.history, start, size))

    @property
    def full(self) -> bool:
        """Whether the history holds a whole window."""
        return len(self.history) >= self.matcher.n
