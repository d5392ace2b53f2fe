"""The pruning rules on hand-made cases, and scipy's SCC against brute-force reachability."""

from __future__ import annotations

import math

import numpy as np
import pytest

from control.graph import GraphOptions, build_graph, case4, largest_scc
from control.graph._prune import contact_groups, local_maxima
from control.motion import Clip, Contacts, Library, Motion, find_role


def _allowed(groups: list[tuple[np.ndarray, np.ndarray]]) -> set[tuple[int, int]]:
    out = set()
    for rows, cols in groups:
        out |= {(int(a), int(b)) for a in rows for b in cols if a != b}
    return out


def test_loose_and_strict_contact_rules_by_hand() -> None:
    # one clip: L foot down for frames 0-2, lifts at 3; both down again from 5
    st = np.array([[1, 1], [1, 1], [1, 1], [0, 1], [0, 1], [1, 1], [1, 1]], dtype=bool)
    start = np.array([0, 7])
    loose = _allowed(contact_groups(st, start, "loose"))
    # (a, b) allowed iff state(a) == state(b) and state(a+1) == state(b+1)
    assert (0, 1) in loose and (1, 0) in loose and (0, 5) in loose
    assert (2, 1) not in loose  # 2 -> 3 lifts the foot, 1 -> 2 does not
    assert (3, 4) not in loose  # 3 -> 4 stays up, 4 -> 5 puts it down
    assert (6, 5) in loose  # the last frame is compared as if its state held
    assert all(b != 6 for _, b in loose)  # b + 1 must exist
    strict = _allowed(contact_groups(st, start, "strict"))
    # only at the same contact change: lift-off at 2->3, touch-down at 4->5
    assert strict == set()  # each change happens once: nothing to pair with
    two = np.concatenate((st, st))
    strict2 = _allowed(contact_groups(two, np.array([0, 7, 14]), "strict"))
    assert strict2 == {(2, 9), (9, 2), (4, 11), (11, 4)}
    none = _allowed(contact_groups(st, start, "none"))
    assert len(none) == 7 * 6 - 6  # every pair except a == b, and b never the last frame


def test_contact_groups_agree_with_brute_force(rng: np.random.Generator) -> None:
    st = rng.random((60, 2)) < 0.5
    start = np.array([0, 25, 60])
    last = {24, 59}

    def nxt(f: int) -> int:
        return f if f in last else f + 1

    for rule in ("loose", "strict"):
        truth = set()
        for a in range(60):
            for b in range(60):
                if a == b or b in last:
                    continue
                ok = (st[a] == st[b]).all() and (st[nxt(a)] == st[b + 1]).all()
                if rule == "strict":
                    ok &= not (st[a] == st[nxt(a)]).all()
                if ok:
                    truth.add((a, b))
        assert _allowed(contact_groups(st, start, rule)) == truth


def test_local_maxima_keeps_the_best_of_a_ridge() -> None:
    start = np.array([0, 10, 20])
    # a ridge of similar pairs between clip 0 and clip 1; the middle one is best
    a = np.array([2, 3, 4, 7])
    b = np.array([12, 13, 14, 17])
    d = np.array([0.3, 0.1, 0.2, 0.5])
    keep = local_maxima(a, b, d, start)
    assert keep.tolist() == [False, True, False, True]  # (7, 17) has no present neighbour
    # pairs next to the diagonal lose against playback (distance 0)
    keep = local_maxima(np.array([3, 5]), np.array([4, 8]), np.array([0.01, 0.2]), start)
    assert keep.tolist() == [False, True]
    # neighbours across a clip boundary do not count
    keep = local_maxima(np.array([9, 10]), np.array([15, 16]), np.array([0.5, 0.1]), start)
    assert keep.tolist() == [True, True]


def test_scc_on_graphs_with_known_components() -> None:
    # clips [0..3], [4..6]: playback 0->1->2->3 and 4->5->6
    start = np.array([0, 4, 7])
    # transitions 3 -> 0 (loop in clip 0), 6 -> 4 (loop in clip 1), 2 -> 5 (one way)
    src = np.array([3, 6, 2])
    dst = np.array([0, 4, 5])
    in_scc, n_comp = largest_scc(7, src, dst, start)
    assert in_scc.tolist() == [True] * 4 + [False] * 3
    assert n_comp == 2
    # add 5 -> 1: everything joins
    in_scc, n_comp = largest_scc(7, np.append(src, 5), np.append(dst, 1), start)
    assert in_scc.all() and n_comp == 1


