"""DTW (``control.dtw``, shared by the vision matcher and the sketch interface) against
a slow reference and dtaidistance."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from dtaidistance import dtw_ndim
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from control.dtw import dtw, dtw_batch, dtw_best_window, dtw_reference, dtw_windows


def test_textbook_case() -> None:
    a = np.array([[0.0], [1.0], [2.0]])
    b = np.array([[0.0], [0.0], [1.0], [2.0]])
    assert dtw(a, b) == 0.0  # the repeated 0 is absorbed by warping
    c = np.array([[0.0], [2.0], [2.0]])
    assert dtw(a, c) == pytest.approx(1.0)  # one step of 1
    assert dtw(a, a) == 0.0


@pytest.mark.parametrize("window", [0, 1, 2, 3, 6])
def test_matches_reference_and_dtaidistance(rng: np.random.Generator, window: int) -> None:
    for n, m in ((15, 15), (12, 17), (20, 9)):
        for d, walk in ((9, False), (2, True)):
            a = rng.normal(size=(n, d))
            b = rng.normal(size=(m, d))
            if walk:  # random walks: their best paths run along the band's edge
                a, b = np.cumsum(a, axis=0), np.cumsum(b, axis=0)
            ours = dtw(a, b, window)
            assert ours == pytest.approx(dtw_reference(a, b, window), rel=1e-12)
            theirs = dtw_ndim.distance(a, b, window=window) if window else dtw_ndim.distance(a, b)
            assert ours == pytest.approx(theirs, rel=1e-9), (n, m, d, window)


def test_the_band_is_symmetric_and_its_edge_is_used() -> None:
    # b is a shifted by k frames: the cheapest path runs k cells off the diagonal, so a
    # band narrower than k + 1 must cost more, the same on either side
    t = np.linspace(0.0, 6.0, 24)
    a = np.sin(t)[:, None]
    for k in (1, 2, 3):
        b = np.sin(t + k * (t[1] - t[0]))[:, None]
        inside, outside = dtw(a, b, k + 1), dtw(a, b, k)
        assert outside > inside
        assert dtw(b, a, k + 1) == pytest.approx(inside, rel=1e-12)  # symmetric
        assert dtw(b, a, k) == pytest.approx(outside, rel=1e-12)
        assert inside == pytest.approx(dtw_ndim.distance(a, b, window=k + 1), rel=1e-9)


def test_batch_equals_one_by_one_and_abandoning_is_exact(rng: np.random.Generator) -> None:
    q = rng.normal(size=(15, 9))
    refs = rng.normal(size=(120, 15, 9))
    refs[37] = q + 0.01 * rng.normal(size=q.shape)  # a clear winner
    refs[80] = q + 0.3 * rng.normal(size=q.shape)  # a runner-up in another group
    one = np.array([dtw(q, r, 4) for r in refs])
    np.testing.assert_allclose(dtw_batch(q, refs, window=4), one, rtol=1e-12)
    group = np.arange(120) // 6  # 20 paths x 6 views
    got = dtw_batch(q, refs, group, window=4)
    best = np.array([one[group == g].min() for g in range(20)])
    gbest = np.array([got[group == g].min() for g in range(20)])
    order = np.argsort(best)
    # the best and the runner-up groups, and their costs, are exact
    assert np.argmin(gbest) == order[0]
    assert gbest[order[0]] == pytest.approx(best[order[0]], rel=1e-12)
    second = np.sort(gbest)[1]
    assert second == pytest.approx(best[order[1]], rel=1e-12)
    assert np.isinf(got).sum() > 30  # and it did abandon most
    finite = np.isfinite(got)
    np.testing.assert_allclose(got[finite], one[finite], rtol=1e-12)


def test_bad_input() -> None:
    with pytest.raises(ValueError, match="same d"):
        dtw(np.zeros((3, 2)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="empty"):
        dtw(np.zeros((0, 2)), np.zeros((3, 2)))


@pytest.mark.parametrize("n_shape", [7, 32])
def test_best_window_is_the_exhaustive_minimum(n_shape: int) -> None:
    rng = np.random.default_rng(11)
    hu = rng.normal(size=(60, 3, n_shape))
    centre = np.cumsum(rng.normal(size=(60, 3, 2)), axis=0)
    starts = np.array([0, 5, 9, 20, 33, 44], dtype=np.int64)
    query = rng.normal(size=(12, n_shape + 2))
    m = 10

    def window(s: int, v: int) -> np.ndarray:
        return np.concatenate((hu[s : s + m, v], centre[s : s + m, v] - centre[s, v]), axis=1)

    for band in (0, 3):
        costs = {(s, v): dtw(query, window(s, v), band) for s in starts for v in range(3)}
        s, v, c = dtw_best_window(query, hu, centre, starts, m, band)
        assert c == pytest.approx(min(costs.values()))
        assert costs[(s, v)] == pytest.approx(c)
    with pytest.raises(ValueError, match="inside"):
        dtw_best_window(query, hu, centre, np.array([55]), m)
    with pytest.raises(ValueError, match="S \\+ 2"):
        dtw_best_window(query[:, 1:], hu, centre, starts, m)


@settings(max_examples=60, deadline=None, derandomize=True)
@given(
    arrays(np.float64, st.tuples(st.integers(1, 12), st.just(2)), elements=st.floats(-5, 5)),
    arrays(np.float64, st.tuples(st.integers(1, 12), st.just(2)), elements=st.floats(-5, 5)),
)
def test_a_wider_band_never_costs_more_and_the_band_is_symmetric(
    a: np.ndarray, b: np.ndarray
) -> None:
    costs = [dtw(a, b, w) for w in (1, 2, 3, 5, 8)] + [dtw(a, b)]
    assert all(x >= y - 1e-9 for x, y in itertools.pairwise(costs))
    for w in (1, 3, 0):
        assert dtw(a, b, w) == pytest.approx(dtw(b, a, w), rel=1e-12, abs=1e-12)
        assert dtw(a, b, w) == pytest.approx(dtw_reference(a, b, w), rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("recency", [0.5, 2.0])
def test_recency_weighs_the_last_rows_and_every_kernel_agrees(
    rng: np.random.Generator, recency: float
) -> None:
    # the definition: row i of n costs (1 + r i / (n - 1)) / (1 + r / 2) times its distance
    for n, m, band in ((15, 15, 4), (12, 17, 3), (20, 9, 0)):
        a, b = rng.normal(size=(n, 5)), rng.normal(size=(m, 5))
        ours = dtw(a, b, band, recency)
        assert ours == pytest.approx(dtw_reference(a, b, band, recency), rel=1e-12)
        assert ours != pytest.approx(dtw(a, b, band), rel=1e-6)
    # 1 on average: a constant distance costs the same whatever the weighing
    a = np.zeros((10, 3))
    assert dtw(a, a + 1.0, 0, recency) == pytest.approx(dtw(a, a + 1.0), rel=1e-12)
    # the last rows count more: b that fits a's end beats c that fits its start as well
    a = np.zeros((10, 2))
    b, c = a.copy(), a.copy()
    b[:3] += 1.0
    c[-3:] += 1.0
    assert dtw(a, b) == pytest.approx(dtw(a, c), rel=1e-12)
    assert dtw(a, b, 0, recency) < dtw(a, c, 0, recency)
    # the batched, grouped and window kernels weigh alike
    q = rng.normal(size=(12, 9))
    refs = rng.normal(size=(30, 12, 9))
    one = np.array([dtw(q, r, 4, recency) for r in refs])
    np.testing.assert_allclose(dtw_batch(q, refs, window=4, recency=recency), one, rtol=1e-12)
    group = np.arange(30) // 3
    got = dtw_batch(q, refs, group, 4, recency)
    assert np.nanmin(got) == pytest.approx(one.min(), rel=1e-12)
    hu = rng.normal(size=(40, 2, 7))
    centre = np.cumsum(rng.normal(size=(40, 2, 2)), axis=0)
    starts = np.arange(0, 30, 3, dtype=np.int64)
    query = rng.normal(size=(10, 9))

    def window(s: int, v: int) -> np.ndarray:
        return np.concatenate((hu[s : s + 10, v], centre[s : s + 10, v] - centre[s, v]), axis=1)

    costs = {(s, v): dtw(query, window(s, v), 3, recency) for s in starts for v in range(2)}
    s, v, c = dtw_best_window(query, hu, centre, starts, 10, 3, recency)
    assert c == pytest.approx(min(costs.values()), rel=1e-6)  # (tables in float32)
    assert costs[(s, v)] == pytest.approx(c, rel=1e-6)
    views = np.zeros(starts.size, dtype=np.int64)
    np.testing.assert_allclose(
        dtw_windows(query, hu, centre, starts, views, 10, 3, recency),
        [costs[(int(s), 0)] for s in starts],
        rtol=1e-6,
    )


def test_recency_must_be_a_finite_number_not_below_zero() -> None:
    a = np.zeros((4, 2))
    for bad in (-0.5, float("inf"), float("nan")):
        with pytest.raises(ValueError, match="recency"):
            dtw(a, a, 0, bad)
        with pytest.raises(ValueError, match="recency"):
            dtw_batch(a, a[None], recency=bad)
