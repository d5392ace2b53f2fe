"""The cluster transition graph (Peng et al. §4.2) and its candidate paths (§4.3).

Nodes are clusters; each node holds the *runs* of contiguous frames of one motion clip
that lie in it. Two consecutive runs of a clip in different clusters make an edge between
those clusters, carrying the concatenated frames as a transition clip; a node pair may
have many such clips. Undirected graphs also let an edge be used backwards (the clip
played in reverse).

Edge cost (eq. 1): the frame count of the edge's shortest clip times the distance
between the two clusters' centre frames. For every node pair, up to ``k`` cheapest
simple paths whose total cost is under ``max_cost`` are kept as candidates; pairs without
any are known (``paths_between`` returns nothing).
"""

from __future__ import annotations

import heapq
import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..graph import FrameFeatures, pair_distances
from ._cluster import FrameClusters

__all__ = ["CandidatePaths", "TransitionGraph", "build_transition_graph", "candidate_paths"]

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class TransitionGraph:
    """Clusters as nodes, transition clips as edges.

    Attributes
    ----------
    runs : (R, 3) ``(first frame, stop frame, cluster)`` of every run of frames.
    edge_nodes : (E, 2) ``(from, to)`` cluster of each distinct edge.
    edge_cost, edge_frames, edge_distance : (E,) eq. 1 cost, shortest clip length,
        distance between the centres.
    clip_edge, clip_runs, clip_backward : (C,), (C, 2), (C,) every transition clip: its
        edge, its two runs, and whether it plays backwards (undirected graphs only).
    directed : whether clips may be played backwards.
    """

    clusters: FrameClusters
    runs: IntArray
    edge_nodes: IntArray
    edge_cost: FloatArray
    edge_frames: IntArray
    edge_distance: FloatArray
    clip_edge: IntArray
    clip_runs: IntArray
    clip_backward: NDArray[np.bool_]
    directed: bool

    @property
    def n_nodes(self) -> int:
        return self.clusters.k

    def clips_of(self, a: int, b: int) -> IntArray:
        """Transition clips from cluster ``a`` to cluster ``b``."""
        e = np.flatnonzero((self.edge_nodes[:, 0] == a) & (self.edge_nodes[:, 1] == b))
        return np.flatnonzero(np.isin(self.clip_edge, e))


def _runs(labels: IntArray, clip_start: IntArray) -> IntArray:
    out: list[tuple[int, int, int]] = []
    for a, b in itertools.pairwise(clip_start):
        lab = labels[a:b]
        cut = np.flatnonzero(np.diff(lab)) + 1
        starts = np.concatenate(([0], cut))
        stops = np.concatenate((cut, [b - a]))
        out.extend(
            (int(a + s), int(a + e), int(lab[s])) for s, e in zip(starts, stops, strict=True)
        )
    return np.array(out, dtype=np.int64).reshape(-1, 3)


def build_transition_graph(
    feat: FrameFeatures, clusters: FrameClusters, directed: bool = True, nu: float = 0.01
) -> TransitionGraph:
    """Edges from consecutive frames of a clip that change cluster."""
    runs = _runs(clusters.labels, feat.clip_start)
    same_clip = np.searchsorted(feat.clip_start, runs[:-1, 0], side="right") == np.searchsorted(
        feat.clip_start, runs[1:, 0], side="right"
    )
    first = np.flatnonzero(same_clip)
    pairs = [(int(i), int(i) + 1, False) for i in first]
    if not directed:
        pairs += [(int(i) + 1, int(i), True) for i in first]  # played backwards
    clip_runs = np.array([(a, b) for a, b, _ in pairs], dtype=np.int64).reshape(-1, 2)
    backward = np.array([bw for *_, bw in pairs], dtype=bool)
    nodes = np.stack((runs[clip_runs[:, 0], 2], runs[clip_runs[:, 1], 2]), axis=1)
    edge_nodes, clip_edge = np.unique(nodes, axis=0, return_inverse=True)
    clip_edge = clip_edge.reshape(-1)
    length = (runs[clip_runs[:, 0], 1] - runs[clip_runs[:, 0], 0]) + (
        runs[clip_runs[:, 1], 1] - runs[clip_runs[:, 1], 0]
    )
    edge_frames = np.full(edge_nodes.shape[0], np.iinfo(np.int64).max, dtype=np.int64)
    np.minimum.at(edge_frames, clip_edge, length)
    c = clusters.centres
    dist, _ = pair_distances(feat, c[edge_nodes[:, 0]], c[edge_nodes[:, 1]], nu)
    return TransitionGraph(
        clusters=clusters,
        runs=runs,
        edge_nodes=edge_nodes.astype(np.int64),
        edge_cost=edge_frames * dist,
        edge_frames=edge_frames,
        edge_distance=dist,
        clip_edge=clip_edge.astype(np.int64),
        clip_runs=clip_runs,
        clip_backward=backward,
        directed=directed,
    )


