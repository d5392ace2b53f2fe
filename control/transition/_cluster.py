"""Frame-based two-pass clustering with a radius threshold (Peng et al. §4.1).

First pass, frames in order: a frame within ``radius`` of the nearest cluster centre
joins that cluster; one farther than ``2 * radius`` from every centre founds a new
cluster with itself as centre; anything between is left undefined. Second pass: every
undefined frame joins its nearest cluster (no new clusters). The distance is the motion
graph's frame distance (Lee et al. eqs. 2-3, relative coordinates by default, so the
same pose anywhere in the capture space is the same pose).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..graph import FrameFeatures, pair_distances

__all__ = ["FrameClusters", "two_pass_clusters"]

IntArray = NDArray[np.int64]


@dataclass(frozen=True, eq=False)
class FrameClusters:
    """``labels`` (n,) cluster of every frame; ``centres`` (K,) the centre frame of each;
    ``undefined`` (n,) frames the first pass left undefined; ``radius`` the threshold."""

    labels: IntArray
    centres: IntArray
    undefined: NDArray[np.bool_]
    radius: float

    @property
    def k(self) -> int:
        return int(self.centres.size)


def two_pass_clusters(feat: FrameFeatures, radius: float, nu: float = 0.01) -> FrameClusters:
    """Cluster the frames of ``feat`` with covering radius ``radius`` (a frame distance)."""
    if not radius > 0:
        raise ValueError("radius must be positive")
    n = feat.n
    labels = np.full(n, -1, dtype=np.int64)
    centres: list[int] = [0]
    labels[0] = 0
    undefined = np.zeros(n, dtype=bool)
    cap = 64
    centre_arr = np.zeros(cap, dtype=np.int64)
    for f in range(1, n):
        k = len(centres)
        d, _ = pair_distances(feat, np.full(k, f), centre_arr[:k], nu)
        j = int(np.argmin(d))
        if d[j] <= radius:
            labels[f] = j
        elif d[j] > 2.0 * radius:
            labels[f] = k
            centres.append(f)
            if k + 1 > cap:
                cap *= 2
                centre_arr = np.resize(centre_arr, cap)
            centre_arr[k] = f
        else:
            undefined[f] = True
    c = np.array(centres, dtype=np.int64)
    todo = np.flatnonzero(undefined)
    if todo.size:
        a = np.repeat(todo, c.size)
        b = np.tile(c, todo.size)
        d, _ = pair_distances(feat, a, b, nu)
        labels[todo] = np.argmin(d.reshape(todo.size, c.size), axis=1)
    return FrameClusters(labels, c, undefined, float(radius))
