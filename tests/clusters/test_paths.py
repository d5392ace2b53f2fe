"""Most probable motions (eq. 7) against brute-force enumeration on small graphs."""

from __future__ import annotations

import numpy as np
import pytest

from control.clusters import transition_log_probs
from control.clusters._paths import most_probable_motion
from control.graph import GraphOptions, MotionGraph


def small_graph(
    rng: np.random.Generator, n_clips: int = 3, length: int = 6, n_edges: int = 10
) -> MotionGraph:
    start = np.arange(n_clips + 1) * length
    n = int(start[-1])
    last = set((start[1:] - 1).tolist())
    src = rng.integers(0, n, n_edges)
    cand = np.array([f for f in range(1, n) if f not in set(start[:-1].tolist())])
    dst = rng.choice(cand, n_edges)
    order = np.lexsort((dst, src))
    del last
    return MotionGraph(
        options=GraphOptions(),
        clip_names=tuple(f"c{i}" for i in range(n_clips)),
        clip_start=start,
        fps=15.0,
        sigma=0.1,
        src=src[order],
        dst=dst[order],
        dist=rng.uniform(0.0, 0.3, n_edges).astype(np.float32)[order],
        align=np.zeros((n_edges, 4), dtype=np.float32),
        in_scc=np.ones(n, dtype=bool),
        library_digest="hand-made",
    )


def brute_force(g, labels, post, start, path, bound):
    log_play, log_edge = transition_log_probs(g)
    best = (-np.inf, None)

    def exits(f):
        out = []
        if np.isfinite(log_play[f]):
            out.append((f + 1, log_play[f]))
        for e in np.flatnonzero(g.src == f):
            out.append((int(g.dst[e]), log_edge[e]))
        return out

    def go(seq, k, score):
        nonlocal best
        if k == len(path) - 1:
            if score > best[0]:
                best = (score, list(seq))
            return
        if len(seq) - 1 >= bound:
            return
        for nxt, lp in exits(seq[-1]):
            c = labels[nxt]
            if c == path[k]:
                k2 = k
            elif c == path[k + 1]:
                k2 = k + 1
            else:
                continue
            go([*seq, nxt], k2, score + lp + np.log(post[nxt]))

    go([start], 0, 0.0)
    return best


def test_equals_brute_force() -> None:
    found = 0
    for seed in range(30):
        found += _compare(np.random.default_rng(seed))
    assert found >= 15  # most cases have a motion to find, the rest are checked as None


def _compare(rng: np.random.Generator) -> int:
    found = 0
    g = small_graph(rng)
    labels = rng.integers(0, 3, g.n_frames)
    post = rng.uniform(0.3, 1.0, g.n_frames)
    start = int(rng.integers(0, g.n_frames))
    bound = 9
    for path in (
        [labels[start], (labels[start] + 1) % 3],
        [labels[start], (labels[start] + 2) % 3, labels[start]],
    ):
        want_score, want_frames = brute_force(g, labels, post, start, path, bound)
        got = most_probable_motion(g, labels, post, start, np.array(path), bound)
        if want_frames is None:
            assert got is None
            continue
        assert got is not None
        found += 1
        assert got.log_prob == pytest.approx(want_score, abs=1e-9)
        assert got.frames.tolist() == want_frames
        # the edges reproduce the frames
        for i, e in enumerate(got.edges):
            if e < 0:
                assert got.frames[i + 1] == got.frames[i] + 1
            else:
                assert (g.src[e], g.dst[e]) == (got.frames[i], got.frames[i + 1])
    return found


def test_bad_paths_are_refused(rng: np.random.Generator) -> None:
    g = small_graph(rng)
    labels = np.zeros(g.n_frames, dtype=np.int64)
    post = np.ones(g.n_frames)
    with pytest.raises(ValueError, match="start frame's cluster"):
        most_probable_motion(g, labels, post, 0, np.array([1, 0]), 5)
    with pytest.raises(ValueError, match="must differ"):
        most_probable_motion(g, labels, post, 0, np.array([0, 0]), 5)
