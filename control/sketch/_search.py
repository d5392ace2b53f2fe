"""The sketch tracker's second approach (Lee et al. §5.2, eq. 8): each step a best-first
search in the lower layer for a path of ``step_frames`` frames, committed."""

from __future__ import annotations

import heapq
import time
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ..graph import compose

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
    g = tr.graph
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
        succ: list[tuple[int, int]] = []
        if tr._plays[f] and g.in_scc[f + 1]:
            succ.append((f + 1, -1))
        for e in range(tr._indptr[f], tr._indptr[f + 1]):
            succ.append((int(g.dst[e]), e))
        for h, e in succ:
            if e >= 0:
                al = tr._align[e]
                yaw2, trans2 = compose(yaw, trans, float(al[0]), al[1:])
            else:
                yaw2, trans2 = yaw, trans
            x2, z2, a2 = tr._ground(h, yaw2, trans2)
            if tr.env is not None and tr.env.clearance(np.array([[x2, z2]]))[0] < s.body_radius:
                continue
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
