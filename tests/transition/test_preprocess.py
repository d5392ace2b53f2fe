"""Peng et al.'s preprocess: two-pass clustering, the transition graph, candidate paths."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from control.graph import frame_features, pair_distances
from control.motion import Library
from control.transition import (
    FrameClusters,
    build_transition_graph,
    candidate_paths,
    two_pass_clusters,
)
from tests.graph.test_prune import _knee_clip


def reference_two_pass(d: np.ndarray, radius: float) -> tuple[list[int], list[int]]:
    """The paper's algorithm on a full distance matrix, written plainly."""
    n = d.shape[0]
    centres = [0]
    labels = [0] + [-1] * (n - 1)
    undefined = []
    for f in range(1, n):
        dist = [d[f, c] for c in centres]
        j = int(np.argmin(dist))
        if dist[j] <= radius:
            labels[f] = j
        elif dist[j] > 2 * radius:
            labels[f] = len(centres)
            centres.append(f)
        else:
            undefined.append(f)
    for f in undefined:
        labels[f] = int(np.argmin([d[f, c] for c in centres]))
    return labels, centres


def test_two_pass_clustering_matches_the_reference(walk_lib: Library) -> None:
    feat = frame_features(walk_lib.clips, "relative")
    n = feat.n
    a = np.repeat(np.arange(n), n)
    b = np.tile(np.arange(n), n)
    d = pair_distances(feat, a, b, 0.01)[0].reshape(n, n)
    for radius in (0.2, 0.5, 1.0):
        got = two_pass_clusters(feat, radius)
        labels, centres = reference_two_pass(d, radius)
        assert got.labels.tolist() == labels and got.centres.tolist() == centres
    with pytest.raises(ValueError, match="radius"):
        two_pass_clusters(feat, 0.0)


def test_knee_clips_by_hand(walk_lib: Library) -> None:
    # angles 0, 0.1, ... 0.9: distance = (difference / 2)^2; radius 0.0026 covers one step
    clip = _knee_clip(walk_lib.clips[0], "k", np.arange(10) * 0.1)
    feat = frame_features([clip], "relative")
    c = two_pass_clusters(feat, 0.0026)
    # frame 0 is a centre; 1 joins it (0.0025); 2 is 0.01 away (> 2r): a new centre; ...
    assert c.centres.tolist() == [0, 2, 4, 6, 8]
    assert c.labels.tolist() == [0, 0, 1, 1, 2, 2, 3, 3, 4, 4]


def test_transition_graph_from_hand_labels(walk_lib: Library) -> None:
    feat = frame_features(walk_lib.clips[:2], "relative")  # 43 + 38 frames
    labels = np.zeros(feat.n, dtype=np.int64)
    labels[10:20] = 1
    labels[20:43] = 2
    labels[43:60] = 2  # the second clip starts in cluster 2: no edge across clips
    labels[60:] = 0
    clusters = FrameClusters(labels, np.array([0, 10, 20]), np.zeros(feat.n, bool), 1.0)
    g = build_transition_graph(feat, clusters)
    assert g.runs.tolist() == [[0, 10, 0], [10, 20, 1], [20, 43, 2], [43, 60, 2], [60, 81, 0]]
    assert g.edge_nodes.tolist() == [[0, 1], [1, 2], [2, 0]]
    assert g.edge_frames.tolist() == [20, 33, 38]  # each edge's clip: both runs together
    assert g.clips_of(2, 0).tolist() == [2] and g.clips_of(0, 2).size == 0
    both = build_transition_graph(feat, clusters, directed=False)
    assert both.clips_of(0, 2).size == 1 and both.clip_backward[both.clips_of(0, 2)].all()
    np.testing.assert_allclose(g.edge_cost, g.edge_frames * g.edge_distance)


def _brute_paths(n: int, edges: dict[tuple[int, int], float], s: int, t: int, max_cost: float):
    out = []
    nodes = [x for x in range(n) if x not in (s, t)]
    for r in range(len(nodes) + 1):
        for mid in itertools.permutations(nodes, r):
            path = (s, *mid, t)
            if all((a, b) in edges for a, b in itertools.pairwise(path)):
                cost = sum(edges[(a, b)] for a, b in itertools.pairwise(path))
                if cost <= max_cost:
                    out.append(cost)
    return sorted(out)


@pytest.mark.parametrize("seed", range(40))
def test_candidate_paths_are_the_k_cheapest_simple_paths(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = 6
    pairs = {(int(a), int(b)) for a, b in rng.integers(0, n, (14, 2)) if a != b}
    edges = {p: float(rng.uniform(1, 10)) for p in sorted(pairs)}

    class G:  # the parts of a TransitionGraph that candidate_paths reads
        n_nodes = n
        edge_nodes = np.array(list(edges), dtype=np.int64)
        edge_cost = np.array(list(edges.values()))

    cp = candidate_paths(G(), k=3, max_cost=25.0)  # type: ignore[arg-type]
    for s in range(n):
        for t in range(n):
            if s == t:
                continue
            want = _brute_paths(n, edges, s, t, 25.0)[:3]
            got = cp.paths_between(s, t)
            assert [round(c, 9) for c, _ in got] == [round(c, 9) for c in want]
            for c, nodes in got:
                assert nodes[0] == s and nodes[-1] == t and len(set(nodes.tolist())) == nodes.size
                assert math.isclose(
                    c, sum(edges[(int(a), int(b))] for a, b in itertools.pairwise(nodes))
                )