@dataclass(frozen=True, eq=False)
class CandidatePaths:
    """Up to ``k`` candidate paths per node pair, CSR over pairs.

    ``pairs`` (P, 2) node pairs that have paths; ``first`` (P + 1,) their ranges in
    ``cost`` (M,) and ``offsets`` (M + 1,) into ``nodes`` (the node sequences).
    """

    n_nodes: int
    pairs: IntArray
    first: IntArray
    cost: FloatArray
    offsets: IntArray
    nodes: IntArray
    k: int
    max_cost: float

    def paths_between(self, a: int, b: int) -> list[tuple[float, IntArray]]:
        """``[(cost, nodes)]`` of the candidates from ``a`` to ``b``, cheapest first."""
        key = a * self.n_nodes + b
        keys = self.pairs[:, 0] * self.n_nodes + self.pairs[:, 1]
        i = int(np.searchsorted(keys, key))
        if i >= keys.size or keys[i] != key:
            return []
        out = []
        for m in range(self.first[i], self.first[i + 1]):
            out.append((float(self.cost[m]), self.nodes[self.offsets[m] : self.offsets[m + 1]]))
        return out


def candidate_paths(
    graph: TransitionGraph, k: int = 5, max_cost: float | None = None
) -> CandidatePaths:
    """The ``k`` cheapest simple paths between every node pair, under ``max_cost``
    (default: 20 times the median edge cost).

    One best-first search per source node: a partial path leaves the queue in cost
    order, each node is settled at most ``k`` times, and paths never revisit a node.
    This is the k-shortest-walks algorithm restricted to simple paths: it is exact unless
    every one of the ``k`` cheapest paths to some node already passes through the target
    (then a path through that node can be missed). The tests compare it with brute-force
    enumeration on random small graphs.
    """
    if k < 1:
        raise ValueError("k must be at least 1")
    n = graph.n_nodes
    if max_cost is None:
        max_cost = 20.0 * float(np.median(graph.edge_cost)) if graph.edge_cost.size else 0.0
    out_edges: list[list[tuple[int, float]]] = [[] for _ in range(n)]
    for (a, b), c in zip(graph.edge_nodes, graph.edge_cost, strict=True):
        if a != b:
            out_edges[int(a)].append((int(b), float(c)))
    pair_list: list[tuple[int, int]] = []
    costs: list[float] = []
    seqs: list[tuple[int, ...]] = []
    first = [0]
    for s in range(n):
        found: dict[int, list[tuple[float, tuple[int, ...]]]] = {}
        settled = np.zeros(n, dtype=np.int64)
        heap: list[tuple[float, tuple[int, ...]]] = [(0.0, (s,))]
        while heap:
            cost, path = heapq.heappop(heap)
            node = path[-1]
            if settled[node] >= k:
                continue
            settled[node] += 1
            if node != s:
                found.setdefault(node, []).append((cost, path))
            for nxt, c in out_edges[node]:
                if nxt in path or settled[nxt] >= k:
                    continue
                total = cost + c
                if total <= max_cost:
                    heapq.heappush(heap, (total, (*path, nxt)))
        for t in sorted(found):
            pair_list.append((s, t))
            for cost, path in found[t]:
                costs.append(cost)
                seqs.append(path)
            first.append(len(costs))
    offsets = np.concatenate(([0], np.cumsum([len(p) for p in seqs]))).astype(np.int64)
    nodes = np.array([x for p in seqs for x in p], dtype=np.int64)
    return CandidatePaths(
        n_nodes=n,
        pairs=np.array(pair_list, dtype=np.int64).reshape(-1, 2),
        first=np.array(first, dtype=np.int64),
        cost=np.array(costs),
        offsets=offsets,
        nodes=nodes,
        k=k,
        max_cost=float(max_cost),
    )
