"""A broad phase for the likely-pair search of large contact groups (``BroadPhase``).

The blocked search (``close_pair_blocks``) compares every row with every column through
one matrix product per block: frames^2 comparisons, most of the graph's time past
100,000 frames. The lower bound it evaluates is a squared Euclidean distance between
rows of ``X`` (``lower_bound_features``), so a pair within it is also within it after an
orthogonal projection onto a few principal directions of ``X``: a KD-tree
(``scipy.spatial.cKDTree``) of the projected columns, queried with the bound's radius,
gives a superset of the pairs without visiting the others, and the full bound is then
evaluated on that superset only. Exact, like the blocked search: no pair under the
threshold is lost. The projection and the tree are made once per contact group and can be
sent to cluster workers.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from ..kernels import kernel_input

__all__ = ["BROAD_DIMS", "BROAD_MIN_PAIRS", "BroadPhase", "squared_gaps", "wants_broad"]

IntArray = NDArray[np.int64]

#: principal directions the tree works in (on the largest contact group of the 200,000-frame
#: synthetic library, 64k frames: 6 gave 59 M candidates in 4.7 s of queries, 8 34 M in 6.5
#: s, 10 26 M in 5.9 s, 12 20 M in 6.7 s, 16 14 M in 9.2 s; each candidate then costs a
#: full bound)
BROAD_DIMS = 10
#: a contact group with at least this many row x column comparisons uses the tree (the
#: 50,000-frame synthetic library's search: 3.2 s blocked, 1.9 s with trees from groups
#: of 2,048 x 2,048 frames up)
BROAD_MIN_PAIRS = 1 << 22
#: frames whose principal directions are found (an even stride over the columns)
_SAMPLE = 20000
#: rows queried against the tree at a time
_ROWS = 1024
#: pairs one query may hold, about (its rows are split where their estimate passes it):
#: a query's pairs and their sorting cost some 70 bytes each, and two run at once
_MAX_PAIRS = 1 << 22
#: one row in this many is counted to estimate a block's pairs
_STRIDE = 8


def wants_broad(n_rows: int, n_cols: int) -> bool:
    """Whether a contact group of ``n_rows x n_cols`` comparisons is searched by a tree."""
    return n_rows * n_cols >= BROAD_MIN_PAIRS


@numba.njit(cache=True, parallel=True)
def _gaps_kernel(x: np.ndarray, a: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    d = x.shape[1]
    for t in numba.prange(a.shape[0]):
        i = a[t]
        j = b[t]
        s = 0.0
        for k in range(d):
            g = np.float64(x[i, k]) - np.float64(x[j, k])
            s += g * g
        out[t] = s


def squared_gaps(x: np.ndarray, a: IntArray, b: IntArray) -> NDArray[np.float64]:
    """``|x[a] - x[b]|^2`` per pair, in float64, without holding ``x[a] - x[b]``."""
    out = np.empty(len(a))
    _gaps_kernel(
        kernel_input(x, np.float32), kernel_input(a, np.int64), kernel_input(b, np.int64), out
    )
    return out


@dataclass(frozen=True)
class BroadPhase:
    """A contact group's columns projected onto ``BROAD_DIMS`` principal directions of
    ``X`` and held in a KD-tree (``of``); ``pairs`` yields the rows' pairs within a limit."""

    mean: NDArray[np.float64]  # (d,)
    basis: NDArray[np.float64]  # (k, d), orthonormal rows
    cols: IntArray
    tree: cKDTree

    @classmethod
    def of(cls, x: np.ndarray, cols: IntArray, dims: int = BROAD_DIMS) -> BroadPhase:
        """The broad phase of the columns ``cols`` of ``x`` (rows: frames)."""
        cols = np.asarray(cols, dtype=np.int64)
        sample = x[cols[:: max(1, cols.size // _SAMPLE)]].astype(np.float64)
        mean = sample.mean(axis=0)
        _, _, vt = np.linalg.svd(sample - mean, full_matrices=False)
        basis = np.ascontiguousarray(vt[: min(dims, vt.shape[0])])
        return cls(mean, basis, cols, cKDTree(cls._project(x, cols, mean, basis)))

    @staticmethod
    def _project(
        x: np.ndarray, idx: IntArray, mean: np.ndarray, basis: np.ndarray
    ) -> NDArray[np.float64]:
        return (x[idx].astype(np.float64) - mean) @ basis.T

    def _near(self, x: np.ndarray, rb: IntArray, radius: float) -> tuple[IntArray, IntArray]:
        """The pairs of rows ``rb`` whose projected gap is within ``radius``, row-major."""
        near = cKDTree(self._project(x, rb, self.mean, self.basis)).sparse_distance_matrix(
            self.tree, radius, output_type="ndarray"
        )
        order = np.lexsort((near["j"], near["i"]))
        a = rb[near["i"][order]]
        b = self.cols[near["j"][order]]
        keep = a != b
        return a[keep], b[keep]

    def _split(self, x: np.ndarray, rb: IntArray, radius: float) -> list[IntArray]:
        """``rb`` cut into runs of rows whose pairs number about ``_MAX_PAIRS`` at most,
        by counting one row in ``_STRIDE`` (a dense block of near-duplicate frames can
        have tens of millions)."""
        sample = self._project(x, rb[::_STRIDE], self.mean, self.basis)
        counts = np.asarray(self.tree.query_ball_point(sample, radius, return_length=True))
        est = np.cumsum(np.repeat(counts, _STRIDE)[: rb.size])
        if est[-1] <= _MAX_PAIRS:
            return [rb]
        cuts = np.searchsorted(est, np.arange(_MAX_PAIRS, est[-1], _MAX_PAIRS), side="right")
        inner = np.unique(np.clip(cuts, 1, rb.size - 1)) if rb.size > 1 else cuts[:0]
        return np.split(rb, inner)

    def pairs(
        self, x: np.ndarray, rows: IntArray, limit: float, per_block: int | None = None
    ) -> Iterator[tuple[IntArray, IntArray]]:
        """Pairs ``(a, b)``, ``a`` in ``rows``, ``b`` in the columns, ``a != b``, with
        ``|x[a] - x[b]|^2 <= limit``, a run of rows at a time (row-major within it; at most
        ``per_block`` rows, fewer where they have many pairs: ``_split``). The tree's
        queries run on a thread per core (scipy lets go of the GIL there), a few runs at a
        time, and the full bound in numba."""
        rows = np.asarray(rows, dtype=np.int64)
        # a projection shortens every gap: the tree's radius is the bound's, widened by
        # far more than the rounding of the projection
        radius = math.sqrt(max(limit, 0.0)) * (1.0 + 1e-6) + 1e-9
        per_block = per_block or _ROWS
        blocks = [rows[r0 : r0 + per_block] for r0 in range(0, rows.size, per_block)]
        workers = max(1, min(len(blocks), len(os.sched_getaffinity(0))))
        with ThreadPoolExecutor(workers) as pool:
            for w0 in range(0, len(blocks), workers):
                runs = [
                    r
                    for parts in pool.map(
                        lambda rb: self._split(x, rb, radius), blocks[w0 : w0 + workers]
                    )
                    for r in parts
                ]
                for r0 in range(0, len(runs), workers):
                    wave = runs[r0 : r0 + workers]
                    for a, b in pool.map(lambda rb: self._near(x, rb, radius), wave):
                        keep = squared_gaps(x, a, b) <= limit
                        yield a[keep], b[keep]
