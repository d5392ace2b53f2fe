"""The sketch tracker's first approach (Lee et al. §5.2): at each step, the cluster path
of the avatar's cluster tree whose most probable motion's root path is nearest the
sketch ahead by DTW (the root path resampled every ``dtw_spacing`` metres against as
much of the sketch ahead as the path is long), plus the sketch length left beyond that
part, performed to its end."""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..clusters import HigherLayer
from ..dtw import dtw
from ..graph import compose
from ._ground import SketchSettings, ground_path, resample_polyline

if TYPE_CHECKING:
    from ._track import SketchTracker

__all__ = ["ActionPlanner"]

FloatArray = NDArray[np.float64]


class ActionPlanner:
    """The first approach over ``layer`` (the graph's higher layer): ``set_sketch`` when
    the sketch changes, ``step`` to choose and commit an action; ``progress`` is the
    metres of the sketch matched so far."""

    def __init__(self, layer: HigherLayer, settings: SketchSettings) -> None:
        self.layer = layer
        self.settings = settings
        self.progress = 0.0
        self.fine = np.zeros((0, 2))
        self.fine_s = np.zeros(0)

    def set_sketch(self, sketch: FloatArray) -> None:
        """The sketch every ``dtw_spacing`` metres from its start, with arc lengths."""
        self.fine = np.vstack((sketch[:1], resample_polyline(sketch, self.settings.dtw_spacing)))
        steps = np.linalg.norm(np.diff(self.fine, axis=0), axis=1)
        self.fine_s = np.concatenate(([0.0], np.cumsum(steps)))

    def actions(self, tr: SketchTracker) -> list[int]:
        """The first approach's candidates: nodes of the avatar's cluster tree first
        reached within the look-ahead that have no child within it (cluster paths)."""
        tree = self.layer.forest.tree(tr.frame)
        t = (tree.arrival + tree.root_frame - tr.frame) / tr.graph.fps
        _, leaves = tree.subtree(t <= self.settings.lookahead)
        return [int(x) for x in leaves if x != 0]

    def step(self, tr: SketchTracker) -> int:
        """The first approach: choose the action whose root path is nearest the sketch
        ahead by DTW (against the part of the sketch ahead as long as the root path),
        plus the sketch left beyond that part; commit it."""
        t0 = time.perf_counter()
        s = self.settings
        g = tr.graph
        bound = math.floor(s.lookahead * g.fps + 1e-9)
        total = float(self.fine_s[-1])
        best: tuple[float, Any, float] | None = None
        actions = self.actions(tr)
        if len(actions) > s.max_actions:  # an even spread of them
            pick = np.linspace(0, len(actions) - 1, s.max_actions).round().astype(int)
            actions = [actions[i] for i in np.unique(pick)]
        tried = 0
        for node in actions:
            pm = self.layer.motion_to(tr.frame, node, bound)
            if pm is None or pm.frames.size < 2:
                continue
            tried += 1
            ground, _ = ground_path(
                tr._root, tr._heading, tr._align, pm.frames, pm.edges, tr._yaw, tr._trans
            )
            if tr.env is not None and tr.env.clearance(ground).min() < s.body_radius:
                continue
            q = np.vstack((ground[:1], resample_polyline(ground, s.dtw_spacing)))
            length = float(np.linalg.norm(np.diff(ground, axis=0), axis=1).sum())
            # the part of the sketch it covers: up to the point nearest its end (no
            # further on than its own length and a metre)
            end = self.nearest_along(ground[-1], self.progress, self.progress + length + 1.0)
            ahead = self.sketch_between(self.progress, end, q.shape[0])
            cost = dtw(q, ahead) / math.sqrt(q.shape[0]) + (total - end)
            if best is None or cost < best[0]:
                best = (cost, pm, end)
        tr.expansions.append(tried)
        tr.step_seconds.append(time.perf_counter() - t0)
        tr.search_seconds += tr.step_seconds[-1]
        if best is None:
            return 0
        _, pm, end = best
        n0 = len(tr.frames)
        for i, e in enumerate(pm.edges):
            if e >= 0:
                al = tr._align[e]
                tr._yaw, tr._trans = compose(tr._yaw, tr._trans, float(al[0]), al[1:])
                tr.jumps.append(n0 + i)
                tr.edges.append(int(e))
        tr.frames.extend(int(f) for f in pm.frames[1:])
        # progress: that part; its goals are reached when the avatar ends within twice
        # ``reach`` of the sketch
        self.progress = max(self.progress, end)
        x, z, a = tr.position()
        if np.hypot(*(self.sketch_between(end, end, 1)[0] - (x, z))) <= 2.0 * s.reach:
            goal_s = total - tr._ahead  # arc length of each goal
            reached = int(np.searchsorted(goal_s, self.progress + s.reach, side="right"))
            tr.goal = max(tr.goal, reached)
        tr.goal = max(tr.goal, tr._score(x, z, a, tr.goal)[1])
        return pm.frames.size - 1

    def nearest_along(self, p: FloatArray, s0: float, s1: float) -> float:
        """Arc length of the sketch point nearest ``p`` between arc lengths ``s0``, ``s1``
        (every ``dtw_spacing`` metres)."""
        lo, hi = np.searchsorted(self.fine_s, (s0, s1), side="right")
        lo = max(int(lo) - 1, 0)
        pts = self.fine[lo : max(int(hi), lo + 1)]
        k = int(np.argmin(np.hypot(pts[:, 0] - p[0], pts[:, 1] - p[1])))
        return max(s0, float(self.fine_s[lo + k]))

    def sketch_between(self, s0: float, s1: float, n: int) -> FloatArray:
        """``n`` points evenly spaced along the sketch from arc length ``s0`` to ``s1``."""
        at = np.linspace(s0, s1, max(n, 2))
        return np.stack([np.interp(at, self.fine_s, self.fine[:, k]) for k in range(2)], axis=1)
