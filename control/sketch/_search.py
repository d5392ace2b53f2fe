"""The sketch tracker's second approach (Lee et al. §5.2, eq. 8): each step a best-first
search in the lower layer for a path of ``step_frames`` frames, committed."""

from __future__ import annotations

import heapq
import math
import time
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from ._track import SketchTracker

__all__ = ["search_step"]

FloatArray = NDArray[np.float64]


def search_step(tr: SketchTracker) -> int:
    """One step of the second approach (eq. 8): best-first search for a path of
    ``step_frames`` frames from the avatar's frame, the first complete one committed;
    the number of frames added (0: every way on collides)."""
    t0 = time.perf_counter()
    s = tr.settings
    x, z, a = tr.position()
    first, goal0 = tr._score(x, z, a, tr.goal)
    tr.goal = goal0  # goals within reach where the avatar stands (a grown sketch)
    if tr.done:
        return 0
    # nodes: (frame, yaw, trans, depth, parent, edge, goal)
    nodes: list[tuple[int, float, FloatArray, int, int, int, int]] = [
        (tr.frame, tr._yaw, tr._trans, 0, -1, -1, goal0)
    ]
    heap = [(first, 0)]
    found = -1
    expanded = 0
    deepest = (0, 0.0, 0)  # (depth, -score, node): the fallback when the search runs out
    while heap and expanded < s.max_expansions:
        score, i = heapq.heappop(heap)
        f, yaw, trans, depth, _, _, goal = nodes[i]
        if depth == s.step_frames or goal >= len(tr.goals):
            if f not in tr._banned:
                found = i
                break
            continue
        deepest = max(deepest, (depth, -score, i))
        expanded += 1
        for h, e, yaw2, trans2, x2, z2, a2 in _successors(tr, f, yaw, trans):
            if tr.blocks is not None and not tr.blocks.fits(h, yaw2, trans2):
                continue
            score, goal2 = tr._score(x2, z2, a2, goal)
            nodes.append((h, yaw2, trans2, depth + 1, i, e, goal2))
            heapq.heappush(heap, (score, len(nodes) - 1))
    tr.expansions.append(expanded)
    tr.step_seconds.append(time.perf_counter() - t0)
    tr.search_seconds += tr.step_seconds[-1]
    if found < 0 and heap:
        found = deepest[2]  # out of expansions: the best of the longest partial paths
    if found <= 0:  # every way on collides (a local minimum of eq. 8)
        return 0
    tr._undo.append(((len(tr.frames), len(tr.jumps), tr._yaw, tr._trans, tr.goal), tr._banned))
    tr._banned = set()
    chain = []
    i = found
    while nodes[i][4] >= 0:
        chain.append(i)
        i = nodes[i][4]
    for i in reversed(chain):
        f, yaw, trans, _, _, e, goal = nodes[i]
        if e >= 0:
            tr.jumps.append(len(tr.frames))
            tr.edges.append(e)
        tr.frames.append(f)
    last = nodes[found]
    tr._yaw, tr._trans, tr.goal = last[1], last[2], last[6]
    return len(chain)


class SearchTable:
    """What the search reads of each frame, as Python numbers (the search opens hundreds
    of thousands of nodes, one to a few successors each: numbers, not small arrays):
    per frame its root ``(x, y, z)``, heading, and the ways on ``(frame, edge (-1: plays
    on), alignment yaw, alignment x, y, z)``."""

    def __init__(self, tr: SketchTracker) -> None:
        g = tr.graph
        self.root: list[list[float]] = tr._root.tolist()
        self.heading: list[float] = tr._heading.tolist()
        dst, align, indptr = g.dst.tolist(), tr._align.tolist(), tr._indptr.tolist()
        on = [*(tr._plays[:-1] & g.in_scc[1:]).tolist(), False]
        self.ways: list[list[tuple[int, int, float, float, float, float]]] = []
        for f in range(len(self.root)):
            ways = [(f + 1, -1, 0.0, 0.0, 0.0, 0.0)] if on[f] else []
            for e in range(indptr[f], indptr[f + 1]):
                a = align[e]
                ways.append((dst[e], e, a[0], a[1], a[2], a[3]))
            self.ways.append(ways)


def _successors(
    tr: SketchTracker, f: int, yaw: float, trans: FloatArray
) -> list[tuple[int, int, float, FloatArray, float, float, float]]:
    """The frames the avatar can go on to from frame ``f`` placed by ``(yaw, trans)``:
    ``(frame, edge (-1: plays on), yaw, trans, x, z, facing)`` each, those whose root
    stands closer than the body's radius to an obstacle left out. The maps compose as
    ``control.graph.compose`` does and the roots are placed as ``SketchTracker._ground``
    does, in the same floating-point operations."""
    table = tr._search_table
    if table is None:
        table = tr._search_table = SearchTable(tr)
    ways = table.ways[f]
    if not ways:
        return []
    c, s = math.cos(yaw), math.sin(yaw)
    tx, ty, tz = trans.tolist()
    out = []
    for h, e, ayaw, ax, ay, az in ways:
        if e < 0:
            yaw2, trans2 = yaw, trans
        else:
            yaw2 = yaw + ayaw
            trans2 = np.array((c * ax + s * az + tx, ay + ty, -s * ax + c * az + tz))
        rx, _ry, rz = table.root[h]
        c2, s2 = math.cos(yaw2), math.sin(yaw2)
        mx, _, mz = trans2.tolist()
        x2 = c2 * rx + s2 * rz + mx
        z2 = -s2 * rx + c2 * rz + mz
        out.append((h, e, yaw2, trans2, x2, z2, yaw2 + table.heading[h]))
    if tr.env is not None:
        xz = np.array([(o[4], o[5]) for o in out])
        keep = tr.env.clearance(xz) >= tr.settings.body_radius
        out = [o for o, k in zip(out, keep.tolist(), strict=True) if k]
    return out
