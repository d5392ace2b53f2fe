"""The cluster tree's traversal (``tree_kernel``): states ``(time, frame, node)`` in
order of arrival, from a binary min-heap of packed integers, in numba without the GIL so
that threads build trees side by side (``control.clusters._forest``)."""

from __future__ import annotations

import numba
import numpy as np
from numba import types
from numba.typed import Dict

__all__ = ["MAX_TREE_NODES", "T_SHIFT", "tree_kernel"]

#: a search state (time, frame, node) packed into one int64 that orders as the tuple
#: does: 19 bits of time (frames), 28 of frame, 16 of node
T_SHIFT, _F_SHIFT = 44, 16
MAX_TREE_NODES = 1 << 16


@numba.njit(cache=True, nogil=True, inline="always")
def _heap_push(heap: np.ndarray, n: int, item: np.int64) -> np.ndarray:
    """Push ``item`` on the binary min-heap ``heap[:n]`` (grown when full)."""
    if n == heap.size:
        bigger = np.empty(2 * heap.size, np.int64)
        bigger[:n] = heap[:n]
        heap = bigger
    i = n
    while i > 0:
        up = (i - 1) >> 1
        if heap[up] <= item:
            break
        heap[i] = heap[up]
        i = up
    heap[i] = item
    return heap


@numba.njit(cache=True, nogil=True, inline="always")
def _heap_pop(heap: np.ndarray, n: int) -> np.int64:
    """Pop the least item of the binary min-heap ``heap[:n]`` (``n`` > 0)."""
    top = heap[0]
    last = heap[n - 1]
    n -= 1
    i = 0
    while True:
        child = 2 * i + 1
        if child >= n:
            break
        if child + 1 < n and heap[child + 1] < heap[child]:
            child += 1
        if last <= heap[child]:
            break
        heap[i] = heap[child]
        i = child
    if n > 0:
        heap[i] = last
    return top


@numba.njit(cache=True, nogil=True)
def tree_kernel(
    root: int,
    labels: np.ndarray,
    next_event: np.ndarray,
    plays: np.ndarray,
    indptr: np.ndarray,
    dst: np.ndarray,
    bound: int,
    max_nodes: int,
    n_clusters: int,
    max_states: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool, int]:
    parent = np.empty(max_nodes, np.int64)
    cluster = np.empty(max_nodes, np.int64)
    arrival = np.empty(max_nodes, np.int64)
    parent[0] = -1
    cluster[0] = labels[root]
    arrival[0] = 0
    n_nodes = 1
    children = Dict.empty(types.int64, types.int64)
    seen = Dict.empty(types.int64, types.int64)
    # a min-heap of packed (time, frame, node) states: pops in the tuples' order
    heap = np.empty(4096, np.int64)
    heap = _heap_push(heap, 0, np.int64(root) << _F_SHIFT)
    n_heap = 1
    truncated = False
    horizon = bound
    stride = np.int64(max_nodes)
    f_mask = np.int64((1 << (T_SHIFT - _F_SHIFT)) - 1)
    node_mask = np.int64((1 << _F_SHIFT) - 1)
    while n_heap > 0:
        item = _heap_pop(heap, n_heap)
        n_heap -= 1
        t = item >> T_SHIFT
        f = (item >> _F_SHIFT) & f_mask
        node = item & node_mask
        key = f * stride + node
        if key in seen:
            continue
        seen[key] = 1
        if len(seen) > max_states:
            truncated = True
            horizon = int(t)
            break
        g = next_event[f]
        tg = t + (g - f)
        if tg >= bound:
            continue
        lo = indptr[g]
        hi = indptr[g + 1]
        n_out = hi - lo + (1 if plays[g] else 0)
        for k in range(n_out):
            fn = g + 1 if (plays[g] and k == n_out - 1) else dst[lo + k]
            c = labels[fn]
            nd = node
            if c != cluster[node]:
                ck = node * n_clusters + c
                if ck in children:
                    nd = children[ck]
                    if tg + 1 < arrival[nd]:  # runs differ in length: keep the earliest
                        arrival[nd] = tg + 1
                else:
                    if n_nodes >= max_nodes:
                        truncated = True
                        continue
                    nd = np.int64(n_nodes)
                    children[ck] = nd
                    parent[nd] = node
                    cluster[nd] = c
                    arrival[nd] = tg + 1
                    n_nodes += 1
            if (fn * stride + nd) not in seen:
                packed = ((tg + 1) << T_SHIFT) | (np.int64(fn) << _F_SHIFT) | nd
                heap = _heap_push(heap, n_heap, packed)
                n_heap += 1
    return (
        parent[:n_nodes].copy(),
        cluster[:n_nodes].copy(),
        arrival[:n_nodes].copy(),
        truncated,
        horizon,
    )
