"""Dynamic time warping: feature sequences (vision's matcher) and ground paths (the sketch
interface), one query against many references.

``cost(a, b) = sqrt(min over warping paths of sum ||a_i - b_j||^2)``, the convention of
dtaidistance's ``dtw_ndim.distance``, optionally inside its Sakoe-Chiba band: with
``window`` w > 0, row i of ``a`` (n rows) may meet row j of ``b`` (m rows) when
``i - max(0, n - m) - w < j < i + max(0, m - n) + w``, i.e. ``|i - j| < w`` for sequences
of the same length, widened towards the longer one by the difference in length.

With ``recency`` r > 0 the query's rows weigh unequally: row i of n costs
``w_i = (1 + r i / (n - 1)) / (1 + r / 2)`` times its squared distance, from ``1 / (1 + r/2)``
at the first row to ``(1 + r) / (1 + r/2)`` at the last, 1 on average: the query's last
frames (what a performer is doing now) count for more than its first (what they did a
window ago), so a window that fits the end wins over one that fits the start equally well.

The batched kernel keeps the two best costs found so far over *groups* (a group is a
candidate path, its members the 18 views) and abandons a reference as soon as every cell
of a row exceeds the second-best group cost: such a reference cannot change the best or
the runner-up group, so both stay exact.
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np
from numpy.typing import NDArray

from .kernels import read_only

__all__ = [
    "SHAPE_DTYPE",
    "ShapeTable",
    "dtw",
    "dtw_batch",
    "dtw_best_window",
    "dtw_reference",
    "dtw_windows",
]

FloatArray = NDArray[np.float64]

#: the window tables' shape numbers (``dtw_best_window``, ``dtw_windows``): float32, as
#: stored beside the bank (half the bytes of float64; they come from the bank's float16
#: features); the DTW itself sums in float64
SHAPE_DTYPE = np.float32
#: a table of shape numbers: float32 as stored, or float64 (cast on the way in)
ShapeTable = NDArray[np.floating[Any]]


@numba.njit(cache=True, nogil=True)
def _row_weight(i: int, n: int, recency: float) -> float:
    """The weight of row ``i`` (0-based) of a query of ``n`` rows (the module's ``w_i``)."""
    if recency == 0.0 or n < 2:
        return 1.0
    return (1.0 + recency * i / (n - 1)) / (1.0 + 0.5 * recency)


#: the distance's sum may be reordered (vectorised): 2x faster, the same costs to within
#: 4e-16 relative (``tests/test_dtw.py`` checks them against dtaidistance); the
#: band's infinities and the early abandon's comparisons keep IEEE semantics
@numba.njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _dtw_sq(
    a: np.ndarray,
    b: np.ndarray,
    window: int,
    limit: float,
    row: np.ndarray,
    prev: np.ndarray,
    recency: float,
) -> float:
    """Squared DTW cost, or ``inf`` once it must exceed ``limit`` (squared); ``a``'s rows
    weighed by ``recency`` (the module's ``w_i``)."""
    n, m, d = a.shape[0], b.shape[0], a.shape[1]
    inf = np.inf
    for j in range(m + 1):
        prev[j] = inf
    prev[0] = 0.0
    shrink, grow = max(0, n - m), max(0, m - n)
    for i in range(1, n + 1):
        w = _row_weight(i - 1, n, recency)
        # the band: i - shrink - window < j < i + grow + window (dtaidistance's)
        lo = max(1, i - shrink - window + 1) if window > 0 else 1
        hi = min(m, i + grow + window - 1) if window > 0 else m
        for j in range(m + 1):
            row[j] = inf
        best_row = inf
        for j in range(lo, hi + 1):
            s = 0.0
            for k in range(d):
                x = a[i - 1, k] - b[j - 1, k]
                s += x * x
            c = prev[j - 1]
            if prev[j] < c:
                c = prev[j]
            if row[j - 1] < c:
                c = row[j - 1]
            v = s * w + c
            row[j] = v
            if v < best_row:
                best_row = v
        if best_row > limit:
            return inf
        for j in range(m + 1):
            prev[j] = row[j]
    return float(prev[m])


@numba.njit(cache=True, nogil=True)
def _batch_kernel(
    query: np.ndarray,
    refs: np.ndarray,
    group: np.ndarray,
    n_groups: int,
    window: int,
    out: np.ndarray,
    recency: float,
) -> None:
    m = refs.shape[1]
    row = np.empty(m + 1)
    prev = np.empty(m + 1)
    gbest = np.full(n_groups, np.inf)  # best squared cost per group so far
    top = -1  # the best group
    best1 = np.inf
    best2 = np.inf  # the best cost of any other group
    for r in range(refs.shape[0]):
        g = group[r]
        # what this reference must beat to change the best or the runner-up group
        limit = gbest[g] if g == top else min(gbest[g], best2)
        c = _dtw_sq(query, refs[r], window, limit, row, prev, recency)
        out[r] = c
        if c < gbest[g]:
            gbest[g] = c
            if g == top:
                best1 = c
            elif c < best1:
                best2 = best1
                best1 = c
                top = g
            elif c < best2:
                best2 = c


@numba.njit(cache=True, nogil=True)
def _best_window_kernel(
    query: np.ndarray,
    shape: np.ndarray,
    centre: np.ndarray,
    starts: np.ndarray,
    m: int,
    window: int,
    recency: float,
) -> tuple[int, int, float]:
    n_views = shape.shape[1]
    n_shape = shape.shape[2]
    d = query.shape[1]
    row = np.empty(m + 1)
    prev = np.empty(m + 1)
    b = np.empty((m, d))
    best = np.inf
    best_s = -1
    best_v = -1
    for s in starts:
        for v in range(n_views):
            for i in range(m):
                for k in range(n_shape):
                    b[i, k] = shape[s + i, v, k]
                for k in range(d - n_shape):
                    b[i, n_shape + k] = centre[s + i, v, k] - centre[s, v, k]
            c = _dtw_sq(query, b, window, best, row, prev, recency)
            if c < best:
                best = c
                best_s = s
                best_v = v
    return best_s, best_v, best


def dtw_best_window(
    query: FloatArray,
    shape: ShapeTable,
    centre: FloatArray,
    starts: NDArray[np.int64],
    length: int,
    window: int = 0,
    recency: float = 0.0,
) -> tuple[int, int, float]:
    """The window of a long multi-view sequence nearest ``query (n, S + 2)`` by DTW:
    ``(start, view, cost)`` over ``starts``, every view, windows of ``length`` frames.

    A window's features are ``shape[s:s+length, v]`` (``S`` columns: the silhouette's
    shape numbers) beside ``centre[s:s+length, v] - centre[s, v]`` (2 columns).
    References that cannot beat the best so far are abandoned early, so the result is
    exact. ``recency``: the query's last rows weigh more (the module's ``w_i``).
    """
    q = np.ascontiguousarray(query, dtype=np.float64)
    h = np.ascontiguousarray(shape, dtype=SHAPE_DTYPE)
    c = np.ascontiguousarray(centre, dtype=np.float64)
    st = np.ascontiguousarray(starts, dtype=np.int64)
    if (
        q.ndim != 2
        or h.ndim != 3
        or c.ndim != 3
        or c.shape[2] != 2
        or q.shape[1] != h.shape[2] + 2
        or h.shape[:2] != c.shape[:2]
    ):
        raise ValueError("query must be (n, S + 2), shape (N, V, S) and centre (N, V, 2)")
    if st.size and (st.min() < 0 or st.max() + length > h.shape[0]):
        raise ValueError("every window must lie inside the sequence")
    # the tables read-only, stored or made: one compiled signature (control.kernels)
    s, v, cost = _best_window_kernel(
        q, read_only(h), read_only(c), st, int(length), int(window), _recency(recency)
    )
    return int(s), int(v), math.sqrt(cost)


@numba.njit(cache=True, nogil=True)
def _windows_kernel(
    query: np.ndarray,
    shape: np.ndarray,
    centre: np.ndarray,
    starts: np.ndarray,
    views: np.ndarray,
    m: int,
    window: int,
    out: np.ndarray,
    recency: float,
) -> None:
    n_shape = shape.shape[2]
    d = query.shape[1]
    row = np.empty(m + 1)
    prev = np.empty(m + 1)
    b = np.empty((m, d))
    for r in range(starts.size):
        s = starts[r]
        v = views[r]
        for i in range(m):
            for k in range(n_shape):
                b[i, k] = shape[s + i, v, k]
            for k in range(d - n_shape):
                b[i, n_shape + k] = centre[s + i, v, k] - centre[s, v, k]
        out[r] = _dtw_sq(query, b, window, np.inf, row, prev, recency)


def dtw_windows(
    query: FloatArray,
    shape: ShapeTable,
    centre: FloatArray,
    starts: NDArray[np.int64],
    views: NDArray[np.int64],
    length: int,
    window: int = 0,
    recency: float = 0.0,
) -> FloatArray:
    """Exact DTW costs ``(K,)`` of ``query (n, S + 2)`` against the windows
    ``(starts[k], views[k])`` of the tables ``dtw_best_window`` takes (``recency`` as
    there)."""
    q = np.ascontiguousarray(query, dtype=np.float64)
    st = np.ascontiguousarray(starts, dtype=np.int64)
    vw = np.ascontiguousarray(views, dtype=np.int64)
    if q.ndim != 2 or shape.ndim != 3 or q.shape[1] != shape.shape[2] + 2:
        raise ValueError("query must be (n, S + 2) and shape (N, V, S)")
    if st.shape != vw.shape or st.ndim != 1:
        raise ValueError("starts and views must be 1-D arrays of one length")
    if st.size and (st.min() < 0 or st.max() + length > shape.shape[0]):
        raise ValueError("every window must lie inside the sequence")
    if vw.size and (vw.min() < 0 or vw.max() >= shape.shape[1]):
        raise ValueError("views must lie in 0..V - 1")
    out = np.empty(st.size)
    h = np.ascontiguousarray(shape, dtype=SHAPE_DTYPE)
    c = np.ascontiguousarray(centre, dtype=np.float64)
    _windows_kernel(
        q, read_only(h), read_only(c), st, vw, int(length), int(window), out, _recency(recency)
    )
    return np.sqrt(out)


def _recency(recency: float) -> float:
    """``recency`` checked: a finite number >= 0 (a clear error otherwise)."""
    r = float(recency)
    if not (math.isfinite(r) and r >= 0.0):
        raise ValueError(f"recency must be a finite number >= 0, not {recency!r}")
    return r


def dtw(a: FloatArray, b: FloatArray, window: int = 0, recency: float = 0.0) -> float:
    """DTW cost of two sequences ``(n, d)`` and ``(m, d)``; ``window`` 0 means no band;
    ``recency``: ``a``'s last rows weigh more (the module's ``w_i``)."""
    a = np.ascontiguousarray(a, dtype=np.float64)
    b = np.ascontiguousarray(b, dtype=np.float64)
    if a.ndim != 2 or b.ndim != 2 or a.shape[1] != b.shape[1]:
        raise ValueError("sequences must be (n, d) and (m, d) with the same d")
    if a.shape[0] == 0 or b.shape[0] == 0:
        raise ValueError("sequences must not be empty")
    m = b.shape[0]
    c = _dtw_sq(a, b, int(window), np.inf, np.empty(m + 1), np.empty(m + 1), _recency(recency))
    return math.sqrt(c)


def dtw_batch(
    query: FloatArray,
    refs: FloatArray,
    group: NDArray[np.int64] | None = None,
    window: int = 0,
    recency: float = 0.0,
) -> FloatArray:
    """DTW costs ``(B,)`` of ``query (n, d)`` against ``refs (B, m, d)``.

    With ``group`` (B,) ints (e.g. the candidate path of each view's sequence), costs of
    references that can beat neither the best nor the second-best group are ``inf``
    (abandoned early); the best cost of every group that could rank first or second is
    exact. Without ``group`` every cost is exact. ``recency``: the query's last rows
    weigh more (the module's ``w_i``).
    """
    q = np.ascontiguousarray(query, dtype=np.float64)
    r = np.ascontiguousarray(refs, dtype=np.float64)
    if q.ndim != 2 or r.ndim != 3 or r.shape[2] != q.shape[1]:
        raise ValueError("query must be (n, d) and refs (B, m, d) with the same d")
    rc = _recency(recency)
    out = np.empty(r.shape[0])
    if r.shape[0] == 0:
        return out
    if group is None:
        row = np.empty(r.shape[1] + 1)
        prev = np.empty(r.shape[1] + 1)
        for i in range(r.shape[0]):
            out[i] = _dtw_sq(q, r[i], int(window), np.inf, row, prev, rc)
        return np.sqrt(out)
    grp = np.ascontiguousarray(group, dtype=np.int64)
    if grp.shape != (r.shape[0],) or grp.min() < 0:
        raise ValueError("group must give a non-negative group per reference")
    _batch_kernel(
        read_only(q), read_only(r), read_only(grp), int(grp.max()) + 1, int(window), out, rc
    )
    return np.sqrt(out)


def dtw_reference(a: FloatArray, b: FloatArray, window: int = 0, recency: float = 0.0) -> float:
    """Plain-Python DTW (the definition, for tests)."""
    n, m = len(a), len(b)
    w = [1.0 if n < 2 else (1.0 + recency * i / (n - 1)) / (1.0 + recency / 2) for i in range(n)]
    cost = [[math.inf] * (m + 1) for _ in range(n + 1)]
    cost[0][0] = 0.0
    shrink, grow = max(0, n - m), max(0, m - n)
    for i in range(1, n + 1):
        for j in range(1, m + 1):
            if window > 0 and not (i - shrink - window < j < i + grow + window):
                continue
            d = w[i - 1] * float(np.sum((np.asarray(a[i - 1]) - np.asarray(b[j - 1])) ** 2))
            cost[i][j] = d + min(cost[i - 1][j - 1], cost[i - 1][j], cost[i][j - 1])
    return math.sqrt(cost[n][m])
