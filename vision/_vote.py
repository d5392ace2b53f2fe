"""The action vote (issue 17): which action the performer is doing, by the best windows of
the last decisions.

One decision's best window can be wrong (another action that looks alike for a moment);
the performer's action lasts seconds. So on a library whose clips are labelled, each
decision votes for an action (a label; an unlabelled clip counts as an action of its
own): its best window's, or as the library's action classifier settles it between the
best windows of the actions (``vision._classify``, ``ActionChoice``), and the avatar
keeps to the action most voted for over the last ``ActionSettings.vote`` decisions (or
voted for by the last third of them, all alike: a new action is taken up in 0.5 s, not
when it has outvoted the old one), and leaves a motion that is not that action, or will
have played on out of it within half a window. When none of a decision's best windows
shows the voted action, the matcher searches the windows that do (``starts``). The vote
weighs rather than forbids (``ActionSettings.margin``, 0.2): a window of another
action, and the avatar's own motion of another action, cost 1.2 times as much, so the
avatar takes one only where it fits the performer far better (the library's labels are
coarser than its poses); with the margin infinite the avatar never jumps into an action
the performer is not voted to do. Where the last votes agree
(``ActionSettings.strict_share``), a decision's jumps go into the voted action alone, and
an avatar about to play on out of it jumps first (``Lander.strict``). A source slower
than the decisions has decision points skipped (``missed``); each vote then stands for
them too, so that the vote spans the same time at any frame rate.

With ``ActionSettings.switch_chance`` the voted action is not counted but filtered
(``ActionVote.filter``): a hidden (semi-)Markov model over the actions, each decision's
action scores its evidence. It is the default where the ballots hear landmarks (the
pose descriptor, or a silhouette's with the landmarks read from it), whose ballots it
follows steadier and as soon once a decision may jump into its own ballot's action
(``ActionSettings.ballot_jumps``), and plays on in an action a ballot named lately
without the margin (``ActionSettings.ballot_keep``); a silhouette alone keeps the counted
vote, its ballots less sure, which the filter follows late (``ActionSettings.switch_for``).
"""

from __future__ import annotations

import itertools
from collections import Counter, deque
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from ._classify import ActionClassifier, action_scores, cached_action_classifier
from ._search import WindowSearch
from ._settings import ActionSettings, MatchSettings
from ._windows import per_frame_cost, tempo_readings

__all__ = ["ActionChoice", "ActionVote", "Evidence", "Partner", "fused"]

#: how steeply ``fused`` weighs a descriptor by its fit: (reject / per-frame cost) to this
#: power. From the front the pose model's landmarks' best windows cost about 0.3 of their
#: threshold and the silhouette's 0.5, so the landmarks weigh about 60 times as much;
#: from the side and behind the two cost about alike and weigh alike. At 4 the
#: silhouette of another body than the library's still swayed landmarks that were right
#: (``benchmarks/HISTORY.md``, "Both descriptors")
FIT_POWER = 8.0

#: how far (relatively) a ballot's best action must lead the second for a voice without
#: a fit (``Evidence``) to say nothing. With the landmarks read from a silhouette: the
#: silhouettes of the library's own performer mostly lead by more, another person's by
#: less, and with a longer reach the landmarks, blind to what the silhouette hides, cost
#: the library's own performer more (``benchmarks/HISTORY.md``, "Views and people")
UNSURE_LEAD = 0.15
#: decision points ``ActionVote.voted_back`` reaches until a loop's rate is known
#: (``keep_voted``; over ``vision._repeat``'s 3 s at 10 decisions a second)
VOTED_KEPT = 40

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]


