"""The cluster forest (Lee et al. §4.2.2): a tree of reachable clusters for every frame.

The tree of frame ``r`` starts as one node, ``r``'s cluster. Following the graph from
``r`` (playback and transitions), each step into a frame of another cluster moves to a
child node of that cluster (made on first use); steps within the cluster stay on the
node. The traversal stops at the time bound (15 s by default).

Enumerating paths explodes, so the traversal runs over states ``(frame, node)`` in order
of arrival time (a priority queue) and visits each state once, at its earliest time:
anything reachable from a later visit is reachable from the earlier one. Playback runs
are skipped in one step each up to the next cluster change or branching frame. Trees are
capped at ``max_nodes`` nodes (nodes are made in order of arrival time, so a capped tree
holds the nearest behaviours); capped trees are counted in the report.

Frames with a single exit (playback only) share the tree of the first branching frame
they play into, as in the paper.

A tree per branching frame does not scale to dense graphs: in relative coordinates the
synthetic 50k-frame library has 240,782 transitions and 34,103 branching frames, and its
2 s trees take 254 ms each (about 2.4 hours on one core, for trees of which a ``perform``
visits a few hundred). So when a sample of trees projects the whole forest past
``LAZY_SECONDS``, the forest is *lazy*: a tree is built the first time it is asked for
(``ClusterForest.tree``) and kept; the trees are the ones an eager build makes.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..graph import MotionGraph
from ..jobs import JobStore, cluster_address, run_jobs
from ._kernel import MAX_TREE_NODES, T_SHIFT, tree_kernel

__all__ = ["LAZY_SECONDS", "ClusterForest", "ClusterTree", "LazyTrees", "build_forest"]

IntArray = NDArray[np.int64]


@dataclass(frozen=True, eq=False)
class ClusterTree:
    """One cluster tree.

    Attributes
    ----------
    root_frame : the frame it was built from.
    parent : (N,) parent node, -1 for the root (node 0).
    cluster : (N,) cluster of each node.
    arrival : (N,) earliest time (frames after the root frame) the node is reached.
    truncated : a cap (nodes or states) was hit.
    horizon : frames ahead up to which the tree is complete (the time bound unless the
        state cap stopped the traversal earlier).
    """

    root_frame: int
    parent: IntArray
    cluster: IntArray
    arrival: IntArray
    truncated: bool = False
    horizon: int = 0

    @property
    def size(self) -> int:
        return int(self.parent.size)

    def leaves(self) -> IntArray:
        """Nodes without children."""
        has_child = np.zeros(self.size, dtype=bool)
        has_child[self.parent[self.parent >= 0]] = True
        return np.flatnonzero(~has_child).astype(np.int64)

    def subtree(self, selected: NDArray[np.bool_]) -> tuple[NDArray[np.bool_], IntArray]:
        """The subtree of ``selected`` nodes hanging from the root: ``(inside, leaves)``,
        where ``inside`` (N,) marks the root and every selected node whose ancestors are
        all selected, and ``leaves`` are the nodes inside with no selected child."""
        inside = np.asarray(selected, dtype=bool).copy()
        inside[0] = True
        for node in range(1, self.size):  # parents come before children
            inside[node] &= inside[self.parent[node]]
        has_child = np.zeros(self.size, dtype=bool)
        kids = np.flatnonzero(inside & (self.parent >= 0))
        has_child[self.parent[kids]] = True
        return inside, np.flatnonzero(inside & ~has_child).astype(np.int64)

    def path_to(self, node: int) -> IntArray:
        """Nodes from the root to ``node`` (a cluster path when ``node`` is a leaf)."""
        out = [node]
        while self.parent[out[-1]] >= 0:
            out.append(int(self.parent[out[-1]]))
        return np.array(out[::-1], dtype=np.int64)

    def clusters_to(self, node: int) -> IntArray:
        return self.cluster[self.path_to(node)]


class LazyTrees:
    """The trees of a lazy forest, each built the first time it is asked for and kept
    (thread-safe: the matcher's background search may ask too)."""

    def __init__(self, roots: IntArray, shared: tuple[Any, ...]) -> None:
        #: the branching frame of each tree
        self.roots = roots
        self.shared = shared
        self.built: dict[int, ClusterTree] = {}
        self._lock = threading.Lock()

    def __len__(self) -> int:
        return int(self.roots.size)

    def __getitem__(self, t: int) -> ClusterTree:
        tree = self.built.get(t)
        if tree is None:
            tree = _build_tree(int(self.roots[t]), *self.shared)
            with self._lock:
                tree = self.built.setdefault(t, tree)
        return tree


@dataclass(frozen=True, eq=False)
class ClusterForest:
    """Trees for the branching frames; ``tree_of[f]`` indexes ``trees`` (-1: no tree,
    for frames outside the graph's strongly connected component). A lazy forest's
    ``trees`` is empty: ``lazy`` builds them as ``tree`` asks for them."""

    trees: tuple[ClusterTree, ...]
    tree_of: IntArray
    bound: int
    report: dict[str, Any] = field(default_factory=dict)
    lazy: LazyTrees | None = None

    def tree(self, frame: int) -> ClusterTree:
        t = int(self.tree_of[frame])
        if t < 0:
            raise ValueError(f"frame {frame} is outside the graph's component: no tree")
        return self.lazy[t] if self.lazy is not None else self.trees[t]

    @property
    def n_trees(self) -> int:
        return len(self.lazy) if self.lazy is not None else len(self.trees)


class _Runs:
    """Playback shortcuts: from a frame, where the next cluster change or branch is."""

    def __init__(self, graph: MotionGraph, labels: IntArray) -> None:
        n = graph.n_frames
        indptr = graph.indptr
        self.branch = (indptr[1:] - indptr[:-1]) > 0
        self.plays = graph.plays_on()
        # next_event[f]: first g >= f that is a branch, cannot play on, or whose
        # successor changes cluster (a backward running minimum)
        stop = self.branch | ~self.plays
        stop[:-1] |= labels[1:] != labels[:-1]
        at = np.where(stop, np.arange(n, dtype=np.int64), n)
        self.next_event = np.minimum.accumulate(at[::-1])[::-1].copy()


def _build_tree(
    root: int,
    labels: IntArray,
    runs: _Runs,
    indptr: IntArray,
    dst: IntArray,
    bound: int,
    max_nodes: int,
    n_clusters: int,
    max_states: int,
) -> ClusterTree:
    parent, cluster, arrival, truncated, horizon = tree_kernel(
        root,
        labels,
        runs.next_event,
        runs.plays,
        indptr,
        dst,
        bound,
        max_nodes,
        n_clusters,
        max_states,
    )
    return ClusterTree(root, parent, cluster, arrival, bool(truncated), int(horizon))


#: trees built by one job on a cluster (``build_forest``)
_TREES_PER_JOB = 512


def _trees_job(shared: tuple[Any, ...], roots: list[int]) -> list[ClusterTree]:
    """One cluster job: the trees of the branching frames ``roots``."""
    return [_build_tree(f, *shared) for f in roots]


def _eager_trees(
    branching: IntArray,
    shared: tuple[Any, ...],
    address: str | None,
    threads: int,
    sampled: dict[int, ClusterTree],
    store: JobStore | None,
    progress: Callable[[int, int], None] | None = None,
) -> list[ClusterTree]:
    """Every tree of the ``branching`` frames, in order, ``_TREES_PER_JOB`` a job: on the
    cluster at ``address``, else here by ``threads`` threads (the kernel lets go of the
    GIL; ``sampled`` trees are not built again). With ``store`` each job's trees are kept
    as they come, and the jobs it holds already are read back, not run."""
    roots = [int(f) for f in branching]
    jobs = [roots[i : i + _TREES_PER_JOB] for i in range(0, len(roots), _TREES_PER_JOB)]
    done: dict[int, list[ClusterTree]] = {}
    if store is not None:
        done = {i: _trees_of(a) for i, a in store.done(len(jobs), _TREE_KEYS).items()}
    todo = [i for i in range(len(jobs)) if i not in done]
    built = sum(len(t) for t in done.values())

    def finished(k: int, trees: list[ClusterTree]) -> None:
        nonlocal built
        done[todo[k]] = trees
        if store is not None:
            store.save(todo[k], _tree_arrays(trees))
        built += len(trees)
        if progress is not None:
            progress(built, len(roots))

    if address is not None:
        run_jobs(_trees_job, [jobs[i] for i in todo], finished, cluster=address, shared=shared)
    else:

        def one(f: int) -> ClusterTree:
            tree = sampled.get(f)
            return tree if tree is not None else _build_tree(f, *shared)

        with ThreadPoolExecutor(max_workers=threads) as pool:
            for k, i in enumerate(todo):
                finished(k, list(pool.map(one, jobs[i])))
    return [t for i in range(len(jobs)) for t in done[i]]


_TREE_KEYS = ("root", "size", "parent", "cluster", "arrival", "truncated", "horizon")


def _tree_arrays(trees: list[ClusterTree]) -> dict[str, np.ndarray]:
    """A job's trees as the arrays a ``JobStore`` keeps (their nodes end to end)."""
    return {
        "root": np.array([t.root_frame for t in trees], dtype=np.int64),
        "size": np.array([t.size for t in trees], dtype=np.int64),
        "parent": np.concatenate([t.parent for t in trees]).astype(np.int64),
        "cluster": np.concatenate([t.cluster for t in trees]).astype(np.int64),
        "arrival": np.concatenate([t.arrival for t in trees]).astype(np.int64),
        "truncated": np.array([t.truncated for t in trees], dtype=bool),
        "horizon": np.array([t.horizon for t in trees], dtype=np.int64),
    }


def _trees_of(a: dict[str, np.ndarray]) -> list[ClusterTree]:
    cut = np.cumsum(a["size"])[:-1]
    parts = [np.split(a[name], cut) for name in ("parent", "cluster", "arrival")]
    return [
        ClusterTree(int(r), p, c, t, bool(tr), int(h))
        for r, p, c, t, tr, h in zip(a["root"], *parts, a["truncated"], a["horizon"], strict=True)
    ]


#: a forest projected (from a sample of its trees) to take longer than this, in seconds
#: on this machine's threads, is built lazily (``LazyTrees``)
LAZY_SECONDS = 120.0
#: trees timed to project the forest's build time
_SAMPLE = 48


def _check_forest(
    graph: MotionGraph, labels: IntArray, bound_seconds: float, max_nodes: int
) -> None:
    """``build_forest``'s arguments are ones it can build trees of (``ValueError``)."""
    if labels.shape != (graph.n_frames,):
        raise ValueError(f"labels must have one cluster per graph frame ({graph.n_frames})")
    if not bound_seconds > 0 or not 1 <= max_nodes <= MAX_TREE_NODES:
        raise ValueError(
            f"bound_seconds must be positive and max_nodes in 1..{MAX_TREE_NODES}, "
            f"not {bound_seconds} and {max_nodes}"
        )
    if bound_seconds * graph.fps >= 1 << (63 - T_SHIFT) or graph.n_frames >= 1 << 28:
        raise ValueError("trees of over 2^19 frames, or graphs of over 2^28, are not built")


def _tree_of(graph: MotionGraph, branching: IntArray, plays: NDArray[np.bool_]) -> IntArray:
    """Each graph frame's tree: a branching frame's own; a single-exit frame (one that
    ``plays`` on) the tree of the first branching frame it plays into; -1: none."""
    tree_of = np.full(graph.n_frames, -1, dtype=np.int64)
    tree_of[branching] = np.arange(branching.size)
    for f in range(graph.n_frames - 1, -1, -1):
        if graph.in_scc[f] and tree_of[f] < 0 and plays[f]:
            tree_of[f] = tree_of[f + 1]
    return tree_of


def build_forest(
    graph: MotionGraph,
    labels: IntArray,
    bound_seconds: float = 15.0,
    max_nodes: int = 4096,
    max_states: int = 200_000,
    cluster: str | None = None,
    lazy: bool | None = None,
    store: JobStore | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> ClusterForest:
    """Cluster trees for every branching frame of ``graph`` with frame clusters ``labels``:
    by threads here, or as jobs on a Dask cluster when ``cluster`` (or
    ``$MIMIC_CLUSTER``: ``control.jobs``) names one (the same trees, in the same order).
    ``lazy``: each tree built here when first asked for (``None``: when a sample of
    trees, built here, projects the whole build past ``LAZY_SECONDS`` on this machine's
    threads, with or without a cluster). With ``store`` the trees of an eager build are
    kept there ``_TREES_PER_JOB`` at a time, and those kept by a build stopped before
    are not built again (``_eager_trees``); ``progress(done, total)`` counts an eager
    build's trees as their jobs finish."""
    labels = np.asarray(labels, dtype=np.int64)
    _check_forest(graph, labels, bound_seconds, max_nodes)
    t0 = time.perf_counter()
    bound = max(1, round(bound_seconds * graph.fps))
    runs, shared = _tree_args(graph, labels, bound, max_nodes, max_states)
    branching = np.flatnonzero(runs.branch & graph.in_scc)
    address = cluster_address(cluster)
    threads = min(4, os.cpu_count() or 1)
    sampled: dict[int, ClusterTree] = {}  # (kept: the build below does not make them again)
    # (on a cluster too: an eager forest of a dense graph is hours of trees on a few
    # workers, where the avatar needs a few hundred of them)
    if lazy is None and branching.size > _SAMPLE:
        picked = np.random.default_rng(0).choice(branching, _SAMPLE, replace=False)
        t = time.perf_counter()
        sampled = {int(f): _build_tree(int(f), *shared) for f in picked}
        per_tree = (time.perf_counter() - t) / _SAMPLE
        lazy = per_tree * branching.size / threads > LAZY_SECONDS
    sample = list(sampled.values())
    forest_of: LazyTrees | None = None
    trees: list[ClusterTree] = []
    if lazy:
        forest_of = LazyTrees(branching, shared)
        for f, tree in sampled.items():
            forest_of.built[int(np.searchsorted(branching, f))] = tree
    else:
        trees = _eager_trees(branching, shared, address, threads, sampled, store, progress)
    tree_of = _tree_of(graph, branching, runs.plays)
    report = _report(trees or sample, graph, tree_of, bound, max_nodes, max_states)
    # (a lazy forest's figures are its sample's)
    lazy_now = forest_of is not None
    report.update(trees=int(branching.size), lazy=lazy_now, sampled=len(sample) if lazy_now else 0)
    report["seconds"] = round(time.perf_counter() - t0, 3)
    return ClusterForest(tuple(trees), tree_of, bound, report, forest_of)


def lazy_forest(
    graph: MotionGraph,
    labels: IntArray,
    roots: IntArray,
    tree_of: IntArray,
    bound: int,
    max_nodes: int,
    max_states: int,
    report: dict[str, Any],
) -> ClusterForest:
    """A lazy forest of ``graph`` again (as ``build_forest`` made it, read from a file):
    the trees of the branching frames ``roots``, built when asked for."""
    _, shared = _tree_args(graph, np.asarray(labels, dtype=np.int64), bound, max_nodes, max_states)
    return ClusterForest((), tree_of, bound, report, LazyTrees(roots, shared))


def _tree_args(
    graph: MotionGraph, labels: IntArray, bound: int, max_nodes: int, max_states: int
) -> tuple[_Runs, tuple[Any, ...]]:
    """The playback shortcuts and the arguments every tree of the forest is built with
    after its root (``_build_tree``)."""
    runs = _Runs(graph, labels)
    dst = np.ascontiguousarray(graph.dst, dtype=np.int64)
    n_clusters = int(labels.max()) + 1
    return runs, (labels, runs, graph.indptr, dst, bound, max_nodes, n_clusters, max_states)


def _report(
    trees: list[ClusterTree],
    graph: MotionGraph,
    tree_of: IntArray,
    bound: int,
    max_nodes: int,
    max_states: int,
) -> dict[str, Any]:
    """The forest's report over ``trees`` (all of them; a lazy forest's: a sample)."""
    sizes = np.array([t.size for t in trees]) if trees else np.zeros(1, dtype=np.int64)
    leaves = np.array([t.leaves().size for t in trees]) if trees else np.zeros(1, dtype=np.int64)
    return {
        "frames_with_tree": int((tree_of >= 0).sum()),
        "frames_in_component": int(graph.in_scc.sum()),
        "bound_frames": bound,
        "nodes": {
            "mean": float(sizes.mean()),
            "median": float(np.median(sizes)),
            "p95": float(np.percentile(sizes, 95)),
            "max": int(sizes.max()),
        },
        "leaves": {"mean": float(leaves.mean()), "max": int(leaves.max())},
        "truncated": int(sum(t.truncated for t in trees)),
        "horizon_seconds": {
            "min": float(min((t.horizon for t in trees), default=0)) / graph.fps,
            "median": float(np.median([t.horizon for t in trees] or [0])) / graph.fps,
        },
        "max_nodes": max_nodes,
        "max_states": max_states,
    }
