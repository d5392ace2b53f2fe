"""Peng et al.'s run-time pieces on real clips and by hand."""

from __future__ import annotations

import numpy as np
import pytest

from control.graph import frame_features, pair_distances
from control.motion import Library
from control.transition import build_transition_graph, candidate_paths, two_pass_clusters
from control.transition._runtime import (
    choose_path,
    clip_frames,
    nearest_cluster,
    stitch_path,
    transition_point,
)


@pytest.fixture(scope="module")
def setup(medium_lib: Library):
    feat = frame_features(medium_lib.clips, "relative")
    clusters = two_pass_clusters(feat, 0.8)
    graph = build_transition_graph(feat, clusters)
    return feat, clusters, graph, candidate_paths(graph)


def test_nearest_cluster_is_the_nearest_centre(setup, rng: np.random.Generator) -> None:
    feat, clusters, _, _ = setup
    for f in rng.integers(0, feat.n, 20):
        d, _ = pair_distances(feat, np.full(clusters.k, f), clusters.centres, 0.01)
        assert nearest_cluster(feat, clusters, int(f)) == int(np.argmin(d))
    # a centre is its own nearest centre
    assert nearest_cluster(feat, clusters, int(clusters.centres[3])) == 3


def test_path_choice_follows_inverse_cost(setup) -> None:
    _, _, _, paths = setup
    keys = [tuple(p) for p in paths.pairs.tolist()]
    a, b = next(k for k in keys if len(paths.paths_between(*k)) >= 3)
    cands = paths.paths_between(a, b)
    rng = np.random.default_rng(0)
    picks = [tuple(choose_path(paths, a, b, rng).tolist()) for _ in range(3000)]
    w = np.array([1 / c for c, _ in cands])
    for (_, nodes), p in zip(cands, w / w.sum(), strict=True):
        assert picks.count(tuple(nodes.tolist())) / 3000 == pytest.approx(p, abs=0.03)
    assert choose_path(paths, a, a, rng).tolist() == [a]
    missing = next(
        (s, t)
        for s in range(paths.n_nodes)
        for t in range(paths.n_nodes)
        if s != t and not paths.paths_between(s, t)
    )
    assert choose_path(paths, *missing, rng) is None


def test_transition_point_is_the_grid_minimum(setup) -> None:
    feat = setup[0]
    tail = np.arange(100, 110)
    head = np.arange(300, 325)
    i, j, d = transition_point(feat, tail, head)
    grid = pair_distances(feat, np.repeat(tail, 25), np.tile(head, 10), 0.01)[0].reshape(10, 25)
    assert d == grid.min() and grid[i, j] == d


def test_stitching_follows_the_path_through_its_clips(setup) -> None:
    feat, clusters, graph, paths = setup
    rng = np.random.default_rng(1)
    motion = list(range(10, 40))
    a = int(clusters.labels[39])
    targets = [t for s, t in paths.pairs.tolist() if s == a]
    path = choose_path(paths, a, targets[len(targets) // 2], rng)
    out = stitch_path(feat, graph, motion, path)
    assert out[: len(motion) - 10] == motion[: len(motion) - 10]  # only the tail is cut
    # it ends in the path's last cluster, and joins at most one clip per node pair
    assert int(clusters.labels[out[-1]]) == int(path[-1])
    jumps = np.flatnonzero(np.abs(np.diff(out)) != 1)
    assert 1 <= jumps.size <= len(path) - 1
    # every clip's frames are contiguous in the library (forward clips here)
    for c in range(graph.clip_edge.size):
        f = clip_frames(graph, c)
        assert np.all(np.diff(f) == 1)
