"""The action vote (issue 17): which action the performer is doing, by the best windows of
the last decisions.

One decision's best window can be wrong (another action that looks alike for a moment);
the performer's action lasts seconds. So on a library whose clips are labelled, the
action of each decision's best window (its label; an unlabelled clip counts as an action
of its own) is a vote, and the avatar jumps only into windows of the action most voted
for over the last ``MatchSettings.vote`` decisions, and leaves at once a motion that is
not that action, or will have played on out of it within half a window.
"""

from __future__ import annotations

from collections import Counter, deque

import numpy as np
from numpy.typing import NDArray

__all__ = ["ActionVote"]

IntArray = NDArray[np.int64]


class ActionVote:
    """The vote over the last ``size`` decisions (0: none); a window counts for its action
    only when it still shows it ``span`` frames on."""

    def __init__(self, size: int, span: int) -> None:
        self.size, self.span = size, span
        #: the action of every graph frame (``vision.action_keys``); ``None``: the library
        #: names no actions, and nothing is voted
        self.actions: IntArray | None = None
        self._votes: deque[int] = deque(maxlen=max(1, size))
        #: the action most voted for (-1: none yet)
        self.voted = -1

    def cast(self, target: IntArray) -> NDArray[np.bool_] | None:
        """The best window's vote (``target``: the frames after the best windows, best
        first), and which of them show the action most voted for and still show it
        ``span`` frames on (``None`` without a vote). The voted action changes only when
        another has more votes (to the one of them voted for last)."""
        if self.actions is None or self.size <= 0:
            return None
        last = self.actions.size - 1
        keys = self.actions[np.clip(target, 0, last)]
        self._votes.append(int(keys[0]))
        counts = Counter(self._votes)
        top = max(counts.values())
        if counts.get(self.voted, 0) < top:
            self.voted = next(k for k in reversed(self._votes) if counts[k] == top)
        ahead = self.actions[np.clip(target + self.span, 0, last)]
        return np.asarray((keys == self.voted) & (ahead == self.voted))

    def leaves(self, frame: int, ahead: int) -> bool:
        """Whether an avatar at ``frame``, which plays on to ``ahead`` (``span`` frames on,
        or its clip's end), shows another action than the voted one at either."""
        assert self.actions is not None
        return {int(self.actions[frame]), int(self.actions[ahead])} != {self.voted}