def _reach(n: int, edges: list[tuple[int, int]]) -> np.ndarray:
    r = np.eye(n, dtype=bool)
    for s, t in edges:
        r[s, t] = True
    for k in range(n):
        r |= r[:, [k]] & r[[k], :]
    return r


@pytest.mark.parametrize("seed", range(5))
def test_scc_agrees_with_brute_force_reachability(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = 40
    cuts = np.sort(rng.choice(np.arange(1, n), 6, replace=False))
    start = np.concatenate(([0], cuts, [n]))
    src = rng.integers(0, n, 25)
    dst = rng.integers(0, n, 25)
    in_scc, _ = largest_scc(n, src, dst, start)
    last = set((start[1:] - 1).tolist())
    edges = [(f, f + 1) for f in range(n) if f not in last] + list(zip(src, dst, strict=True))
    r = _reach(n, edges)
    mutual = r & r.T
    sizes = mutual.sum(axis=1)
    biggest = int(sizes.max())
    assert int(in_scc.sum()) == biggest
    f = int(np.flatnonzero(in_scc)[0])
    assert np.array_equal(in_scc, mutual[f])


def _knee_clip(template: Clip, name: str, angles: np.ndarray) -> Clip:
    """A clip on a real skeleton that stands still and bends only the left knee."""
    sk = template.motion.skeleton
    n = angles.size
    q = np.zeros((n, sk.n_joints, 4))
    q[..., 0] = 1.0
    knee = find_role(sk, "left_knee")
    q[:, knee, 0] = np.cos(angles / 2)
    q[:, knee, 1] = np.sin(angles / 2)
    m = Motion(sk, np.tile([0.0, 0.9, 0.0], (n, 1)), q, 15.0, name)
    contacts = Contacts(np.ones((n, 2), dtype=bool), 0.0, 0.0)
    return Clip(m, contacts, "", np.full(n, -1), (), np.arange(n, dtype=float), name)


def test_likelihood_rule_by_hand(walk_lib: Library) -> None:
    # two clips bending the knee at the same speed (0.1 rad per frame), offset by 0.05
    # rad: the distance of two frames is the squared half difference of their angles,
    # the velocity terms cancel, and sigma is (0.1 / 2)^2
    alpha = [np.arange(10) * 0.1, 0.05 + np.arange(8) * 0.1]
    clips = [_knee_clip(walk_lib.clips[0], f"k{i}", a) for i, a in enumerate(alpha)]
    options = GraphOptions(contact="none", similarity=False, threshold=math.exp(-1.5))
    g = build_graph(clips, options)
    assert g.sigma == pytest.approx(0.05**2)
    # kept: D <= 1.5 sigma, i.e. angles at most 0.122 rad apart: 0.05 and 0.1, not 0.15
    every = np.concatenate(alpha)
    last = {9, 17}
    expected = {
        (a, b)
        for a in range(18)
        for b in range(18)
        if a != b and b not in last and abs(every[a] - every[b]) < 0.12
    }
    assert g.report["likelihood"] == len(expected)
    assert g.report["contact"] == 18 * 16 - 16
    kept = set(zip(g.src.tolist(), (g.dst - 1).tolist(), strict=True))
    assert kept <= expected
    assert np.allclose(g.likelihood(), np.exp(-g.dist / g.sigma))


def test_case4_by_hand() -> None:
    # one clip of 30 frames; the left foot is down for frames 0-20, the right never
    st = np.zeros((30, 2), dtype=bool)
    st[:21, 0] = True
    start = np.array([0, 30])
    src = np.array([2, 18, 25, 25, 25])
    dst = np.array([26, 26, 3, 17, 28])
    flags = case4(st, start, src, dst, b=5)
    # 2: contact runs to 20 >= 2 + 5; 18: ends at 20 < 23; j = 3: runs to 20 >= 3 + 4;
    # j = 17: 20 >= 21 fails; j = 28: no contact
    assert flags.tolist() == [True, False, True, False, False]
    # contact runs stop at clip ends
    flags = case4(st, np.array([0, 5, 30]), np.array([2]), np.array([26]), b=5)
    assert flags.tolist() == [False]