class ActionVote:
    """The vote over the last ``size`` decisions (0: none); a window counts for its action
    only when it still shows it ``span`` frames on. ``keep``: how many decision points'
    ballots ``named_lately`` remembers (``ActionSettings.ballot_keep``)."""

    def __init__(
        self,
        size: int,
        span: int,
        switch: float = 0.0,
        temperature: float = 0.1,
        min_stay: int = 1,
        confidence: float = 0.0,
        keep: int = 0,
    ) -> None:
        self.size, self.span = size, span
        #: > 0: ``filter`` decides the voted action (``ActionSettings.switch_chance``)
        self.switch, self.temperature, self.min_stay = switch, temperature, max(1, min_stay)
        self.confidence = confidence
        self._belief: NDArray[np.float64] | None = None
        #: the action of every graph frame (``control.motion.action_keys``); ``None``: the library
        #: names no actions, and nothing is voted
        self.actions: IntArray | None = None
        #: the name of each action number (``control.motion.action_names``)
        self.names: list[str] = []
        self._votes: deque[int] = deque(maxlen=max(1, size))
        #: the action most voted for (-1: none yet)
        self.voted = -1
        #: the action the latest decision's ballot named (-1: none)
        self.named = -1
        #: the actions the ballots of the last ``keep`` decision points named, a skipped
        #: point's too (``named_lately``)
        self.keep = max(0, keep)
        self._lately: deque[int] = deque(maxlen=self.keep)
        #: this many votes in a row for one action make it the voted one at once, before
        #: it has the most votes (a third of the vote: 0.5 s of 1.5 s); the older votes
        #: stay, so one vote more for the old action, while it still has the most, takes
        #: it back
        self.quick = max(2, size // 3)
        #: decision points skipped just before the decision being made (a source slower
        #: than the decisions; ``Performance`` sets it): its vote counts for them too, so
        #: that the vote spans ``size`` decision points of time whatever the frame rate
        self.missed = 0
        self._starts: tuple[tuple[int, int, int], NDArray[np.bool_]] | None = None
        #: the action voted at each of the last decision points, a skipped one's too
        #: (``voted_back``)
        self._past: deque[int] = deque(maxlen=VOTED_KEPT)

    @classmethod
    def of(
        cls,
        settings: ActionSettings,
        span: int,
        actions: IntArray | None = None,
        names: Sequence[str] = (),
        descriptor: str = "",
        voice: bool = False,
    ) -> ActionVote:
        """The vote ``settings`` ask for, over ``actions`` named ``names``, for a matcher
        of ``descriptor``, ``voice``: with the landmarks read from its silhouettes
        (``ActionSettings.switch_for``)."""
        st = settings
        switch = st.switch_for(descriptor, voice)
        vote = cls(
            st.vote, span, switch, st.temperature, st.min_points, st.confidence, st.ballot_keep
        )
        vote.actions, vote.names = actions, list(names)
        return vote

    def skipped(self, points: int) -> None:
        """``points`` decision points were skipped just before the next decision (a
        source slower than the decisions): its vote stands for them too."""
        self.missed = points

    def filter(self, scores: NDArray[np.float64]) -> None:
        """One step of the forward filter of a hidden semi-Markov model over the actions:
        an action once entered lasts at least ``min_stay`` decision points (a chain of
        that many states, each passed in one step), then changes with the chance
        ``switch`` per point (for the points skipped too); each decision's evidence is
        ``exp(-(score - best) / temperature)``. The voted action is the most believed. A
        switch needs evidence that outweighs its prior cost, so one odd decision moves
        nothing, and a new action is not left within ``min_stay`` points."""
        k, m = scores.size, self.min_stay
        if self._belief is None or self._belief.shape != (k, m):
            self._belief = np.full((k, m), 1.0 / (k * m))
        p = self._belief
        for _ in range(1 + self.missed):
            last = p[:, -1]
            leave = self.switch * last
            moved = np.zeros_like(p)
            moved[:, 1:] = p[:, :-1]  # (m == 1: nothing moves along a chain)
            moved[:, -1] += last - leave
            moved[:, 0] += (leave.sum() - leave) / max(k - 1, 1)
            p = moved
        ok = np.isfinite(scores)
        if ok.any():
            # one decision rules no action out: an action without a score (``inf``) has
            # the worst scored action's evidence. Ruled out, the action believed in was
            # dropped whenever its windows fell off the search's short lists for one
            # decision (a sixth of the decisions from the side); ``ActionChoice`` scores
            # such an action at the lists' cutoff instead
            gap = scores - scores[ok].min()
            gap = np.where(ok, gap, gap[ok].max())
            p = p * np.exp(-np.minimum(gap / self.temperature, 50.0))[:, None]
        p = p / p.sum()
        self._belief = p
        self.missed = 0
        belief = p.sum(axis=1)
        best = int(np.argmax(belief))
        # the decision changes only on a belief of at least ``confidence``: where two
        # actions are about as likely, the one voted stays
        if self.voted < 0 or self.voted >= k or belief[best] >= self.confidence:
            self.voted = best

    def cast(
        self,
        target: IntArray,
        choice: int | None = None,
        scores: NDArray[np.float64] | None = None,
    ) -> NDArray[np.bool_] | None:
        """The decision's vote (``choice``, an action; by default the best window's:
        ``target`` holds the frames after the best windows, best first), and which of
        them show the action most voted for and still show it ``span`` frames on
        (``None`` without a vote). The voted action changes when
        another has more votes (to the one of them voted for last), or when the last
        ``quick`` votes are all for another."""
        if self.actions is None or self.size <= 0:
            return None
        points = 1 + self.missed  # (a decision stands for those skipped before it)
        shown = self._cast(target, choice, scores)
        self._past.extend([self.voted] * points)
        return shown

    def _cast(
        self, target: IntArray, choice: int | None, scores: NDArray[np.float64] | None
    ) -> NDArray[np.bool_]:
        """``cast`` for a library with actions, before the voted action is kept."""
        assert self.actions is not None
        self.named = -1 if choice is None else choice
        self._lately.extend([self.named] * min(1 + self.missed, self.keep))
        if self.switch > 0 and scores is not None:
            self.filter(scores)
            return self.gate(target)
        best = choice
        if best is None:
            best = int(self.actions[min(max(int(target[0]), 0), self.actions.size - 1)])
        for _ in range(1 + self.missed):  # (a decision stands for those skipped before it)
            self._votes.append(best)
        self.missed = 0
        counts = Counter(self._votes)
        top = max(counts.values())
        if counts.get(self.voted, 0) < top:
            self.voted = next(k for k in reversed(self._votes) if counts[k] == top)
        q = self.quick
        if len(self._votes) >= q and len(set(itertools.islice(reversed(self._votes), q))) == 1:
            self.voted = self._votes[-1]  # the last ``quick`` votes agree: at once
        return self.gate(target)

    def keep_voted(self, points: int) -> None:
        """Keep the action voted at the last ``points`` decision points (``voted_back``
        reaches that far): a loop deciding more often than 10 times a second needs more
        of them for the same seconds."""
        self._past = deque(self._past, maxlen=max(1, points))

    def voted_back(self, points: int) -> int:
        """The action voted ``points`` decision points ago (1: at the last decision; a
        skipped point counts, a point without a vote does not; -1: none, or further back
        than is kept)."""
        return self._past[-points] if 1 <= points <= len(self._past) else -1

    def named_lately(self, action: int) -> bool:
        """Whether a ballot of the last ``keep`` decision points named ``action``."""
        return action >= 0 and action in self._lately

    def share(self) -> float:
        """The share of the last votes that went to the voted action (0 before any); with
        the filter, how much the voted action is believed."""
        if self._belief is not None and 0 <= self.voted < self._belief.shape[0]:
            return float(self._belief[self.voted].sum())
        if not self._votes or self.voted < 0:
            return 0.0
        return sum(1 for v in self._votes if v == self.voted) / len(self._votes)

    def gate(self, target: IntArray) -> NDArray[np.bool_]:
        """Which of ``target`` show the action voted for and still show it ``span``
        frames on (clipped to the library's last frame)."""
        keys, ahead = self._shown(target)
        return np.asarray((keys == self.voted) & (ahead == self.voted))

    def _shown(self, target: IntArray) -> tuple[IntArray, IntArray]:
        """The actions at ``target`` and ``span`` frames on (clipped to the library's last
        frame)."""
        assert self.actions is not None
        last = self.actions.size - 1
        return (
            self.actions[np.clip(target, 0, last)],
            self.actions[np.clip(target + self.span, 0, last)],
        )

    def starts(self, length: int) -> NDArray[np.bool_]:
        """The frames a window of ``length`` frames may start at for the frame after it to
        pass ``gate`` (a flag for each library frame; the last mask is kept)."""
        assert self.actions is not None
        key = (self.voted, length, id(self.actions))
        if self._starts is None or self._starts[0] != key:
            target = np.arange(self.actions.size, dtype=np.int64) + length
            self._starts = (key, self.gate(target))
        return self._starts[1]

    def window_actions(self, length: int) -> IntArray:
        """For each library frame, the action a window of ``length`` frames starting there
        counts for (``gate`` of the frame after it), or -1: ``starts(length)`` with
        ``voted`` the action ``a`` is ``window_actions(length) == a``."""
        assert self.actions is not None
        keys, ahead = self._shown(np.arange(self.actions.size, dtype=np.int64) + length)
        return np.where(keys == ahead, keys, -1).astype(np.int64)

    def leaves(self, frame: int, ahead: int) -> bool:
        """Whether an avatar at ``frame``, which plays on to ``ahead`` (``span`` frames on,
        or its clip's end), shows another action than the voted one at either."""
        assert self.actions is not None
        return {int(self.actions[frame]), int(self.actions[ahead])} != {self.voted}


def fused(
    scores: Sequence[FloatArray],
    fits: Sequence[float | None],
    weights: Sequence[float] | None = None,
) -> FloatArray:
    """Action scores ``scores`` of several descriptors (each ``action_scores``', no
    ``inf``) as one: their mean, each weighed by ``fit ** -FIT_POWER`` (times its
    ``weights``, default 1), ``fit`` its best window's per-frame cost over its reject
    threshold (lower: the descriptor reads the performer better). Where any ``fit`` is
    ``None`` the fits are not weighed at all (a voice whose fit says nothing beside the
    other's: ``vision._voice``)."""
    if any(f is None for f in fits):
        w = np.ones(len(fits))
    else:
        w = np.array([max(f, 1e-6) ** -FIT_POWER for f in fits if f is not None])
    if weights is not None:
        w = w * np.asarray(weights, dtype=np.float64)
    return np.asarray(np.tensordot(w / w.sum(), np.asarray(scores), axes=1), dtype=np.float64)


def unsure(scores: FloatArray) -> float:
    """How unsure a ballot's action ``scores`` (lower: better) are: 1 where the best two
    tie, falling to 0 where the best is ``UNSURE_LEAD`` under the second (relatively)."""
    if scores.size < 2:
        return 0.0
    best, second = np.partition(scores, 1)[:2]
    lead = (second - best) / max(float(best), 1e-9)
    return float(np.clip(1.0 - lead / UNSURE_LEAD, 0.0, 1.0))


#: a second descriptor's evidence at a decision (``ActionChoice.partner``): its action
#: scores, its fit (best per-frame cost over its reject threshold; ``None``: a voice whose
#: fit says nothing beside the ballot's own, weighed by its weight as far as the ballot is
#: ``unsure``, whatever the fits) and its weight (``fused``)
Evidence = tuple[FloatArray, "float | None", float]
Partner = Callable[[ActionVote], "Evidence | None"]


class ActionChoice:
    """Each decision's ballot: the action the performer's window votes for, as the
    library's action classifier (``vision._classify``) and the search's costs agree
    (``action_scores``), the performer read at ``settings.action.tempos`` too.
    ``windows``: the matcher's window search, whose tables the classifier is learned
    from and stored beside (in ``folder``, the bank's). ``partner``: another
    descriptor's evidence, weighed with this one's (``fused``) at the decisions where it
    gives any (``ActionSettings.fuse``: the silhouette beside the landmarks, where limbs
    are hidden)."""

    def __init__(
        self,
        windows: WindowSearch,
        settings: MatchSettings,
        n: int,
        folder: str | None,
        partner: Partner | None = None,
    ) -> None:
        self.windows, self.settings, self.n, self.folder = windows, settings, n, folder
        self._classifier: tuple[ActionClassifier | None, int] | None = None
        self.partner = partner

    def classifier(self, actions: IntArray | None) -> ActionClassifier | None:
        """The classifier of the library's ``actions``, learned on first use and stored;
        ``None`` without actions or with ``settings.action.classify`` off."""
        if actions is None or not self.settings.action.classify:
            return None
        if self._classifier is None:
            shape, centre, starts = self.windows.tables()
            key = self.windows.key
            got = cached_action_classifier(shape, centre, starts, self.n, actions, self.folder, key)
            self._classifier = (got, int(actions.max()) + 1 if actions.size else 0)
        return self._classifier[0]

    def choose(
        self,
        vote: ActionVote,
        queries: list[FloatArray],
        ranked: list[tuple[IntArray, IntArray, FloatArray]],
        performer: FloatArray,
    ) -> tuple[int | None, FloatArray | None]:
        """The action this decision votes for in ``vote`` (``None``: the best window's)
        and every action's score, from the search's short lists ``ranked`` (for the
        filter, an action with no window listed at the lists' cutoff)."""
        if vote.actions is None or vote.size <= 0:
            return None, None
        st, w = self.settings, self.windows
        args = (w.desc, w.mean, w.proj, st.centre_weight)
        extra = tempo_readings(performer, self.n, st.action.tempos, queries[0].shape[0], *args)
        if extra:
            ranked = list(ranked)
            w.ranked(extra, ranked)
        # the filter weighs every action at every decision, those off the lists too (and
        # so do fused scores, which cannot average an ``inf``)
        other = self.partner(vote) if self.partner is not None else None
        unseen = vote.switch > 0 or other is not None
        scores = self._action_scores(vote, queries + extra, ranked, unseen)
        if scores is None or not np.isfinite(scores).any():
            return None, None
        if other is not None and np.isfinite(scores).all():
            fits = [self.fit(ranked, queries[0]), other[1]]
            weight = other[2] if other[1] is not None else other[2] * unsure(scores)
            scores = fused([scores, other[0]], fits, [1.0, weight])
        return int(np.argmin(scores)), scores

    def scores(
        self,
        vote: ActionVote,
        queries: list[FloatArray],
        ranked: list[tuple[IntArray, IntArray, FloatArray]],
    ) -> tuple[FloatArray, float] | None:
        """Every action's score from the short lists ``ranked`` of ``queries`` (an action
        off them at the lists' cutoff) and this descriptor's fit, for another's ballot
        (a ``Partner``); ``None`` without a score for every action."""
        if vote.actions is None or not any(len(c) for _, _, c in ranked):
            return None
        got = self._action_scores(vote, queries, ranked, True)
        if got is None or not np.isfinite(got).all():
            return None
        return got, self.fit(ranked, queries[0])

    def _action_scores(
        self,
        vote: ActionVote,
        queries: list[FloatArray],
        ranked: list[tuple[IntArray, IntArray, FloatArray]],
        unseen: bool,
    ) -> FloatArray | None:
        """``action_scores`` of the vote's actions, with this library's classifier."""
        assert vote.actions is not None
        clf = self.classifier(vote.actions)
        n = self._classifier[1] if self._classifier else 0
        return action_scores(ranked, vote.actions, self.n, clf, queries, n, unseen)

    def fit(self, ranked: list[tuple[IntArray, IntArray, FloatArray]], query: FloatArray) -> float:
        """The best listed window's per-frame cost over the descriptor's reject threshold."""
        best = min(float(np.min(c)) for _, _, c in ranked if len(c))
        reject = self.windows.desc.reject
        return per_frame_cost(best, query.shape[0]) / (reject if np.isfinite(reject) else 1.0)
