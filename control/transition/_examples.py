"""Finding the other instances of an action in the library and time-aligning them (Kovar
and Gleicher 2004, "Automated extraction and parameterization of motions in large data
sets"; Peng et al. §6).

``find_examples``: given one example (library frames ``[start, stop)``), every stretch of
the library that looks like it, by subsequence DTW over the graph's frame distance ``D``
(``control.graph.pair_distances``: joint angles, the root's height and tilt, velocities;
the heading and floor position drop out), taken against the library's background (see
``find_examples``); the cheapest are taken greedily.

``register``: the DTW time warp (monotone, each reference frame against the example
frames it matches, averaged) that resamples an example onto the reference's frames.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from ..graph import FrameFeatures, pair_distances
from ..kernels import kernel_input

__all__ = ["Example", "find_examples", "frame_costs", "register"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class Example:
    """Library frames ``[start, stop)`` and their DTW cost per reference frame, over the
    library's background (``find_examples``)."""

    start: int
    stop: int
    cost: float


def frame_costs(feat: FrameFeatures, rows: IntArray, cols: IntArray, nu: float) -> FloatArray:
    """``D(rows[i], cols[j])`` for every pair ``(len(rows), len(cols))``."""
    rows = np.asarray(rows, dtype=np.int64)
    cols = np.asarray(cols, dtype=np.int64)
    d, _ = pair_distances(feat, np.repeat(rows, cols.size), np.tile(cols, rows.size), nu)
    return d.reshape(rows.size, cols.size)


@numba.njit(cache=True)
def _subsequence_dtw(cost: FloatArray) -> tuple[FloatArray, IntArray]:  # pragma: no cover
    """Open-begin, open-end DTW of the reference (rows) in a clip (columns): for each
    end column the cheapest path's cost and its start column."""
    m, n = cost.shape
    acc = np.empty((m, n))
    start = np.empty((m, n), dtype=np.int64)
    for j in range(n):
        acc[0, j] = cost[0, j]
        start[0, j] = j
    for i in range(1, m):
        acc[i, 0] = acc[i - 1, 0] + cost[i, 0]
        start[i, 0] = start[i - 1, 0]
        for j in range(1, n):
            best = acc[i - 1, j - 1]
            s = start[i - 1, j - 1]
            if acc[i - 1, j] < best:
                best = acc[i - 1, j]
                s = start[i - 1, j]
            if acc[i, j - 1] < best:
                best = acc[i, j - 1]
                s = start[i, j - 1]
            acc[i, j] = best + cost[i, j]
            start[i, j] = s
    return acc[m - 1], start[m - 1]


def find_examples(
    feat: FrameFeatures,
    start: int,
    stop: int,
    nu: float = 0.01,
    max_cost: float = 0.5,
    limit: int = 32,
) -> list[Example]:
    """The instances of the action at library frames ``[start, stop)``, itself first,
    then by cost: stretches between half and twice the reference's length whose DTW
    cost per reference frame is at most ``max_cost`` times the *background*, the median
    over the library's clips of each clip's best such cost (what a stretch that merely
    resembles the action costs), at most ``limit``, none overlapping another by more
    than a quarter of the reference. Measured on the shared library (all clips, or only
    13_29, 13_30 and subject 02): the strikes of 02_05 cost at most 0.48-0.50 of their
    background and the nearest other motion (swordplay) 0.56-0.58; the squats of
    13_29 / 13_30 0.14-0.21 against 0.36-0.55; the forward jumps of 01_01 0.39 against
    0.66."""
    if not 0 <= start < stop <= int(feat.clip_start[-1]) or stop - start < 2:
        raise ValueError(f"the reference [{start}, {stop}) is not a stretch of the library")
    ref = np.arange(start, stop, dtype=np.int64)
    m = ref.size
    runs: list[tuple[int, FloatArray, IntArray]] = []
    best: list[float] = []
    for a, b in zip(feat.clip_start[:-1], feat.clip_start[1:], strict=True):
        a, b = int(a), int(b)
        if b - a < m // 2:
            continue
        cost = frame_costs(feat, ref, np.arange(a, b), nu)
        end_cost, first = _subsequence_dtw(kernel_input(cost, np.float64))
        per = end_cost / m
        length = np.arange(b - a) - first + 1
        fair = (length >= m // 2) & (length <= 2 * m)
        if fair.any():
            best.append(float(per[fair].min()))
            runs.append((a, np.where(fair, per, np.inf), first))
    background = float(np.median(best)) if best else 1.0
    found = sorted(
        (float(per[j]) / background, a + int(first[j]), a + int(j) + 1)
        for a, per, first in runs
        for j in np.flatnonzero(per <= max_cost * background)
    )
    out = [Example(start, stop, 0.0)]
    for c, s, e in found:
        if len(out) >= limit:
            break
        if all(min(e, x.stop) - max(s, x.start) <= m // 4 for x in out):
            out.append(Example(s, e, c))
    return out


def register(feat: FrameFeatures, ref: IntArray, frames: IntArray, nu: float = 0.01) -> FloatArray:
    """Where each reference frame falls in ``frames`` ``(len(ref),)``: fractional indices
    into ``frames``, non-decreasing, from the DTW time warp (both ends matched)."""
    cost = frame_costs(feat, ref, frames, nu)
    path = _dtw_path(kernel_input(cost, np.float64))
    where = np.zeros(ref.size)
    count = np.zeros(ref.size)
    np.add.at(where, path[:, 0], path[:, 1].astype(np.float64))
    np.add.at(count, path[:, 0], 1.0)
    return np.maximum.accumulate(where / count)


@numba.njit(cache=True)
def _dtw_path(cost: FloatArray) -> IntArray:  # pragma: no cover
    """The cheapest monotone path ``(L, 2)`` from ``(0, 0)`` to ``(m - 1, n - 1)``."""
    m, n = cost.shape
    acc = np.full((m + 1, n + 1), np.inf)
    acc[0, 0] = 0.0
    for i in range(1, m + 1):
        for j in range(1, n + 1):
            acc[i, j] = cost[i - 1, j - 1] + min(acc[i - 1, j - 1], acc[i - 1, j], acc[i, j - 1])
    out = np.empty((m + n, 2), dtype=np.int64)
    i, j, k = m, n, 0
    while i > 0 and j > 0:
        out[k, 0] = i - 1
        out[k, 1] = j - 1
        k += 1
        d, u, left = acc[i - 1, j - 1], acc[i - 1, j], acc[i, j - 1]
        if d <= u and d <= left:
            i, j = i - 1, j - 1
        elif u <= left:
            i -= 1
        else:
            j -= 1
    return out[:k][::-1].copy()
