"""Where the avatar goes next, for ``Matcher``: a direct jump lands on the frame after
one of the search's best windows, placed by the performer's last frames
(``phased_targets``), unless the avatar is there already; or, for a performer standing
still, the avatar holds its frame (``held``)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from control.avatar import JumpCosts
from control.dtw import ShapeTable, dtw_batch
from control.graph import MotionGraph

from ._decision import Decision, MatchSettings
from ._facing import Facing
from ._windows import phased_targets

__all__ = ["Gate", "Landing"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
#: ``(target, ok, there)``: the frames after the windows, which a jump may land on, and
#: which the avatar is at already
Gate = tuple[IntArray, NDArray[np.bool_], NDArray[np.bool_]]


class Landing:
    """What ``Matcher`` inherits for its jumps' targets and for holding still; it sets the
    attributes below."""

    graph: MotionGraph
    settings: MatchSettings
    n: int
    plays: NDArray[np.bool_]
    _runs: IntArray
    _global_tables: Callable[[], tuple[ShapeTable, FloatArray, IntArray]]
    _bank_sequences: Callable[[IntArray], FloatArray]
    ring_views: int
    last_own: float
    #: the performer's facing, for silhouettes read both ways (set by the caller, who has
    #: the library's motion: ``Performance``)
    facing: Facing | None

    def weighed(self, costs: FloatArray, middle: int) -> FloatArray:
        """Costs ``(readings, V)`` of one window (its middle frame ``middle``) in each
        view, weighed by the performer's ``facing`` when there is one."""
        return costs if self.facing is None else self.facing.weigh_views(costs, middle)

    def held(
        self, frame: int, queries: list[FloatArray], rival: Decision | None
    ) -> Decision | None:
        """The avatar holding ``frame`` still (shown again, as a performer standing
        still does), when ``settings.still`` and that matches the performer's window
        better than ``rival`` (the jump ``Matcher.jump`` chose, unless it leaves for the
        voted action) or, without one, than playing on; else ``None``. The library has no
        still second (its stillest windows still turn a joint 1.5-5 degrees a frame), so
        without it the avatar jumped about 4 times a second among near-still windows
        while the performer stood still."""
        if not self.settings.still or (rival is not None and rival.extra.get("leave")):
            return None
        against = rival.cost if rival is not None else self.last_own
        if not np.isfinite(against):
            return None
        # the frame's features taken once, seen from every view (restricted to the best
        # window's view and its two neighbours, the avatar held less: on bench_accuracy's
        # pauses, 13_31 with landmarks, 129 -> 204 jumps a minute while the performer
        # stood still)
        one = self._bank_sequences(np.array([frame], dtype=np.int64))  # (V, 1, F)
        refs = np.repeat(one, self.n, axis=1)  # (one frame: its centre does not move)
        band = self.settings.band
        costs = self.weighed(np.array([dtw_batch(q, refs, window=band) for q in queries]), frame)
        cost = float(costs.min())
        if not cost < self.settings.jump_ratio * against:
            return None
        frames = np.full(self.n + 1, frame, dtype=np.int64)
        return Decision(
            frames=frames,
            edges=np.full(self.n, -1, dtype=np.int64),
            cluster_path=np.zeros(0, dtype=np.int64),
            cost=cost,
            runner_up=against,
            view=int(np.argmin(costs.min(axis=0))) % self.ring_views,
            candidates=1,
            latency_ms=0.0,
            extra={"held": 1.0},
        )

    def _targets(
        self,
        frame: int,
        got: list[tuple[int, int, float]],
        costs: JumpCosts,
        queries: list[FloatArray],
    ) -> Gate:
        """The frames after windows ``got`` (placed by the performer's last frames,
        ``phased_targets``), which a jump from ``frame`` may land on, and which the avatar
        is at anyway, within 2 frames in its run (up to a window ahead before 2026-12-04:
        pose score 0.701 -> 0.708 on bench_accuracy's 12 landmark runs)."""
        target = np.array([g[0] for g in got], dtype=np.int64) + self.n
        views = np.array([g[1] for g in got], dtype=np.int64)
        shape = self._global_tables()[0]
        target = phased_targets(target, views, queries, shape, self._runs, self.settings.phase)
        ok = target < self.graph.n_frames
        ok[ok] &= costs.landing[target[ok]] & self.plays[target[ok] - 1]
        there = (np.abs(target - frame) <= 2) & self._same_run(frame, target)
        return target, ok & ~there, there

    def _playback(self, frame: int) -> IntArray:
        """``frame`` and up to a window of frames playing on from it."""
        out = [frame]
        while len(out) <= self.n and self.plays[out[-1]]:
            out.append(out[-1] + 1)
        return np.array(out, dtype=np.int64)

    def _same_run(self, frame: int, target: IntArray) -> NDArray[np.bool_]:
        """Whether ``frame`` plays on to each of ``target`` (or back from it)."""
        return self._runs[np.clip(target, 0, self.graph.n_frames - 1)] == self._runs[frame]
