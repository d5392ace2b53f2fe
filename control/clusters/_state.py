"""Motion state vectors (Lee et al. eq. 4) and the reference root orientation.

``x_i = [p_i0, log(q_hat^-1 q_i0), log(q_i1), ..., log(q_im)]`` over the weighted joints
(weight 1: pelvis, spine chain, hips, knees, shoulders, elbows; the others are left out,
which is weight 0). ``log`` is the paper's: a vector of length half the rotation angle.
The root terms follow the graph's coordinates (see ``control.graph.FrameFeatures``):
world position and orientation for ``fixed``; height and heading-free orientation for
``relative``; for ``terrain``, height and heading-free orientation too (its quarter turns
and block shifts make world position and heading meaningless for clustering).
"""

from __future__ import annotations

import numpy as np

from ..graph import FrameFeatures, yaw_of, yaw_q
from ..motion import FloatArray, qconj, qlog, qmul

__all__ = ["orientation_distance", "reference_orientation", "state_vectors"]


def orientation_distance(qa: FloatArray, qb: FloatArray) -> FloatArray:
    """``min(|log(qa^-1 qb)|, |log(qa^-1 (-qb))|)``: half the angle between the rotations."""
    return 0.5 * np.linalg.norm(qlog(qmul(qconj(qa), qb)), axis=-1)


#: products ``q_a . q_b`` held at a time (``_nearest_dots``): 512 MB of float64 (at 200,000
#: frames in fixed coordinates, 63 s against 103 s with 128 MB and about 70 s and 6.4 GB
#: with all columns at once)
_ELEMS = 1 << 26


def _nearest_dots(rows: FloatArray, q: FloatArray, step: int) -> FloatArray:
    """``min_b |rows_a . q_b|`` for each row ``a``, ``step`` columns of ``q`` at a time
    into one buffer (all at once, 2,048 rows against 500,000 frames held 16 GB)."""
    worst = np.full(rows.shape[0], np.inf)
    buf = np.empty((rows.shape[0], min(step, q.shape[0])))
    for c in range(0, q.shape[0], step):
        cols = q[c : c + step]
        dots = buf if cols.shape[0] == buf.shape[1] else np.empty((rows.shape[0], cols.shape[0]))
        np.matmul(rows, cols.T, out=dots)
        np.abs(dots, out=dots)
        np.minimum(worst, dots.min(axis=1), out=worst)
    return worst


def reference_orientation(
    q: FloatArray, block: int = 2048, sample: int = 2048, candidates: int | None = None
) -> FloatArray:
    """The orientation among ``q`` (N, 4) that minimises the distance to the farthest one
    (the first such, in order); with ``candidates``, among at most that many of ``q``
    spread evenly over it, each still measured against every orientation (on a large
    library the distances to the farthest are nearly all alike, and measuring every
    candidate costs frames squared).

    Exact, without all pairs: the distance is ``arccos(|q_a . q_b|)``, so the farthest
    orientation from ``a`` is the one with the smallest ``|q_a . q_b|`` (``worst(a)``).
    Its minimum over ``sample`` spread orientations bounds ``worst(a)`` from above; the
    candidates are then measured against all of ``q``, ``block`` at a time in order of
    their bound, until no bound left can beat the best found (all pairs took 87 s for
    100,000 frames; ``tests/clusters/test_state_gmm.py`` checks it against them).
    """
    q = np.asarray(q, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != 4 or q.shape[0] == 0:
        raise ValueError("q must be a non-empty (N, 4) array")
    n = q.shape[0]
    some = q[np.linspace(0, n - 1, min(n, sample)).astype(np.int64)]
    bound = np.full(n, -np.inf)  # (-inf: not a candidate)
    pool = np.arange(n)
    if candidates is not None and candidates < n:
        pool = np.unique(np.linspace(0, n - 1, candidates).round().astype(np.int64))
    for s in range(0, pool.size, block):
        rows = pool[s : s + block]
        bound[rows] = np.min(np.abs(q[rows] @ some.T), axis=1)
    order = np.argsort(-bound, kind="stable")[: pool.size]
    best, best_i = -np.inf, n
    for s in range(0, order.size, block):
        idx = order[s : s + block]
        if bound[idx[0]] < best:  # no orientation left can beat (or tie) the best
            break
        worst = _nearest_dots(q[idx], q, max(1, _ELEMS // idx.size))
        for w, i in zip(worst, idx, strict=True):
            if w > best or (w == best and i < best_i):
                best, best_i = float(w), int(i)
    return q[best_i].copy()


def state_vectors(
    feat: FrameFeatures, candidates: int | None = None
) -> tuple[FloatArray, FloatArray]:
    """``(X (n, 3 + 3 + 3K), q_hat (4,))``: eq. 4 for every frame of ``feat``, ``q_hat``
    chosen among at most ``candidates`` frames (``reference_orientation``)."""
    if feat.coords == "terrain":
        root_q = qmul(yaw_q(-yaw_of(feat.root_q)), feat.root_q)
        root_p = np.zeros_like(feat.world_p)
        root_p[:, 1] = feat.world_p[:, 1]
    else:
        root_q, root_p = feat.root_q, feat.root_p
    q_hat = reference_orientation(root_q, candidates=candidates)
    root = 0.5 * qlog(qmul(qconj(q_hat), root_q))
    joints = 0.5 * qlog(feat.joint_q).reshape(feat.n, -1)
    return np.concatenate((root_p, root, joints), axis=1), q_hat
