"""Where the avatar goes next, one of ``Matcher``'s collaborators: a direct jump lands on
the frame after one of the search's best windows, placed by the performer's last frames
(``phased_targets``), unless the avatar is there already, weighed by the action vote
(``gated``); or, for a performer standing still, the avatar holds its frame, or lands
on one and holds it (``held``).
What a jump must beat is the avatar's own cost (``own_cost`` of ``own_frames``).

A live avatar is seen a moment after the frame it answers (the pose model, the page's
round trip): with a lead (``LandingSettings.lead``) it lands that far ahead of the
performer's last frame, where the performer will be when it is shown, and its own cost
is read that far behind its frame."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from control.avatar import JUMP, JumpCosts
from control.dtw import dtw_batch

from ._decision import Decision, Jump
from ._facing import Ranked
from ._index import best_of
from ._search import Windows, WindowSearch
from ._settings import MatchSettings
from ._vote import ActionVote
from ._windows import per_frame_cost, phased_targets, window_costs

__all__ = ["Gate", "Lander"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
#: ``(target, ok, there)``: the frames after the windows, which a jump may land on, and
#: which the avatar is at already
Gate = tuple[IntArray, NDArray[np.bool_], NDArray[np.bool_]]


class Lander:
    """Where the avatar lands: the targets of its jumps, what a jump must beat (its own
    cost), the action vote's part in a jump, and holding still. ``windows``: the
    matcher's window search; ``vote``: its action vote; ``recent_frames``: the avatar's
    frames a decision reads."""

    #: where the performer does again what they did a moment ago
    #: (``ActionSettings.repeat``), the action voted then (-1: none known); this
    #: decision's ballot then opens no new action. ``None``: they do something new
    repeated: int | None = None

    def __init__(
        self,
        windows: WindowSearch,
        settings: MatchSettings,
        vote: ActionVote,
        n: int,
        recent_frames: int,
    ) -> None:
        self.windows, self.settings, self.vote = windows, settings, vote
        self.graph, self.plays = windows.graph, windows.plays
        self.n, self.recent_frames = n, recent_frames
        #: library frames ahead of the performer's last frame a jump lands
        self.lead = round(settings.landing.lead * self.graph.fps)

    def ahead(self, frames: IntArray, k: int | None = None) -> IntArray:
        """Each of ``frames`` played on by ``k`` frames (default: the lead) as far as
        its clip plays on."""
        out = np.asarray(frames, dtype=np.int64).copy()
        n = self.graph.n_frames
        for _ in range(self.lead if k is None else k):
            inside = out < n - 1
            go = inside & self.plays[np.clip(out, 0, n - 1)]
            out = np.where(go, out + 1, out)
        return out

    def behind(self, frame: int) -> int:
        """The frame the lead's frames play into ``frame`` from (as far back as its clip
        goes): where the performer's last frame was, the avatar being ahead."""
        return self.played_into(frame, self.lead)[-1]

    def held(
        self,
        frame: int,
        queries: list[FloatArray],
        rival: Decision | None,
        own: float,
        costs: JumpCosts | None = None,
        holding: bool = False,
        land: bool = True,
    ) -> Decision | None:
        """The avatar holding a frame still (shown again, as a performer standing still
        does), when ``settings.landing.hold_still`` and that matches the performer's
        window better than ``rival`` (the jump ``Matcher.jump`` chose, unless it leaves
        for the voted action) or, without one, than playing on (``own``, the avatar's own
        cost); else ``None``. The frame held is the avatar's own or, where ``rival`` is a
        jump, one of the ``landing.hold_back`` frames that play into its target (the
        jump then lands there and holds: ``costs`` gives its blend). The library has no
        still second (its stillest windows still turn a joint 1.5-5 degrees a frame), so
        without holds the avatar jumped about 4 times a second among near-still windows
        while the performer stood still; and a performer who stops where a cycle turns
        (the bottom of a squat) matches windows that run through that frame and on, so a
        jump lands past the pose the performer holds and plays out of it. With the
        vote's margin, a frame of another action than the voted one costs 1 +
        ``action.margin`` times as much held, as it does played on. ``land`` False: the
        jump's frames are not held (``sparse_window``)."""
        if not self.settings.landing.hold_still or (
            rival is not None and rival.jump is not None and rival.jump.leaves
        ):
            return None
        against = rival.cost if rival is not None else own
        if not np.isfinite(against):
            return None
        frames = [frame]
        if land and rival is not None and rival.jump is not None:
            back = self.played_into(rival.jump.target, self.settings.landing.hold_back)
            if self.vote.actions is not None:  # (the action the jump was let into alone)
                keys = self.vote.actions
                back = [f for f in back if keys[f] == keys[rival.jump.target]]
            frames += back
        got = [self._held_cost(f, queries) for f in frames]
        # a frame held already, where it fits well, is left only for a clearly better
        # one: a performer's stillness read with noise fits many near-alike frames about
        # as well. Where it fits weakly (a pose model guessing from behind, or an action
        # the library lacks) the keep would only hold the avatar in the wrong pose.
        keep = 1.0
        if holding and not self.fits_weakly(got[0][0], queries):
            keep = self.settings.landing.hold_keep
        weighed = [c * (keep if k == 0 else 1.0) for k, (c, _) in enumerate(got)]
        i = int(np.argmin(weighed))
        (cost, view), hold = got[i], frames[i]
        if not weighed[i] < self.settings.landing.jump_ratio * against:
            return None
        path = np.full(self.n + 1, hold, dtype=np.int64)
        edges = np.full(self.n, -1, dtype=np.int64)
        jump = None
        if hold != frame:  # (lands on the frame and holds it)
            path[0] = frame
            edges[0] = JUMP
            assert rival is not None and rival.jump is not None  # (``frames``' others)
            blend = costs(frame, path[1:2])[0][0] if costs is not None else float("nan")
            jump = Jump(hold, rival.jump.own_cost, float(blend))
        return Decision(
            frames=path,
            edges=edges,
            cluster_path=np.zeros(0, dtype=np.int64),
            cost=cost,
            runner_up=against,
            view=view,
            candidates=len(frames),
            latency_ms=0.0,
            how="held",
            jump=jump,
        )

    def played_into(self, frame: int, k: int) -> list[int]:
        """``frame`` and up to ``k`` frames before it that play into it (in its clip),
        nearest first."""
        out = [frame]
        while len(out) <= k and out[-1] > 0 and self.plays[out[-1] - 1]:
            out.append(out[-1] - 1)
        return out

    def _held_cost(self, frame: int, queries: list[FloatArray]) -> tuple[float, int]:
        """The cost of ``frame`` held still against the performer's window (its best
        view's, weighed by the vote's margin where it shows another action than the
        voted one), and that view."""
        # the frame's features taken once, seen from every view (restricted to the best
        # window's view and its neighbours, the avatar holds less while the performer
        # stands still)
        one = self.windows.sequences(np.array([frame], dtype=np.int64))  # (V, 1, F)
        refs = np.repeat(one, self.n, axis=1)  # (one frame: its centre does not move)
        band = self.settings.band
        r = self.settings.recency
        costs = self.windows.weighed(
            np.array([dtw_batch(q, refs, window=band, recency=r) for q in queries]), frame
        )
        cost = float(costs.min())
        margin = self.margin()
        voting = self.vote.actions is not None and self.vote.size > 0 and math.isfinite(margin)
        if voting and self.vote.leaves(frame, frame):  # (held: the frame shows no other)
            cost *= 1.0 + margin  # (weighed as the avatar's own motion is, however taken)
        return cost, int(np.argmin(costs.min(axis=0))) % self.windows.ring_views

    def own_cost(self, queries: list[FloatArray], recent: IntArray) -> float:
        """DTW cost of the avatar's last frames ``recent`` (best view) against the
        performer: how well it follows now. The frames that lead into a window's first
        stand in for those not yet shown; ``inf`` where its clip has none."""
        w = self.lead_in(recent)[-self.n :]
        if w.size < self.n:
            return float("inf")
        band, r = self.settings.band, self.settings.recency
        if np.all(np.diff(w) == 1) and self.windows.same_run(int(w[0]), w[-1:])[0]:
            shape, centre, _ = self.windows.tables()  # a library window: as the search costs it
            costs = window_costs(queries, shape, centre, int(w[0]), self.n, band, r)
        else:
            refs = self.windows.sequences(w)
            costs = np.array([dtw_batch(q, refs, window=band, recency=r) for q in queries])
        return float(self.windows.weighed(costs, int(w[self.n // 2])).min())

    def own_frames(self, frame: int, recent: IntArray) -> IntArray:
        """The frames whose cost is the avatar's own (``jump``): with
        ``settings.landing.own_from_library`` the library window that plays into ``frame`` (when
        its clip has one), else the avatar's ``recent`` frames shown; either, with a lead,
        as far behind as the lead (the avatar is ahead of the performer by it)."""
        if self.settings.landing.own_from_library:
            lib = self.lead_in(np.array([self.behind(frame)], dtype=np.int64))
            if lib.size >= self.n:
                return lib
        if self.lead and recent.size > self.lead:
            return recent[: -self.lead]
        return recent

    def lead_in(self, recent: IntArray) -> IntArray:
        """``recent``, preceded by the frames that play on into its first one, up to
        ``recent_frames`` in all."""
        need = self.recent_frames - recent.size
        if need <= 0 or recent.size == 0:
            return recent
        lead = self.played_into(int(recent[0]), need)[:0:-1]  # (oldest first)
        return np.concatenate((np.array(lead, dtype=np.int64), recent))

    def margin(self) -> float:
        """The vote's margin (``ActionSettings.margin``): what another action's window,
        and the avatar's own motion or hold of another action, cost more."""
        return self.settings.action.margin

    def strict(self) -> bool:
        """Whether this decision's jumps go into the voted action alone: with the margin
        infinite, or where the last votes agree on the voted action by ``strict_share``
        at least, unless the ballot names another action (``named``). The avatar's own
        motion and its holds keep the margin: a performer standing still is still
        mirrored by a held frame of another action."""
        if self.named() is not None:
            return False
        share = self.settings.action.strict_share
        return math.isinf(self.margin()) or 0 < share <= self.vote.share()

    def named(self) -> int | None:
        """With the filter and ``action.ballot_jumps``: the action this decision's ballot
        names where the filter does not vote for it (yet); ``None`` otherwise, and with
        the margin infinite (no window of another action is ever taken)."""
        v = self.vote
        if not self.ballots_jump():
            return None
        return v.named if 0 <= v.named != v.voted else None

    def ballots_jump(self) -> bool:
        """Whether a decision's ballot may open the margin for its own action
        (``ActionSettings.ballot_jumps``: with the filter and a finite margin)."""
        st = self.settings.action
        return st.ballot_jumps and self.vote.switch > 0 and math.isfinite(self.margin())

    def kept(self, frame: int, ahead: int) -> bool:
        """Whether the avatar at ``frame``, which plays on to ``ahead``, shows another
        action than the voted one that a ballot named lately and still shows it there: its
        own motion then costs no margin (``ActionSettings.ballot_keep``)."""
        v = self.vote
        if v.actions is None or not self.ballots_jump():
            return False
        shows = int(v.actions[frame])
        return shows != v.voted and int(v.actions[ahead]) == shows and v.named_lately(shows)

    def gated(
        self,
        frame: int,
        queries: list[FloatArray],
        ranked: Ranked,
        costs: JumpCosts,
        found: tuple[Windows, IntArray, NDArray[np.bool_], NDArray[np.bool_]],
        voted: NDArray[np.bool_] | None,
    ) -> tuple[Windows, IntArray, NDArray[np.bool_], FloatArray, float]:
        """The action vote's part in a jump from ``frame``: the best windows ``found``
        (``(got, target, ok, there)``; ``voted``: which show the voted action), with those
        of the voted action added when none does (``voted_windows``), and ``(got,
        target, ok, weight, own_weight)``: each window's cost is times ``weight`` (1 + the
        settings' ``action.margin`` for another action, ``weak_margin`` where the best
        fits weakly: ``weak``), the avatar's own times
        ``own_weight`` (the same, where it shows another action, unless a ballot named
        that one lately: ``kept``). Where the decision is
        ``strict``, windows of another action are not ``ok``; where the ballot names
        another action (``named``), only its windows and the voted action's are, and
        while the performer does again what they did (``repeated``), the voted action's,
        the avatar's own action's and the one voted then instead (unless none of those
        is ``ok`` where the avatar cannot play on); with the margin infinite,
        ``own_weight`` is infinite where the avatar must leave its action."""
        got, target, ok, there = found
        if voted is None:
            return got, target, ok, np.ones(len(got)), 1.0
        margin, strict = self.margin(), self.strict()
        best = got  # (the search's best windows, before any of the voted action's join them)
        if not (ok & voted).any():
            more = self.voted_windows(frame, queries, ranked, costs, there & voted)
            if strict:
                got, target, ok, voted = more
            else:
                got = [*got, *more[0]]
                target = np.concatenate((target, more[1]))
                ok, voted = np.concatenate((ok, more[2])), np.concatenate((voted, more[3]))
        ahead = int(self.windows.playback(frame)[: self.n // 2 + 1][-1])
        away = self.vote.leaves(frame, ahead)
        own = 1.0 + margin if away and not self.kept(frame, ahead) else 1.0
        if strict:
            # playing on out of the voted action is not weighed: the avatar leaves first
            if away and not self.vote.leaves(frame, frame):
                own = math.inf
            return got, target, ok & voted, np.ones(len(got)), own
        other = (
            max(margin, self.settings.action.weak_margin) if self.weak(best, queries) else margin
        )
        named = self.named()
        if named is not None:  # (the ballot's action, or the voted one: no third)
            actions = self.vote.actions
            assert actions is not None
            keys = actions[np.clip(target, 0, actions.size - 1)]
            opened = keys == named
            if self.repeated is not None:  # no new action: the avatar's, or the one then
                kept = (keys == actions[frame]) | (keys == self.repeated)
                # (at its clip's end the avatar must jump: not into no window at all)
                if self.plays[frame] or (ok & (voted | kept)).any():
                    opened = kept
            ok = ok & (voted | opened)
        return got, target, ok, np.where(voted, 1.0, 1.0 + other), own

    def fits_weakly(self, cost: float, queries: list[FloatArray]) -> bool:
        """Whether a window's DTW ``cost`` against the performer (``queries``, its
        readings) fits weakly: per frame, over ``action.weak_fit`` times the reject
        threshold."""
        st = self.settings
        if not queries:
            return False
        reject = self.windows.desc.reject if st.reject is None else st.reject
        if not math.isfinite(reject * st.action.weak_fit):
            return False
        return per_frame_cost(cost, queries[0].shape[0]) > st.action.weak_fit * reject

    def weak(self, got: Windows, queries: list[FloatArray]) -> bool:
        """Whether the best of the windows ``got`` fits the performer (``queries``, its
        readings) weakly (``ActionSettings.weak_fit``): another action's window must
        then fit far better to be taken (``weak_margin``)."""
        return bool(got) and self.fits_weakly(min(g[2] for g in got), queries)

    def voted_windows(
        self,
        frame: int,
        queries: list[FloatArray],
        ranked: Ranked,
        costs: JumpCosts,
        at_voted: NDArray[np.bool_],
    ) -> tuple[Windows, IntArray, NDArray[np.bool_], NDArray[np.bool_]]:
        """None of the best windows shows the voted action: the best that do, from the
        same short lists ``ranked`` when they hold any, else by a search among those
        windows alone, unless the avatar is already at one of them (``at_voted``): no
        search can beat its own cost by much. ``(got, target, ok, voted)`` as ``jump``
        has them."""
        st = self.settings
        only = self.vote.starts(self.n)
        got = best_of(ranked, st.landing.top_windows, only)
        target, ok, _ = self.targets(frame, got, costs, queries)
        voted = self.vote.gate(target)
        if not (ok & voted).any() and not at_voted.any():
            lists: Ranked = []
            got = self.windows.ranked(queries, lists, only)
            facing = self.windows.facing
            if facing is not None:
                got = best_of(facing.weigh(lists, observe=False), st.landing.top_windows, only)
            target, ok, _ = self.targets(frame, got, costs, queries)
            voted = self.vote.gate(target)
        return got, target, ok, voted

    def targets(
        self,
        frame: int,
        got: list[tuple[int, int, float]],
        costs: JumpCosts,
        queries: list[FloatArray],
    ) -> Gate:
        """The frames after windows ``got`` (placed by the performer's last frames,
        ``phased_targets``, then played on by the lead), which a jump from ``frame`` may
        land on, and which the avatar is at anyway, within 2 frames in its run (not a
        window ahead: a jump a few frames on keeps the avatar in step)."""
        target = np.array([g[0] for g in got], dtype=np.int64) + self.n
        views = np.array([g[1] for g in got], dtype=np.int64)
        shape = self.windows.tables()[0]
        target = phased_targets(
            target, views, queries, shape, self.windows.runs, self.settings.landing.phase_frames
        )
        if self.lead:
            inside = target < self.graph.n_frames
            target[inside] = self.ahead(target[inside])
        ok = target < self.graph.n_frames
        ok[ok] &= costs.landing[target[ok]] & self.plays[target[ok] - 1]
        there = (np.abs(target - frame) <= 2) & self.windows.same_run(frame, target)
        return target, ok & ~there, there


def sparse_window(performer: FloatArray) -> bool:
    """Whether the performer's window ``(n, F)`` repeats a frame in at least half of its
    steps: its source gives frames slower than the library's rate (a 5 frames/s clip, a
    loaded page that drops frames), and each frame stands for the steps until the next.
    Such a window reads a performer in motion as one who stops at every frame, and
    landing a jump on a frame and holding it there lost the live page whole squats (the
    avatar held between squats while the performer squatted: ``benchmarks/HISTORY.md``,
    "Holds"), so the jumps are not held there."""
    x = np.asarray(performer)
    if len(x) < 2:
        return False
    same = np.all(x[1:] == x[:-1], axis=1)
    return bool(np.mean(same) >= 0.5)
