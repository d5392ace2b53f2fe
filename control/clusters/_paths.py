"""Cluster paths and their most probable motions (Lee et al. §4.2.3, eq. 7).

For a cluster path ``p = (c_0, ..., c_L)`` from frame ``s_0`` the most probable motion
``s = (s_0, ..., s_N)`` maximises ``prod_i P(s_{i-1} -> s_i) P(c(s_i) | s_i)``: every frame
stays in the current cluster of the path or moves to the next one, and the motion ends
at the first frame of the last cluster, within the time bound. ``P(s -> s')`` is eq. 1
normalised over the exits of ``s`` (playback has likelihood 1); ``P(c | s)`` is the
mixture's posterior of the frame's cluster.

The search is an exact dynamic programme over (frame, position in the path) layer by
layer in time; since every factor is at most 1, a partial motion that is already less
probable than the best finished one, or than an earlier arrival at the same state, is
dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from ..graph import MotionGraph
from ..kernels import kernel_input

__all__ = ["ProbableMotion", "most_probable_motion", "transition_log_probs"]

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class ProbableMotion:
    """A concrete motion through a cluster path.

    Attributes
    ----------
    frames : (N + 1,) graph frames ``s_0 .. s_N``.
    edges : (N,) the transition taken into ``frames[i + 1]``, -1 for playback.
    clusters : the cluster path.
    log_prob : log of eq. 7.
    """

    frames: IntArray
    edges: IntArray
    clusters: IntArray
    log_prob: float

    @property
    def jumps(self) -> IntArray:
        """Positions ``t`` in ``frames`` reached by a transition."""
        return (np.flatnonzero(self.edges >= 0) + 1).astype(np.int64)


def transition_log_probs(graph: MotionGraph) -> tuple[FloatArray, FloatArray]:
    """``(log_play (n,), log_edge (E,))``: eq. 1 normalised over each frame's exits."""
    like = graph.likelihood()
    plays = graph.plays_on().astype(np.float64)
    total = plays + np.bincount(graph.src, weights=like, minlength=graph.n_frames)
    with np.errstate(divide="ignore"):
        log_play = np.where(plays > 0, -np.log(np.where(total > 0, total, 1.0)), -np.inf)
        log_edge = np.log(like) - np.log(total[graph.src])
    return log_play, log_edge


@numba.njit(cache=True, nogil=True)
def _viterbi(
    s0: int,
    path: np.ndarray,
    labels: np.ndarray,
    log_post: np.ndarray,
    indptr: np.ndarray,
    dst: np.ndarray,
    log_edge: np.ndarray,
    log_play: np.ndarray,
    bound: int,
    max_states: int,
) -> tuple[np.ndarray, np.ndarray, float]:
    last = path.size - 1
    st_f = np.empty(max_states, np.int64)
    st_k = np.empty(max_states, np.int64)
    st_score = np.empty(max_states)
    st_prev = np.empty(max_states, np.int64)
    st_edge = np.empty(max_states, np.int64)
    st_f[0] = s0
    st_k[0] = 0
    st_score[0] = 0.0
    st_prev[0] = -1
    st_edge[0] = -1
    n_st = 1
    n_keys = labels.size * (last + 1)
    best_seen = np.full(n_keys, -np.inf)
    in_layer = np.full(n_keys, -1, np.int64)
    best_goal = -np.inf
    goal = -1
    lo = 0
    hi = 1
    for _t in range(bound):
        for si in range(lo, hi):
            f = st_f[si]
            k = st_k[si]
            if k == last:
                continue
            base = st_score[si]
            n_out = indptr[f + 1] - indptr[f]
            for x in range(n_out + 1):
                if x < n_out:
                    e = indptr[f] + x
                    g = dst[e]
                    lp = log_edge[e]
                else:
                    if log_play[f] == -np.inf:
                        continue
                    e = -1
                    g = f + 1
                    lp = log_play[f]
                c = labels[g]
                if c == path[k]:
                    k2 = k
                elif c == path[k + 1]:
                    k2 = k + 1
                else:
                    continue
                s2 = base + lp + log_post[g]
                if s2 <= best_goal:
                    continue
                key = g * (last + 1) + k2
                if s2 <= best_seen[key]:
                    continue
                best_seen[key] = s2
                if in_layer[key] >= 0:
                    j = in_layer[key]
                    st_score[j] = s2
                    st_prev[j] = si
                    st_edge[j] = e
                else:
                    if n_st >= max_states:
                        return np.empty(0, np.int64), np.empty(0, np.int64), -np.inf
                    j = n_st
                    n_st += 1
                    in_layer[key] = j
                    st_f[j] = g
                    st_k[j] = k2
                    st_score[j] = s2
                    st_prev[j] = si
                    st_edge[j] = e
                if k2 == last and s2 > best_goal:
                    best_goal = s2
                    goal = j
        for j in range(hi, n_st):  # forget this layer's index before the next
            in_layer[st_f[j] * (last + 1) + st_k[j]] = -1
        lo = hi
        hi = n_st
        if lo == hi:
            break
    if goal < 0:
        return np.empty(0, np.int64), np.empty(0, np.int64), -np.inf
    length = 0
    j = goal
    while j >= 0:
        length += 1
        j = st_prev[j]
    frames = np.empty(length, np.int64)
    edges = np.empty(length - 1, np.int64)
    j = goal
    for i in range(length - 1, -1, -1):
        frames[i] = st_f[j]
        if i > 0:
            edges[i - 1] = st_edge[j]
        j = st_prev[j]
    return frames, edges, best_goal


def most_probable_motion(
    graph: MotionGraph,
    labels: IntArray,
    posterior: FloatArray,
    start: int,
    clusters: IntArray,
    bound: int,
    tables: tuple[FloatArray, FloatArray] | None = None,
    max_states: int = 1_000_000,
) -> ProbableMotion | None:
    """The most probable motion from frame ``start`` through the cluster path ``clusters``
    (whose first cluster must be ``start``'s), within ``bound`` frames; ``None`` if none.

    ``tables`` are ``transition_log_probs(graph)``, passed in to reuse them.
    """
    clusters = np.asarray(clusters, dtype=np.int64)
    if clusters.size == 0 or clusters[0] != labels[start]:
        raise ValueError("the cluster path must start with the start frame's cluster")
    if np.any(clusters[1:] == clusters[:-1]):
        raise ValueError("consecutive clusters of a path must differ")
    log_play, log_edge = tables if tables is not None else transition_log_probs(graph)
    if clusters.size == 1:
        return ProbableMotion(np.array([start]), np.zeros(0, np.int64), clusters, 0.0)
    with np.errstate(divide="ignore"):
        log_post = np.log(np.asarray(posterior, dtype=np.float64))
    frames, edges, score = _viterbi(
        int(start),
        kernel_input(clusters, np.int64),
        kernel_input(labels, np.int64),
        kernel_input(log_post, np.float64),
        kernel_input(graph.indptr, np.int64),
        kernel_input(graph.dst, np.int64),
        kernel_input(log_edge, np.float64),
        kernel_input(log_play, np.float64),
        int(bound),
        int(max_states),
    )
    if frames.size == 0:
        return None
    return ProbableMotion(frames, edges, clusters, float(score))
