"""The pruning rules on hand-made cases, and scipy's SCC against brute-force reachability."""

from __future__ import annotations

import numpy as np
import pytest

from control.graph import contact_groups, largest_scc, local_maxima


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
