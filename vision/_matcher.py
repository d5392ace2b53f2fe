"""The matcher (Lee et al. §5.3): which of the avatar's possible actions looks like what
the performer just did?

Every decision takes the candidate cluster paths from the avatar's current frame (the
nodes of its cluster tree reached within ``lookahead`` seconds), the most probable
motion of each, and the first ``window`` seconds of that motion as the bank sees it from
each of its views. DTW compares each with the last ``window`` seconds of the performer's
features; a path's cost is its best view; the cheapest path wins.

Features compared per frame, by the bank's descriptor (``silhouette_bank.Descriptor``):
its shape numbers (Hu moments, grid cells, or landmarks) mapped by ``shape_stats`` (the
bank's learned metric, or the descriptor's standardisation), and the centre's
displacement since the window's first frame, in units of body size (performer: from the
image; bank: the root's image motion accumulated plus the centre relative to the root),
times ``centre_weight``. A silhouette is read as seen and mirrored, landmarks as seen only
(they name the performer's sides; ``Descriptor.variants``); the best reading wins, weighed
by which way the performer faces (``vision._facing``). A best match
costing more than ``reject`` per frame is no match: ``why`` says so.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from control.avatar import JUMP, JumpCosts
from control.clusters import HigherLayer
from control.dtw import ShapeTable, dtw_batch, dtw_windows
from control.motion import Clip, action_names
from silhouette_bank import Bank

from ._classify import ActionClassifier, action_scores, cached_action_classifier
from ._decision import Decision, Jump
from ._facing import Facing
from ._index import WindowIndex, best_of, cached_window_index
from ._landing import Landing
from ._library import action_keys
from ._paths import CandidatePaths
from ._settings import MatchSettings
from ._tables import cached_shape_stats, cached_window_tables
from ._vote import ActionVote
from ._windows import (
    bank_sequences,
    best_window,
    per_frame_cost,
    performer_queries,
    tempo_readings,
)

__all__ = ["EARLY_WINDOWS", "Matcher"]

#: the most windows times views a half window is searched over by brute force to place
#: the avatar before its first whole window (``Matcher.early_search``: 25 ms for the
#: 54,000 of the default library on the development machine, about 70 ms at the limit)
EARLY_WINDOWS = 150_000

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


class Matcher(Landing):
    """Matches a performer's recent features against the avatar's candidate actions.

    ``actions`` (each graph frame's action key, ``vision.action_keys``; ``None``: an
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
    ) -> None:
        self.layer = layer
        self.graph = layer.graph
        self.bank = bank
        self.settings = settings or MatchSettings()
        self.n = max(2, round(self.settings.window * self.graph.fps))
        self.bound = max(1, round(self.settings.paths.lookahead * self.graph.fps))
        # graph frame -> bank frame
        index = {name: i for i, name in enumerate(bank.clip_names)}
        missing = [c for c in self.graph.clip_names if c not in index]
        if missing:
            raise ValueError(f"the bank lacks clips of the graph: {', '.join(missing)}")
        self.to_bank = np.concatenate(
            [
                np.arange(bank.clip_start[index[c]], bank.clip_start[index[c] + 1])
                for c in self.graph.clip_names
            ]
        )
        if self.to_bank.size != self.graph.n_frames:
            raise ValueError("the bank and the graph disagree on clip lengths (rebuild the bank)")
        self.mean, self.proj = cached_shape_stats(bank)
        #: what one performer frame is reduced to: the bank's descriptor
        self.desc = bank.settings.features
        self.descriptor = self.desc.name
        self.n_features = self.desc.size
        reject = self.settings.reject
        self.reject = self.desc.reject if reject is None else reject
        #: why the last ``decide`` or ``find_window`` gave nothing ("" when it gave something)
        self.why = ""
        # the bank may hold several variants (bodies, shadows) of the ring's views
        self.ring_views = bank.settings.ring.n_views
        # playing on: inside the component, or with jumps (which reach any frame) inside
        # a clip
        self.plays = self.graph.plays_on()
        if self.settings.landing.jumps:
            self.plays = np.ones(self.graph.n_frames, dtype=bool)
            self.plays[self.graph.clip_start[1:] - 1] = False
        #: Lee et al.'s candidate paths from the avatar's frame
        self.paths = CandidatePaths(layer, self.settings.paths, self.n, self.bound, self.plays)
        self._tables: tuple[ShapeTable, FloatArray, IntArray] | None = None
        self._tables_key = ""
        self._index: WindowIndex | None = None
        self._classifier: tuple[ActionClassifier | None, int] | None = None
        #: the run of playback each frame belongs to (a run breaks where playing on cannot)
        self._runs = np.cumsum(np.concatenate(([0], ~self.plays[:-1])))
        #: frames the avatar must have played on before it may jump again; ``decide``
        #: needs at least this many (and a window's) ``recent`` frames
        self.hold_frames = max(1, round(self.settings.landing.min_play * self.graph.fps))
        self.recent_frames = max(self.n, self.hold_frames + 1)
        #: performer frames ``decide`` reads (its ``tempos`` need more than a window)
        self.history_frames = max(
            [self.n] + [math.ceil(self.n / t) for t in self.settings.action.tempos]
        )
        #: the avatar's own recent cost at the last ``jump`` (``inf`` before a window)
        self.last_own = float("inf")
        d_max = layer.graph.report.get("max_distance") if layer.graph.report else None
        self.d_max = float(d_max) if d_max else 1.0
        if vote is None:
            vote = ActionVote.of(self.settings.action, self.n // 2, actions, names)
        self.vote = vote
        #: the performer's facing, for silhouettes read both ways (``ready``)
        self.facing: Facing | None = None

    def ready(self, clips: Sequence[Clip], period: float) -> None:
        """Ready for a loop deciding every ``period`` s: the vote's actions from ``clips``
        (the graph's) unless it has some, its classifier and each action's search made
        now (else the first decisions stall 7-10 ms), and the performer's facing."""
        if self.vote.actions is None:
            self.vote.actions = actions = action_keys(clips)
            self.vote.names = action_names(clips) if actions is not None else []
        if self.vote.actions is not None and self.settings.landing.jumps and self.vote.size > 0:
            self.classifier()
            self.index().prepare(self.vote.window_actions(self.n))
        self.facing = Facing.of(clips, self, period)

    def _check(self, performer: FloatArray) -> None:
        if performer.ndim != 2 or performer.shape[1] != self.n_features:
            raise ValueError(
                f"performer features must be (n, {self.n_features}) for the bank's "
                f"{self.descriptor!r} descriptor, got {performer.shape}: compute them with "
                f"silhouette_features(mask, descriptor={self.descriptor!r})"
            )

    def _global_tables(self) -> tuple[ShapeTable, FloatArray, IntArray]:
        """Every graph frame's standardised shape numbers and accumulated centre (times
        the centre weight) in every view, and the frames a window may start at (in the
        component, with ``n`` frames of playback ahead)."""
        if self._tables is None:
            shape, centre, self._tables_key = cached_window_tables(
                self.bank,
                self.to_bank,
                self.graph.clip_start,
                self.mean,
                self.proj,
                self.settings.centre_weight,
            )
            # with jumps the avatar reaches any frame; without, only the component
            n = self.graph.n_frames
            ok = np.ones(n, dtype=bool) if self.settings.landing.jumps else self.graph.in_scc.copy()
            end = np.arange(n) + self.n - 1
            ok &= end < n
            ok[ok] &= self._runs[end[ok]] == self._runs[np.flatnonzero(ok)]
            self._tables = (shape, centre, np.flatnonzero(ok).astype(np.int64))
        return self._tables

    @property
    def early_search(self) -> bool:
        """Whether half a window may place the avatar before the first whole one (by
        brute force, ``search``): where the library's windows times views are at most
        ``EARLY_WINDOWS``, a search of well under 0.1 s."""
        shape, _, starts = self._global_tables()
        return starts.size * shape.shape[1] <= EARLY_WINDOWS

    def index(self) -> WindowIndex:
        """The fast whole-library window search (made on first use; stored in the bank's
        folder, and loaded from there when the tables are the same)."""
        if self._index is None:
            shape, centre, starts = self._global_tables()
            folder = self.bank.path or None
            self._index = cached_window_index(
                shape, centre, starts, self.n, folder, key=self._tables_key
            )
        return self._index

    def queries(self, performer: FloatArray) -> list[FloatArray] | None:
        """The DTW queries ``(m, F)`` of the performer's last features ``(n, F)``: NaN rows
        (frames without a silhouette or pose) dropped, one query per reading
        (``Descriptor.variants``: as seen, mirrored, ...). ``None`` (and ``why``) when
        fewer than half the window's frames are usable."""
        self._check(performer)
        now = performer[-self.n :]
        ok = np.isfinite(now).all(axis=1)
        if ok.sum() < max(2, self.n // 2):
            self.why = "no silhouette" if self.desc.kind == "silhouette" else "no pose"
            return None
        st = self.settings
        return performer_queries(
            now[ok], self.desc, self.mean, self.proj, st.centre_weight, st.mirror
        )

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
        return (got[0][0], got[0][1] % self.ring_views, got[0][2]) if got else None

    def search(
        self, performer: FloatArray, top: int = 1, exact: bool = False
    ) -> list[tuple[int, int, float]]:
        """The ``top`` library windows ``(start, view, cost)`` most like the performer's
        last features, cheapest first, one per start; ``view`` counts the bank's variants
        too. Empty (and ``why``) without enough silhouette or when the best is rejected.
        Features of fewer than ``n`` frames (a window not yet whole) are matched, by brute
        force, against windows of their own length: the best one only."""
        queries = self.queries(performer)
        if queries is None:
            return []
        shape, centre, starts = self._global_tables()
        if starts.size == 0:
            self.why = "no window in the component"
            return []
        span = min(performer.shape[0], self.n)
        # a window not yet whole (the first second) by brute force too, over windows of
        # its own length: the index holds whole windows
        st = self.settings
        if exact or span < self.n:
            length = min(span, self.n)
            got = [best_window(queries, shape, centre, starts, length, st.band, st.recency)]
        else:
            got = self.index().search(queries, st.band, top, recency=st.recency)
        if not got or self._rejected(got[0][2], queries[0]):
            return []
        self.why = ""
        return got

    def _plain_cost(self, queries: list[FloatArray]) -> Callable[[int, int, int], float] | None:
        """The cost of the window at ``(start, view)`` of the index against
        ``queries[reading]`` by DTW with every frame alike, for the facing's evidence
        (``None`` when the matcher's DTW already weighs them so: ``recency`` 0)."""
        if self.settings.recency == 0:
            return None
        idx, band = self.index(), self.settings.band

        def cost(reading: int, start: int, view: int) -> float:
            s, v = np.array([start], dtype=np.int64), np.array([view], dtype=np.int64)
            q = queries[reading]
            return float(dtw_windows(q, idx.shape, idx.centre, s, v, idx.length, band)[0])

        return cost

    def _bank_sequences(self, frames: IntArray) -> FloatArray:
        """DTW features ``(V, n, F)`` of graph ``frames`` in every view."""
        w = self.settings.centre_weight
        return bank_sequences(self.bank, self.to_bank[frames], self.mean, self.proj, w)

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
        st = self.settings
        if queries is None:
            queries = self.queries(performer)
            if queries is None:
                return None
        ranked: list[tuple[IntArray, IntArray, FloatArray]] = []
        got = self.index().search(
            queries, st.band, st.landing.top_windows, ranked=ranked, recency=st.recency
        )
        self.last_own = float("inf")
        if not got or self._rejected(got[0][2], queries[0]):
            return None  # (why says so when the best was rejected)
        self.why = ""
        if self.facing is not None:
            ranked[:] = self.facing.weigh(ranked, recost=self._plain_cost(queries))
            got = best_of(ranked, st.landing.top_windows)
        target, ok, there = self._targets(frame, got, costs, queries)
        voted = self.vote.cast(target, *self._choice(queries, ranked, performer))
        at = [g[2] for g, t in zip(got, there, strict=True) if t]
        gated = self._gated(frame, queries, ranked, costs, (got, target, ok, there), voted)
        got, target, ok, weight, own_weight = gated
        # (strict vote) the avatar leaves an action the performer is not voted to do
        leave = math.isinf(own_weight)
        # the avatar's own cost, however it is taken, weighed alike
        mine = 1.0 if leave else own_weight
        if at:  # the avatar does one of the best windows: its cost is its own
            self.last_own = mine * min(at)
        if not ok.any():  # no jump: holding still is weighed against playing on
            if not np.isfinite(self.last_own) and self.plays[frame]:
                self.last_own = mine * self.own_cost(queries, self.own_frames(frame, recent))
            return None
        idx = np.flatnonzero(ok)
        match = np.array([got[i][2] for i in idx]) * weight[idx]
        # at its clip's end the avatar must go somewhere: the best jump, whatever it costs;
        # and leaving for the voted action, any window of it beats staying, at once
        own = float("inf")
        if self.plays[frame] and not leave:
            own = self.own_cost(queries, self.own_frames(frame, recent)) * own_weight
        self.last_own = own
        m, lead = self.hold_frames, self._lead_in(recent)
        # (a frame held still, as played on, lets it jump)
        settled = leave or lead.size < m or bool(np.isin(np.diff(lead[-m:]), (0, 1)).all())
        # the blend only adds to a match's cost: no (slower) distances when the best cannot win
        if (not settled or not match.min() < st.landing.jump_ratio * own) and np.isfinite(own):
            return None
        w = st.landing.blend_weight  # the blend's share saturates: a far jump costs at most w more
        dist = costs(frame, target[idx])[0] if w > 0 else None  # (else the chosen one's only)
        score = match if dist is None else match * (1.0 + w * dist / (dist + self.d_max))
        b = int(np.argmin(score))
        if not score[b] < st.landing.jump_ratio * own:
            return None
        i, j = int(idx[b]), int(target[idx[b]])
        frames = np.concatenate(([frame], self._playback(j)))
        blend = dist[b] if dist is not None else costs(frame, frames[1:2])[0][0]
        return Decision(
            frames=frames,
            edges=np.array([JUMP] + [-1] * (frames.size - 2), dtype=np.int64),
            cluster_path=np.zeros(0, dtype=np.int64),
            cost=float(match[b]),
            runner_up=float(np.sort(score)[1]) if score.size > 1 else float("inf"),
            view=int(got[i][1]) % self.ring_views,
            candidates=int(idx.size),
            latency_ms=(time.perf_counter() - t0) * 1e3,
            jump=Jump(j, float(own), float(blend), bool(leave)),
        )

    def classifier(self) -> ActionClassifier | None:
        """The library's action classifier (``vision._classify``), learned from the
        search's windows and the vote's ``actions`` on first use and stored in the bank's
        folder; ``None`` without actions or with ``settings.action.classify`` off."""
        actions = self.vote.actions
        if actions is None or not self.settings.action.classify:
            return None
        if self._classifier is None:
            shape, centre, starts = self._global_tables()
            folder, key = self.bank.path or None, self._tables_key
            got = cached_action_classifier(shape, centre, starts, self.n, actions, folder, key)
            self._classifier = (got, int(actions.max()) + 1 if actions.size else 0)
        return self._classifier[0]

    def _choice(
        self,
        queries: list[FloatArray],
        ranked: list[tuple[IntArray, IntArray, FloatArray]],
        performer: FloatArray,
    ) -> tuple[int | None, FloatArray | None]:
        """The action this decision votes for (``voted_action``; ``None``: the best
        window's) and every action's score (``action_scores``), the performer's features
        read at ``settings.action.tempos`` too."""
        if self.vote.actions is None or self.vote.size <= 0:
            return None, None
        st = self.settings
        args = (self.desc, self.mean, self.proj, st.centre_weight)
        extra = tempo_readings(performer, self.n, st.action.tempos, queries[0].shape[0], *args)
        if extra:
            ranked = list(ranked)
            self.index().search(
                extra, st.band, st.landing.top_windows, ranked=ranked, recency=st.recency
            )
        clf = self.classifier()
        n = self._classifier[1] if self._classifier else 0
        scores = action_scores(ranked, self.vote.actions, self.n, clf, queries + extra, n)
        if scores is None or not np.isfinite(scores).any():
            return None, None
        return int(np.argmin(scores)), scores

    def warm_up(self, frame: int, recent: IntArray, jump_costs: JumpCosts) -> None:
        """One throwaway decision from the avatar at ``frame`` on a window of the library
        itself, so that the first real one does not pay for loading or compiling the
        search and DTW kernels (0.5 s on a fresh install: a stall a performer would see).
        It votes in a vote of its own, over no actions, which it then drops."""
        if self.bank.features.shape[0] >= self.n:
            probe = np.asarray(self.bank.features[: self.n, 0], dtype=np.float64)
            vote, self.vote = self.vote, ActionVote.of(self.settings.action, self.n // 2)
            try:
                self.decide(frame, probe, recent, jump_costs)
            finally:
                self.vote, self.why, self.last_own = vote, "", float("inf")

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
        better still."""
        t0 = time.perf_counter()
        queries = self.queries(performer)
        if queries is None:
            return None
        if self.settings.landing.jumps and recent is not None and jump_costs is not None:
            j = self.jump(frame, performer, recent, jump_costs, queries)
            if j is None and self.why:  # the best window was rejected: nothing real matches
                return None
            j = self.held(frame, queries, j) or j  # a performer standing still
            if j is not None:
                return dataclasses.replace(j, latency_ms=(time.perf_counter() - t0) * 1e3)
            on = self._playback(frame)
            lee = self.settings.paths.after_no_jump and self.layer.forest.tree_of[frame] >= 0
            if not lee and on.size > 1:
                return Decision(
                    frames=on,
                    edges=np.full(on.size - 1, -1, dtype=np.int64),
                    cluster_path=np.zeros(0, dtype=np.int64),
                    cost=self.last_own,
                    runner_up=float("inf"),
                    view=-1,  # as before
                    candidates=1,
                    latency_ms=(time.perf_counter() - t0) * 1e3,
                    how="plays_on",
                )
        cands = self.paths.candidates(frame)
        if not cands:
            self.why = "no candidate path"
            return None
        views = self.bank.features.shape[1]
        wins = [self.paths.window_frames(f) for _, f, _ in cands]
        refs = np.concatenate([self._bank_sequences(w) for w in wins])
        group = np.repeat(np.arange(len(cands)), views)
        st = self.settings
        each = np.array([dtw_batch(q, refs, group, st.band, st.recency) for q in queries])
        each = each.reshape(len(queries), len(cands), views)
        if self.facing is not None:
            for i, w in enumerate(wins):
                each[:, i] = self.weighed(each[:, i], int(w[self.n // 2]))
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
            view=int(np.argmin(costs[best])) % self.ring_views,
            candidates=len(cands),
            latency_ms=(time.perf_counter() - t0) * 1e3,
        )
