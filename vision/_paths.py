"""The candidate paths of Lee et al.'s vision interface (§5.3), one of ``Matcher``'s
collaborators: the nodes of the avatar's cluster tree reached within the look-ahead, the
most probable motion to each, and the shortest route through the graph's component to a
frame."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from control.clusters import HigherLayer

from ._settings import PathSettings

__all__ = ["CandidatePaths"]

IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


class CandidatePaths:
    """Lee et al.'s candidate paths through ``layer``'s cluster forest with ``settings``
    (``PathSettings``): windows of ``n`` frames, paths reaching ``bound`` frames ahead,
    ``plays`` whether each graph frame plays on into the next."""

    def __init__(
        self, layer: HigherLayer, settings: PathSettings, n: int, bound: int, plays: BoolArray
    ) -> None:
        self.layer, self.graph, self.settings = layer, layer.graph, settings
        self.n, self.bound, self.plays = n, bound, plays
        #: each (tree root, node)'s most probable motion, made once
        self._cache: dict[tuple[int, int], tuple[IntArray, IntArray] | None] = {}

    def route(self, frame: int, target: int) -> tuple[IntArray, IntArray] | None:
        """The shortest way ``(frames, edges)`` from ``frame`` to ``target`` through the
        graph's component (playing on and transitions, one frame per step; breadth
        first), at most ``route_seconds`` long, or ``None``."""
        bound = max(1, round(self.settings.route_seconds * self.graph.fps))
        return self.graph.route(frame, target, bound, self.plays)

    def _path(self, frame: int, node: int) -> tuple[IntArray, IntArray] | None:
        tree = self.layer.forest.tree(frame)
        key = (tree.root_frame, node)
        if key in self._cache:
            got = self._cache[key]
        else:
            if len(self._cache) > 200_000:  # bound the memory of a long run
                self._cache.clear()
            # the node is reached within the look-ahead, so no longer motion is needed
            m = self.layer.motion_to(tree.root_frame, node, self.bound)
            got = None if m is None else (m.frames, m.edges)
            self._cache[key] = got
        if got is None:
            return None
        frames, edges = got
        lead = np.arange(frame, tree.root_frame, dtype=np.int64)
        return (
            np.concatenate((lead, frames)),
            np.concatenate((np.full(lead.size, -1, dtype=np.int64), edges)),
        )

    def window_frames(self, frames: IntArray) -> IntArray:
        """The first ``n`` frames of a path, played on past its end when it is short."""
        out = [int(f) for f in frames[: self.n]]
        while len(out) < self.n:  # played on while it can, then held
            out.append(out[-1] + 1 if self.plays[out[-1]] else out[-1])
        return np.array(out, dtype=np.int64)

    def candidates(self, frame: int) -> list[tuple[int, IntArray, IntArray]]:
        """``(node, frames, edges)`` of the candidate paths from ``frame``: nodes reached
        within the look-ahead, earliest first, at most ``max_candidates`` whose first
        ``window`` seconds differ (paths that part only later look the same to DTW)."""
        if self.layer.forest.tree_of[frame] < 0:  # outside the component (after a jump)
            return []
        tree = self.layer.forest.tree(frame)
        lead = tree.root_frame - frame
        reach = tree.arrival + lead <= self.bound
        reach[0] = True
        nodes = np.flatnonzero(reach)
        nodes = nodes[np.argsort(tree.arrival[nodes], kind="stable")]
        out = []
        seen: set[bytes] = set()
        for node in nodes:
            p = self._path(frame, int(node))
            if p is None:
                continue
            key = self.window_frames(p[0]).tobytes()
            if key in seen:
                continue
            seen.add(key)
            out.append((int(node), p[0], p[1]))
            if len(out) >= self.settings.max_candidates:
                break
        return out
