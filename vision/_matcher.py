"""The matcher (Lee et al. §5.3): which of the avatar's possible actions looks like what
the performer just did?

Every decision takes the candidate cluster paths from the avatar's current frame (the
nodes of its cluster tree reached within ``lookahead`` seconds), the most probable
motion of each, and the first ``window`` seconds of that motion as the bank sees it from
each of its views. DTW compares each with the last ``window`` seconds of the performer's
features; a path's cost is its best view; the cheapest path wins.

With jumps (motion matching, the default) every decision also searches the whole
library's windows for direct blended jumps, and the avatar plays on, holds still or jumps.
The matcher keeps its collaborators, each with its own interface: the window search
(``vision._search.WindowSearch``: the features compared, the index), the candidate paths
(``vision._paths``), the lander (``vision._landing``: where a jump lands, what it must
beat) and the action vote (``vision._vote``). A best match costing more than ``reject``
per frame is no match: ``why`` says so.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from control.avatar import JUMP, JumpCosts
from control.clusters import HigherLayer
from control.dtw import dtw_batch
from control.motion import Clip, action_keys, action_names
from silhouette_bank import Bank

from ._classify import ActionClassifier
from ._decision import Decision, Jump
from ._facing import Facing
from ._index import best_of
from ._landing import Lander, sparse_window
from ._paths import CandidatePaths
from ._repeat import REPEAT_REACH, repeat_frames, repeated
from ._search import Windows, WindowSearch
from ._settings import MatchSettings
from ._vote import ActionChoice, ActionVote, Partner
from ._windows import (
    per_frame_cost,
)

__all__ = ["Matcher"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


class Matcher:
    """Matches a performer's recent features against the avatar's candidate actions.

    ``actions`` (each graph frame's action key, ``control.motion.action_keys``; ``None``: an
    unlabelled library) and their ``names`` are the vote's; ``vote``: one to share with
    another matcher of the same graph (the silhouette beside the landmarks), so that the
    avatar's action does not restart when the evidence changes hands."""

    def __init__(
        self,
        layer: HigherLayer,
        bank: Bank,
        settings: MatchSettings | None = None,
        actions: IntArray | None = None,
        names: Sequence[str] = (),
        vote: ActionVote | None = None,
        partner: Partner | None = None,
    ) -> None:
        self.layer = layer
        self.graph = layer.graph
        self.bank = bank
        self.settings = settings or MatchSettings()
        self.n = max(2, round(self.settings.window * self.graph.fps))
        self.bound = max(1, round(self.settings.paths.lookahead * self.graph.fps))
        # playing on: inside the component, or with jumps (which reach any frame) inside
        # a clip
        self.plays = self.graph.plays_on()
        jumps = self.settings.landing.jumps
        if jumps:
            self.plays = np.ones(self.graph.n_frames, dtype=bool)
            self.plays[self.graph.clip_start[1:] - 1] = False
        #: the library's windows and the searches over them
        self.windows = WindowSearch(self.graph, bank, self.settings, self.n, self.plays, jumps)
        #: what one performer frame is reduced to: the bank's descriptor
        self.desc = self.windows.desc
        self.n_features = self.desc.size
        reject = self.settings.reject
        self.reject = self.desc.reject if reject is None else reject
        #: why the last ``decide`` or ``find_window`` gave nothing ("" when it gave something)
        self.why = ""
        #: Lee et al.'s candidate paths from the avatar's frame
        self.paths = CandidatePaths(layer, self.settings.paths, self.n, self.bound, self.plays)
        #: what each decision votes for (``partner``: another descriptor's evidence, weighed
        #: with this one's)
        self.ballot = ActionChoice(self.windows, self.settings, self.n, bank.path or None, partner)
        #: frames the avatar must have played on before it may jump again; ``decide``
        #: needs at least this many (and a window's) ``recent`` frames
        self.hold_frames = max(1, round(self.settings.landing.min_play * self.graph.fps))
        self.recent_frames = max(self.n, self.hold_frames + 1)
        #: performer frames ``decide`` reads (its ``tempos`` need more than a window)
        action = self.settings.action
        repeat = repeat_frames(self.graph.fps) if action.repeat > 0 and jumps else 0
        self.history_frames = max([self.n, repeat] + [math.ceil(self.n / t) for t in action.tempos])
        #: seconds between decisions (``ready``)
        self.period = 0.1
        #: the avatar's own recent cost at the last ``jump`` (``inf`` before a window)
        self.last_own = float("inf")
        d_max = layer.graph.report.get("max_distance") if layer.graph.report else None
        self.d_max = float(d_max) if d_max else 1.0
        if vote is None:
            kind = self.desc.kind
            # (a silhouette's partner is the landmarks read from it: ``vision._voice``)
            voice = kind == "silhouette" and partner is not None
            vote = ActionVote.of(self.settings.action, self.n // 2, actions, names, kind, voice)
        #: where a jump lands and what it must beat; it holds the action vote
        self.lander = Lander(self.windows, self.settings, vote, self.n, self.recent_frames)

    @property
    def vote(self) -> ActionVote:
        """The action vote (``vision._vote``), which the lander weighs jumps by."""
        return self.lander.vote

    def ready(self, clips: Sequence[Clip], period: float) -> None:
        """Ready for a loop deciding every ``period`` s: the vote's actions from ``clips``
        (the graph's) unless it has some, its classifier and each action's search made
        now (else the first decisions stall 7-10 ms), and the performer's facing."""
        self.period = period
        # (``jump`` asks the vote what it voted as far back as the performer repeats)
        self.vote.keep_voted(math.ceil(REPEAT_REACH / period) + 1)
        if self.vote.actions is None:
            self.vote.actions = actions = action_keys(clips)
            self.vote.names = action_names(clips) if actions is not None else []
        if self.vote.actions is not None and self.settings.landing.jumps and self.vote.size > 0:
            self.classifier()
            self.windows.index().prepare(self.vote.window_actions(self.n))
        self.windows.facing = Facing.of(clips, self, period)

    def queries(self, performer: FloatArray) -> list[FloatArray] | None:
        """The DTW queries of the performer's last features ``(n, F)``, one per reading
        (``WindowSearch.queries``); ``None`` (and ``why``) when fewer than half the
        window's frames are usable."""
        got = self.windows.queries(performer)
        if got is None:
            self.why = "no silhouette" if self.desc.kind == "silhouette" else "no pose"
        return got

    def action_scores(
        self, vote: ActionVote, performer: FloatArray
    ) -> tuple[FloatArray, float] | None:
        """Every action's score for ``vote`` from the performer's last features ``(n,
        F)`` and this matcher's fit (``ActionChoice.scores``), as another descriptor's
        ballot hears them (the silhouette beside the landmarks, the landmarks read from
        a silhouette); ``None`` without enough features or a score for every action."""
        if (queries := self.queries(performer)) is None:
            return None
        ranked: list[tuple[IntArray, IntArray, FloatArray]] = []
        self.windows.ranked(queries, ranked)
        if self.windows.facing is not None:  # (as this descriptor's own decisions weigh it)
            ranked[:] = self.windows.facing.weigh(ranked, recost=self.windows.plain_cost(queries))
        return self.ballot.scores(vote, queries, ranked)

    def per_frame(self, cost: float, query: FloatArray) -> float:
        """``per_frame_cost`` of a DTW cost of ``query``: the scale of ``reject``."""
        return per_frame_cost(cost, query.shape[0])

    def _rejected(self, cost: float, query: FloatArray) -> bool:
        c = self.per_frame(cost, query)
        if c > self.reject:
            self.why = f"no match (cost {c:.2f} per frame > {self.reject:g})"
            return True
        return False

    def find_window(
        self, performer: FloatArray, exact: bool = False
    ) -> tuple[int, int, float] | None:
        """``(frame, view, cost)``: the library window (any frame of the component, view
        and variant, the performer as seen or mirrored) most like the performer's last
        features, ``frame`` its start, ``view`` the ring's; by the index, or with ``exact``
        by brute force. ``None`` without enough silhouette, or when the best is rejected."""
        got = self.search(performer, 1, exact)
        return (got[0][0], got[0][1] % self.windows.ring_views, got[0][2]) if got else None

    def search(
        self, performer: FloatArray, top: int = 1, exact: bool = False
    ) -> list[tuple[int, int, float]]:
        """The ``top`` library windows ``(start, view, cost)`` most like the performer's
        last features, cheapest first, one per start; ``view`` counts the bank's variants
        too. Empty (and ``why``) without enough silhouette or when the best is rejected.
        Features of fewer than ``n`` frames (a window not yet whole) are matched, by brute
        force, against windows of their own length: the best one only, among those that
        play on in their action until the window is whole (``WindowSearch.settled``)."""
        queries = self.queries(performer)
        if queries is None:
            return []
        if self.windows.tables()[2].size == 0:
            self.why = "no window in the component"
            return []
        span = min(performer.shape[0], self.n)
        got = self.windows.best(queries, top, span, exact, self.vote.actions)
        if not got or self._rejected(got[0][2], queries[0]):
            return []
        self.why = ""
        return got

    def jump(
        self,
        frame: int,
        performer: FloatArray,
        recent: IntArray,
        costs: JumpCosts,
        queries: list[FloatArray] | None = None,
    ) -> Decision | None:
        """The best direct blended jump from ``frame`` (motion matching): into the frame
        after one of the ``top`` best library windows, scored by its match cost and the
        blend from ``frame``, or ``None`` when none beats ``jump_ratio`` times the
        avatar's own recent cost (the avatar already follows)."""
        t0 = time.perf_counter()
        st, land = self.settings, self.lander
        if queries is None:
            queries = self.queries(performer)
            if queries is None:
                return None
        self.last_own = float("inf")
        # (only a ballot jump is shut by it; then, what the vote said when the performer
        # last did this)
        back = (
            repeated(performer, self.graph.fps, st.action.repeat) if land.ballots_jump() else None
        )
        land.repeated = None if back is None else self.vote.voted_back(round(back / self.period))
        found = self.voted_windows(frame, performer, costs, queries)
        if found is None:
            return None  # (why says so when the best was rejected)
        got, target, ok, weight, own_weight, at = found
        # (an infinite margin) the avatar leaves an action the performer is not voted to do
        leave = math.isinf(own_weight)
        # the avatar's own cost, however it is taken, weighed alike
        mine = 1.0 if leave else own_weight
        if at:  # the avatar does one of the best windows: its cost is its own
            self.last_own = mine * min(at)
        if not ok.any():  # no jump: holding still is weighed against playing on
            if not np.isfinite(self.last_own) and self.plays[frame]:
                self.last_own = mine * land.own_cost(queries, land.own_frames(frame, recent))
            return None
        idx = np.flatnonzero(ok)
        match = np.array([got[i][2] for i in idx]) * weight[idx]
        # at its clip's end the avatar must go somewhere: the best jump, whatever it costs;
        # and leaving for the voted action, any window of it beats staying, at once
        own = float("inf")
        if self.plays[frame] and not leave:
            own = land.own_cost(queries, land.own_frames(frame, recent)) * own_weight
        self.last_own = own
        m, lead = self.hold_frames, land.lead_in(recent)
        # (a frame held still, as played on, lets it jump)
        settled = leave or lead.size < m or bool(np.isin(np.diff(lead[-m:]), (0, 1)).all())
        # the blend only adds to a match's cost: no (slower) distances when the best cannot win
        if (not settled or not match.min() < st.landing.jump_ratio * own) and np.isfinite(own):
            return None
        picked = [got[i] for i in idx]
        return self._blended_jump(frame, costs, picked, target[idx], match, own, leave, t0)

    def _blended_jump(
        self,
        frame: int,
        costs: JumpCosts,
        got: Windows,
        target: IntArray,
        match: FloatArray,
        own: float,
        leave: bool,
        t0: float,
    ) -> Decision | None:
        """The jump from ``frame`` into the best of the windows ``got`` (landing at
        ``target``, at weighed costs ``match``) once the blend from ``frame`` is counted,
        or ``None`` when it does not beat ``jump_ratio`` times the avatar's ``own`` cost
        (infinite: any window; ``leave``: the avatar leaves an action the performer is
        not voted to do)."""
        st = self.settings
        w = st.landing.blend_weight  # the blend's share saturates: a far jump costs at most w more
        dist = costs(frame, target)[0] if w > 0 else None  # (else the chosen one's only)
        score = match if dist is None else match * (1.0 + w * dist / (dist + self.d_max))
        b = int(np.argmin(score))
        if not score[b] < st.landing.jump_ratio * own:
            return None
        j = int(target[b])
        frames = np.concatenate(([frame], self.windows.playback(j)))
        blend = dist[b] if dist is not None else costs(frame, frames[1:2])[0][0]
        return Decision(
            frames=frames,
            edges=np.array([JUMP] + [-1] * (frames.size - 2), dtype=np.int64),
            cluster_path=np.zeros(0, dtype=np.int64),
            cost=float(match[b]),
            runner_up=float(np.sort(score)[1]) if score.size > 1 else float("inf"),
            view=int(got[b][1]) % self.windows.ring_views,
            candidates=int(target.size),
            latency_ms=(time.perf_counter() - t0) * 1e3,
            jump=Jump(j, float(own), float(blend), leave),
        )

    def voted_windows(
        self, frame: int, performer: FloatArray, costs: JumpCosts, queries: list[FloatArray]
    ) -> tuple[Windows, IntArray, NDArray[np.bool_], FloatArray, float, list[float]] | None:
        """The search's best windows for the performer's ``queries`` (weighed by the
        facing), the decision's vote cast on them, and the vote's part in a jump from
        ``frame`` (``Lander.gated``): ``(got, target, ok, weight, own_weight, at)``,
        ``at`` the costs of those the avatar is at already; ``None`` where the best
        window is rejected (``why`` says so)."""
        ranked: list[tuple[IntArray, IntArray, FloatArray]] = []
        got = self.windows.ranked(queries, ranked)
        if not got or self._rejected(got[0][2], queries[0]):
            return None
        self.why = ""
        facing, land = self.windows.facing, self.lander
        if facing is not None:
            ranked[:] = facing.weigh(ranked, recost=self.windows.plain_cost(queries))
            got = best_of(ranked, self.settings.landing.top_windows)
        target, ok, there = land.targets(frame, got, costs, queries)
        voted = self.vote.cast(target, *self.ballot.choose(self.vote, queries, ranked, performer))
        at = [g[2] for g, t in zip(got, there, strict=True) if t]
        gated = land.gated(frame, queries, ranked, costs, (got, target, ok, there), voted)
        return (*gated, at)

    def classifier(self) -> ActionClassifier | None:
        """The library's action classifier (``ActionChoice.classifier``) of the vote's
        actions; ``None`` without actions or with ``settings.action.classify`` off."""
        return self.ballot.classifier(self.vote.actions)

    def warm_up(self, frame: int, recent: IntArray, jump_costs: JumpCosts) -> None:
        """One throwaway decision from the avatar at ``frame`` on a window of the library
        itself, so that the first real one does not pay for loading or compiling the
        search and DTW kernels (0.5 s on a fresh install: a stall a performer would see).
        It votes in a vote of its own, over no actions, which it then drops."""
        if self.bank.features.shape[0] >= self.n:
            probe = np.asarray(self.bank.features[: self.n, 0], dtype=np.float64)
            own = ActionVote.of(self.settings.action, self.n // 2, descriptor=self.desc.kind)
            vote, self.lander.vote = self.vote, own
            try:
                self.decide(frame, probe, recent, jump_costs)
            finally:
                self.lander.vote, self.why, self.last_own = vote, "", float("inf")

    def decide(
        self,
        frame: int,
        performer: FloatArray,
        recent: IntArray | None = None,
        jump_costs: JumpCosts | None = None,
    ) -> Decision | None:
        """The best path from ``frame`` for the performer's last features ``(n, F)``
        (NaN rows, frames without a silhouette, are dropped); ``None`` without enough.
        With the avatar's ``recent`` frames and its ``jump_costs`` (and
        ``settings.landing.jumps``), a direct blended jump (``jump``) when one is clearly better
        than what the avatar is doing, or its frame held still (``held``) when that is
        better still, else playing on; the paper's cluster paths (``cluster_path``) where
        it cannot play on."""
        t0 = time.perf_counter()
        self.lander.repeated = None  # (``jump`` says)
        queries = self.queries(performer)
        if queries is None:
            return None
        if self.settings.landing.jumps and recent is not None and jump_costs is not None:
            j = self.jump(frame, performer, recent, jump_costs, queries)
            if j is None and self.why:  # the best window was rejected: nothing real matches
                return None
            holding = recent.size >= 2 and recent[-1] == recent[-2] == frame
            land = not sparse_window(performer[-self.n :])
            held = self.lander.held(frame, queries, j, self.last_own, jump_costs, holding, land)
            j = held or j  # standing still
            if j is None:
                j = self.played_on(frame)
            if j is not None:
                return dataclasses.replace(j, latency_ms=(time.perf_counter() - t0) * 1e3)
        return self.cluster_path(frame, queries, t0)

    def played_on(self, frame: int) -> Decision | None:
        """The avatar playing its clip on from ``frame`` at its own cost (no jump or hold
        beat it); ``None`` at its clip's end, or where the paper's paths take over
        (``paths.after_no_jump``)."""
        on = self.windows.playback(frame)
        lee = self.settings.paths.after_no_jump and self.layer.forest.tree_of[frame] >= 0
        if lee or on.size <= 1:
            return None
        return Decision(
            frames=on,
            edges=np.full(on.size - 1, -1, dtype=np.int64),
            cluster_path=np.zeros(0, dtype=np.int64),
            cost=self.last_own,
            runner_up=float("inf"),
            view=-1,  # (the last decision's view goes on)
            candidates=1,
            latency_ms=0.0,
            how="plays_on",
        )

    def cluster_path(self, frame: int, queries: list[FloatArray], t0: float) -> Decision | None:
        """Lee et al.'s choice: of the cluster tree's candidate paths from ``frame``, the
        one whose frames the performer's ``queries`` fit best by DTW (any view; the
        ``keep_clip_bonus`` prior ranks a path that plays on ahead); ``None`` without a
        path or where the best is rejected. ``t0``: when the decision began."""
        cands = self.paths.candidates(frame)
        if not cands:
            self.why = "no candidate path"
            return None
        views = self.bank.features.shape[1]
        wins = [self.paths.window_frames(f) for _, f, _ in cands]
        refs = np.concatenate([self.windows.sequences(w) for w in wins])
        group = np.repeat(np.arange(len(cands)), views)
        st = self.settings
        each = np.array([dtw_batch(q, refs, group, st.band, st.recency) for q in queries])
        each = each.reshape(len(queries), len(cands), views)
        if self.windows.facing is not None:
            for i, w in enumerate(wins):
                each[:, i] = self.windows.weighed(each[:, i], int(w[self.n // 2]))
        costs = each.min(axis=0)
        per_path = costs.min(axis=1)
        rank = per_path  # the costs reported stay DTW costs; the prior only ranks
        if self.settings.paths.keep_clip_bonus > 0:
            plays_on = np.array([not (e[: self.n - 1] >= 0).any() for _, _, e in cands])
            rank = np.where(
                plays_on, per_path * (1.0 - self.settings.paths.keep_clip_bonus), per_path
            )
        order = np.argsort(rank, kind="stable")
        best = int(order[0])
        if self._rejected(float(per_path[best]), queries[0]):
            return None
        self.why = ""
        node, frames, edges = cands[best]
        tree = self.layer.forest.tree(frame)
        return Decision(
            frames=frames,
            edges=edges,
            cluster_path=tree.clusters_to(node),
            cost=float(per_path[best]),
            runner_up=float(per_path[order[1]]) if len(order) > 1 else float("inf"),
            view=int(np.argmin(costs[best])) % self.windows.ring_views,
            candidates=len(cands),
            latency_ms=(time.perf_counter() - t0) * 1e3,
        )
