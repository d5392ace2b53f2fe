"""Run-time pieces of Peng et al. §5: locate the node pair, pick a path, stitch its clips.

All work on frame indices into the library's frames end to end (as ``FrameFeatures``);
a synthesized sequence is a list of such frames (a clip played backwards appears in
descending order).
"""

from __future__ import annotations

import itertools

import numpy as np
from numpy.typing import NDArray

from ..graph import FrameFeatures, pair_distances
from ._cluster import FrameClusters
from ._tgraph import CandidatePaths, TransitionGraph

__all__ = ["choose_path", "clip_frames", "nearest_cluster", "stitch_path", "transition_point"]

IntArray = NDArray[np.int64]


def nearest_cluster(
    feat: FrameFeatures, clusters: FrameClusters, frame: int, nu: float = 0.01
) -> int:
    """The cluster whose centre frame is nearest ``frame`` (§5.1: it need not be the
    frame's own cluster)."""
    c = clusters.centres
    d, _ = pair_distances(feat, np.full(c.size, frame), c, nu)
    return int(np.argmin(d))


def choose_path(paths: CandidatePaths, a: int, b: int, rng: np.random.Generator) -> IntArray | None:
    """One candidate path from node ``a`` to ``b``, drawn with probability inversely
    proportional to its cost (§5.2); ``[a]`` when ``a == b``; ``None`` when there is none."""
    if a == b:
        return np.array([a], dtype=np.int64)
    cands = paths.paths_between(a, b)
    if not cands:
        return None
    w = np.array([1.0 / max(c, 1e-12) for c, _ in cands])
    k = int(rng.choice(len(cands), p=w / w.sum()))
    return cands[k][1]


def clip_frames(graph: TransitionGraph, clip: int) -> IntArray:
    """The frames of a transition clip in playing order."""
    r0, r1 = graph.clip_runs[clip]
    a = min(int(graph.runs[r0, 0]), int(graph.runs[r1, 0]))
    stop = max(int(graph.runs[r0, 1]), int(graph.runs[r1, 1]))
    frames = np.arange(a, stop, dtype=np.int64)
    return frames[::-1].copy() if graph.clip_backward[clip] else frames


def transition_point(
    feat: FrameFeatures, tail: IntArray, head: IntArray, nu: float = 0.01
) -> tuple[int, int, float]:
    """``(i, j, d)``: leave ``tail`` after its ``i``-th frame and enter ``head`` at its
    ``j``-th, where the distance grid between them is smallest (§5.3)."""
    tail = np.asarray(tail, dtype=np.int64)
    head = np.asarray(head, dtype=np.int64)
    a = np.repeat(tail, head.size)
    b = np.tile(head, tail.size)
    d, _ = pair_distances(feat, a, b, nu)
    k = int(np.argmin(d))
    return k // head.size, k % head.size, float(d[k])


def stitch_path(
    feat: FrameFeatures,
    graph: TransitionGraph,
    motion: list[int],
    path: IntArray,
    max_clip: int = 90,
    tail: int = 10,
    head: int = 25,
    nu: float = 0.01,
) -> list[int]:
    """Append the clips of ``path`` to ``motion`` greedily (§5.3).

    For each node pair of the path, the clip (at most ``max_clip`` frames) whose first
    frame is nearest the motion's last frame; the two are joined at the optimal
    transition point of a ``tail`` x ``head`` distance grid.
    """
    out = list(motion)
    for a, b in itertools.pairwise(path):
        clips = graph.clips_of(int(a), int(b))
        frames = [clip_frames(graph, int(c)) for c in clips]
        frames = [f for f in frames if f.size <= max_clip] or frames
        if not frames:
            raise ValueError(f"no transition clip from cluster {a} to {b}")
        firsts = np.array([f[0] for f in frames])
        d, _ = pair_distances(feat, np.full(firsts.size, out[-1]), firsts, nu)
        best = frames[int(np.argmin(d))]
        t = np.array(out[-tail:], dtype=np.int64)
        i, j, _ = transition_point(feat, t, best[:head], nu)
        out = out[: len(out) - t.size + i + 1] + best[j:].tolist()
    return out
