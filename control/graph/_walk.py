"""The random walk (Lee et al. §4.1): the probabilistic motion the avatar falls back on."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ._graph import MotionGraph

__all__ = ["random_step", "random_walk"]

IntArray = NDArray[np.int64]


def random_step(
    graph: MotionGraph,
    frame: int,
    u: float,
    indptr: IntArray,
    like: NDArray[np.float64],
    plays: NDArray[np.bool_],
) -> tuple[int, int]:
    """One step of eq. 1 from ``frame`` with the uniform draw ``u``: ``(next frame, edge)``,
    edge -1 for playback. ``indptr``, ``like``, ``plays`` are the graph's (passed in so
    that a loop computes them once)."""
    lo, hi = indptr[frame], indptr[frame + 1]
    w_play = 1.0 if plays[frame] else 0.0
    total = w_play + float(like[lo:hi].sum())
    if total <= 0.0:
        raise RuntimeError(f"dead end at graph frame {frame}: the component is broken")
    x = u * total
    if x < w_play:
        return frame + 1, -1
    e = lo + int(np.searchsorted(np.cumsum(like[lo:hi]), x - w_play, side="right"))
    e = min(e, hi - 1)
    return int(graph.dst[e]), int(e)


def random_walk(
    graph: MotionGraph, n_frames: int, seed: int = 0, start: int | None = None
) -> tuple[IntArray, IntArray, IntArray]:
    """A seeded walk of ``n_frames`` frames following eq. 1.

    At frame ``i`` the next frame is ``i + 1`` (likelihood 1) or the target of one of
    ``i``'s transitions (likelihood ``exp(-D / sigma)``), drawn in proportion. Only frames
    of the largest strongly connected component are visited, so the walk never meets a
    dead end.

    Returns
    -------
    frames : (n_frames,) graph frames.
    jumps : (M,) output frames where a transition lands.
    edges : (M,) the transitions taken.
    """
    if n_frames < 1:
        raise ValueError("n_frames must be at least 1")
    rng = np.random.default_rng(seed)
    scc = np.flatnonzero(graph.in_scc)
    if scc.size < 2:  # none, or one frame without a way back to itself
        raise ValueError(
            f"the graph's strongly connected component has {scc.size} frame"
            f"{'' if scc.size == 1 else 's'}: too small to walk in (loosen --threshold or "
            "--sigma-scale, or add clips)"
        )
    if start is None:
        f = int(rng.choice(scc))
    else:
        if not (0 <= start < graph.n_frames and graph.in_scc[start]):
            raise ValueError(f"start frame {start} is not in the graph's component")
        f = int(start)
    indptr = graph.indptr
    like = graph.likelihood()
    plays = graph.plays_on()
    frames = np.empty(n_frames, dtype=np.int64)
    jumps: list[int] = []
    edges: list[int] = []
    frames[0] = f
    u = rng.random(n_frames)
    for t in range(1, n_frames):
        f, e = random_step(graph, f, float(u[t]), indptr, like, plays)
        if e >= 0:
            jumps.append(t)
            edges.append(e)
        frames[t] = f
    return frames, np.array(jumps, dtype=np.int64), np.array(edges, dtype=np.int64)
