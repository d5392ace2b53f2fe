"""The cluster forest against a brute-force construction from the paper's definition."""

from __future__ import annotations

import numpy as np
import pytest

from control.clusters._forest import build_forest
from tests.clusters.test_paths import small_graph


def brute_force_tree(g, labels, root, bound):
    """Every walk of at most ``bound`` steps from ``root``; a node per sequence of
    clusters visited (consecutive repeats merged), reached at the walk's length."""
    plays = g.plays_on()
    nodes: dict[tuple[int, ...], int] = {}

    def go(f, seq, t):
        if seq not in nodes or t < nodes[seq]:
            nodes[seq] = t
        if t == bound:
            return
        nxt = [int(d) for d in g.dst[g.src == f]]
        if plays[f]:
            nxt.append(f + 1)
        for h in nxt:
            c = int(labels[h])
            go(h, seq if c == seq[-1] else (*seq, c), t + 1)

    go(root, (int(labels[root]),), 0)
    return nodes


def forest_nodes(tree):
    out = {}
    for node in range(tree.size):
        out[tuple(int(c) for c in tree.clusters_to(node))] = int(tree.arrival[node])
    return out


@pytest.mark.parametrize("seed", range(8))
def test_trees_equal_brute_force(seed: int) -> None:
    rng = np.random.default_rng(seed)
    g = small_graph(rng, n_clips=3, length=5, n_edges=7)
    labels = rng.integers(0, 3, g.n_frames)
    bound = 7
    forest = build_forest(g, labels, bound_seconds=bound / g.fps)
    assert forest.bound == bound
    branching = np.flatnonzero(np.diff(g.indptr) > 0)
    assert len(forest.trees) == branching.size
    for tree in forest.trees:
        assert not tree.truncated and tree.horizon == bound
        assert forest_nodes(tree) == brute_force_tree(g, labels, tree.root_frame, bound)
    # frames without transitions share the tree of the branching frame they play into
    plays = g.plays_on()
    for f in range(g.n_frames):
        if f in set(branching.tolist()):
            assert forest.trees[forest.tree_of[f]].root_frame == f
            continue
        h = f
        while plays[h] and h not in set(branching.tolist()):
            h += 1
        want = forest.tree_of[h] if h in set(branching.tolist()) else -1
        assert forest.tree_of[f] == want


def test_caps_truncate_and_say_so() -> None:
    rng = np.random.default_rng(3)
    g = small_graph(rng, n_clips=4, length=8, n_edges=30)
    labels = rng.integers(0, 5, g.n_frames)
    full = build_forest(g, labels, bound_seconds=12 / g.fps)
    capped = build_forest(g, labels, bound_seconds=12 / g.fps, max_nodes=4)
    assert max(t.size for t in capped.trees) <= 4
    assert capped.report["truncated"] > 0 and full.report["truncated"] == 0
    few = build_forest(g, labels, bound_seconds=12 / g.fps, max_states=5)
    assert all(t.horizon <= 12 for t in few.trees) and few.report["truncated"] > 0
    with pytest.raises(ValueError, match="one cluster per graph frame"):
        build_forest(g, labels[:-1])
    with pytest.raises(ValueError, match=r"max_nodes in 1\.\.65536"):
        build_forest(g, labels, max_nodes=1 << 17)  # (a node must fit the heap's 16 bits)


def test_trees_built_on_a_two_worker_cluster_are_the_local_ones(
    monkeypatch: pytest.MonkeyPatch, dask_cluster: str
) -> None:
    from control.clusters import _forest

    rng = np.random.default_rng(5)
    g = small_graph(rng, n_clips=6, length=12, n_edges=40)
    labels = rng.integers(0, 4, g.n_frames)
    here = build_forest(g, labels, bound_seconds=9 / g.fps)
    monkeypatch.setattr(_forest, "_TREES_PER_JOB", 3)  # several jobs
    there = build_forest(g, labels, bound_seconds=9 / g.fps, cluster=dask_cluster)
    assert len(here.trees) > 6 and len(there.trees) == len(here.trees)
    np.testing.assert_array_equal(there.tree_of, here.tree_of)
    for a, b in zip(here.trees, there.trees, strict=True):
        assert a.root_frame == b.root_frame and a.truncated == b.truncated
        for name in ("parent", "cluster", "arrival"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_a_forest_too_slow_to_build_whole_is_lazy_on_a_cluster_too(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A dense graph's forest would keep a few workers busy for hours where the avatar
    needs a few hundred trees: it is lazy there as here, and the cluster is not asked."""
    from control.clusters import _forest

    rng = np.random.default_rng(5)
    g = small_graph(rng, n_clips=6, length=12, n_edges=40)
    labels = rng.integers(0, 4, g.n_frames)
    monkeypatch.setattr(_forest, "_SAMPLE", 2)
    monkeypatch.setattr(_forest, "LAZY_SECONDS", 0.0)
    here = build_forest(g, labels, bound_seconds=9 / g.fps, lazy=False)
    lazy = build_forest(g, labels, bound_seconds=9 / g.fps, cluster="tcp://192.0.2.1:8786")
    assert lazy.report["lazy"] and lazy.n_trees == len(here.trees)
    for t, tree in enumerate(here.trees):
        assert np.array_equal(lazy.tree(tree.root_frame).parent, tree.parent), t
