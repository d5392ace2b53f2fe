"""The Bezier fallback of Peng et al. §5.4, for node pairs that no path connects.

A greedy walk over the cluster centres goes from the source cluster to the target: at
each step only nodes nearer the target than the current node are allowed, and the
nearest of those to the current node is taken. The visited nodes are split into two
halves whose averaged poses become the control points C1 and C2, and the poses between
the source and target frames follow the Bezier curve of the control polygon
``[source, C1, C2, target]`` (de Casteljau with slerp, per joint). The paper calls the
curve quadratic while naming two control points; we read it as this one curve through
both. Its duration (eq. 2) is ``T = D(source, target) / delta`` frames.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..graph import FrameFeatures, pair_distances
from ..motion import qnormalize, slerp
from ._cluster import FrameClusters

__all__ = ["average_quats", "bezier_quats", "greedy_walk", "interpolation_frames"]

FloatArray = NDArray[np.float64]


def greedy_walk(
    feat: FrameFeatures, clusters: FrameClusters, source: int, target: int, nu: float = 0.01
) -> list[int]:
    """Cluster indices visited from ``source`` to ``target`` (both included)."""
    c = clusters.centres
    k = c.size
    d, _ = pair_distances(feat, np.repeat(c, k), np.tile(c, k), nu)
    dist = d.reshape(k, k)
    walk = [source]
    node = source
    while node != target:
        allowed = np.flatnonzero(dist[:, target] < dist[node, target])
        if allowed.size == 0:  # cannot happen: the target itself is always nearer
            break
        node = int(allowed[np.argmin(dist[node, allowed])])
        walk.append(node)
    return walk


def average_quats(q: FloatArray) -> FloatArray:
    """Average of unit quaternions ``(N, ..., 4)`` over the first axis, signs aligned."""
    ref = q[0]
    signs = np.where(np.sum(q * ref, axis=-1, keepdims=True) < 0.0, -1.0, 1.0)
    return qnormalize(np.sum(q * signs, axis=0))


def bezier_quats(control: FloatArray, n: int) -> FloatArray:
    """Poses ``(n, J, 4)`` along the Bezier curve of control poses ``(P, J, 4)``
    (de Casteljau with slerp), from the first control pose (t = 0) to the last (t = 1)."""
    if n < 2:
        raise ValueError("n must be at least 2")
    t = np.linspace(0.0, 1.0, n)
    pts = np.broadcast_to(control[:, None], (control.shape[0], n, *control.shape[1:])).copy()
    tt = t.reshape(n, *([1] * (control.ndim - 2)))
    while pts.shape[0] > 1:
        pts = np.stack(
            [
                slerp(pts[i], pts[i + 1], np.broadcast_to(tt, pts.shape[1:-1]))
                for i in range(pts.shape[0] - 1)
            ]
        )
    return pts[0]


def interpolation_frames(distance: float, delta: float) -> int:
    """Eq. 2: ``T = D / delta`` frames (at least 2)."""
    if not delta > 0:
        raise ValueError("delta must be positive")
    return max(2, round(distance / delta))
