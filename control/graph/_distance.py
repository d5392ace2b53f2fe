"""The frame distance (Lee et al. eqs. 2-3): an exact kernel over frame pairs and a
blocked search for all pairs below a threshold that never holds a dense n x n matrix.

The search is exact: a cheap lower bound of ``D`` for whole blocks of pairs comes from
one matrix product (``sin^2`` of each half angle instead of the angle squared, see
``q_embed``; the velocity and position terms are plain Euclidean), and only pairs whose
bound is under the threshold are measured with the exact kernel.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numba
import numpy as np
from numpy.typing import NDArray

from ._broad import BroadPhase, wants_broad
from ._features import FrameFeatures, q_embed

__all__ = ["MODE", "close_pair_blocks", "close_pairs", "lower_bound_features", "pair_distances"]

MODE = {"fixed": 0, "relative": 1, "terrain": 2}
IntArray = NDArray[np.int64]


@numba.njit(cache=True, nogil=True)
def _geodesic_sq(p: np.ndarray, q: np.ndarray) -> float:
    c = abs(p[0] * q[0] + p[1] * q[1] + p[2] * q[2] + p[3] * q[3])
    if c > 1.0:
        c = 1.0
    h = math.acos(c)
    return h * h


@numba.njit(cache=True, parallel=True)
def _pair_kernel(
    a: np.ndarray,
    b: np.ndarray,
    joint_q: np.ndarray,
    root_q: np.ndarray,
    root_p: np.ndarray,
    vel: np.ndarray,
    world_p: np.ndarray,
    yaw: np.ndarray,
    nu: float,
    mode: int,
    block: float,
    origin_x: float,
    origin_z: float,
    rise: float,
    out_d: np.ndarray,
    out_align: np.ndarray,
) -> None:
    n_k = joint_q.shape[1]
    n_v = vel.shape[1]
    n_jv = n_v - 6
    for t in numba.prange(a.shape[0]):
        i = a[t]
        j = b[t]
        s = 0.0
        for k in range(n_k):
            s += _geodesic_sq(joint_q[i, k], joint_q[j, k])
        for x in range(n_jv):
            d = vel[i, x] - vel[j, x]
            s += nu * d * d
        if mode != 2:
            s += _geodesic_sq(root_q[i], root_q[j])
            for x in range(3):
                d = root_p[i, x] - root_p[j, x]
                s += d * d
            for x in range(n_jv, n_v):
                d = vel[i, x] - vel[j, x]
                s += nu * d * d
            out_d[t] = s
            if mode == 1:
                ang = yaw[i] - yaw[j]
                c = math.cos(ang)
                sn = math.sin(ang)
                out_align[t, 0] = ang
                out_align[t, 1] = world_p[i, 0] - (c * world_p[j, 0] + sn * world_p[j, 2])
                out_align[t, 2] = 0.0
                out_align[t, 3] = world_p[i, 2] - (-sn * world_p[j, 0] + c * world_p[j, 2])
            else:
                for x in range(4):
                    out_align[t, x] = 0.0
            continue
        # terrain: the best of four quarter turns of frame j about the block centre
        # ``origin``, shifted by whole blocks
        pix = world_p[i, 0] - origin_x
        piz = world_p[i, 2] - origin_z
        pjx = world_p[j, 0] - origin_x
        pjz = world_p[j, 2] - origin_z
        best = np.inf
        for r in range(4):
            ang = r * 0.5 * math.pi
            c = math.cos(ang)
            sn = math.sin(ang)
            ch = math.cos(0.5 * ang)
            sh = math.sin(0.5 * ang)
            qi = root_q[i]
            qj = root_q[j]
            # (quarter-turn yaw) * q_j, dotted with q_i
            cq = abs(
                qi[0] * (ch * qj[0] - sh * qj[2])
                + qi[1] * (ch * qj[1] + sh * qj[3])
                + qi[2] * (ch * qj[2] + sh * qj[0])
                + qi[3] * (ch * qj[3] - sh * qj[1])
            )
            h = math.acos(min(cq, 1.0))
            e = h * h
            rx = pix - (c * pjx + sn * pjz)
            rz = piz - (-sn * pjx + c * pjz)
            kx = round(rx / block)
            kz = round(rz / block)
            ex = rx - kx * block
            ez = rz - kz * block
            e += ex * ex + ez * ez
            for o in (n_jv, n_jv + 3):
                vx = c * vel[j, o] + sn * vel[j, o + 2]
                vz = -sn * vel[j, o] + c * vel[j, o + 2]
                dx = vel[i, o] - vx
                dy = vel[i, o + 1] - vel[j, o + 1]
                dz = vel[i, o + 2] - vz
                e += nu * (dx * dx + dy * dy + dz * dz)
            if e < best:
                best = e
                out_align[t, 0] = ang
                # the same map in library coordinates: p -> R p + t + o - R o
                out_align[t, 1] = kx * block + origin_x - (c * origin_x + sn * origin_z)
                dy = world_p[i, 1] - world_p[j, 1]
                if rise > 0.0:
                    dy = round(dy / rise) * rise
                out_align[t, 2] = dy
                out_align[t, 3] = kz * block + origin_z - (-sn * origin_x + c * origin_z)
        out_d[t] = s + best


#: the same kernel on one thread (``prange`` runs as ``range``)
_pair_kernel_serial = numba.njit(cache=True)(_pair_kernel.py_func)


def pair_distances(
    feat: FrameFeatures,
    a: IntArray,
    b: IntArray,
    nu: float,
    block: float = 0.5,
    origin: tuple[float, float] = (0.0, 0.0),
    rise: float = 0.0,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Exact ``D(a[t], b[t])`` and the alignment that takes frame ``b`` onto frame ``a``.

    Parameters
    ----------
    feat : frame features.
    a, b : (P,) frame indices.
    nu : weight of the velocity term (s^2).
    block : terrain block size in metres (``coords == "terrain"`` only).
    origin : terrain only: ``(x, z)`` of a block's centre on the ground; quarter turns
        are about it, so block centres map onto block centres.
    rise : terrain only: the block height in metres; the vertical offset of a transition
        is rounded to whole blocks (feet stay on block tops). 0 keeps it continuous.

    Returns
    -------
    D : (P,) float64.
    align : (P, 4) ``(yaw, dx, dy, dz)``: rotate frame ``b``'s root by ``yaw`` about +Y,
        then add ``(dx, dy, dz)``. Zero for fixed coordinates.
    """
    a = np.ascontiguousarray(a, dtype=np.int64)
    b = np.ascontiguousarray(b, dtype=np.int64)
    if a.shape != b.shape or a.ndim != 1:
        raise ValueError("a and b must be 1-D arrays of the same length")
    if a.size and (min(a.min(), b.min()) < 0 or max(a.max(), b.max()) >= feat.n):
        raise IndexError(f"frame index out of range 0..{feat.n - 1}")
    if block <= 0 or rise < 0:
        raise ValueError("block must be positive and rise not negative")
    out_d = np.empty(a.size)
    out_align = np.empty((a.size, 4))
    # a few pairs (the vision interface's jumps, every decision): threads cost more than
    # they save
    kernel = _pair_kernel if a.size >= 256 else _pair_kernel_serial
    kernel(
        a,
        b,
        feat.joint_q,
        feat.root_q,
        feat.root_p,
        feat.vel,
        feat.world_p,
        feat.yaw,
        float(nu),
        MODE[feat.coords],
        float(block),
        float(origin[0]),
        float(origin[1]),
        float(rise),
        out_d,
        out_align,
    )
    return out_d, out_align


def lower_bound_features(feat: FrameFeatures, nu: float) -> tuple[np.ndarray, np.ndarray]:
    """``X (n, d)`` float32 and ``norms (n,)`` with ``norms_a + norms_b - 2 X_a.X_b <= D``."""
    parts = [q_embed(feat.joint_q).reshape(feat.n, -1) / np.sqrt(2.0)]
    if feat.coords == "terrain":
        parts.append(np.sqrt(nu) * feat.vel[:, :-6])
    else:
        parts.append(q_embed(feat.root_q) / np.sqrt(2.0))
        parts.append(np.sqrt(nu) * feat.vel)
        p = feat.root_p - feat.root_p.mean(axis=0)
        parts.append(p)
    x = np.concatenate(parts, axis=1)
    return np.ascontiguousarray(x, dtype=np.float32), np.sum(x * x, axis=1)


def close_pairs(
    feat: FrameFeatures,
    rows: IntArray,
    cols: IntArray,
    dmax: float,
    nu: float,
    x: np.ndarray | None = None,
    norms: np.ndarray | None = None,
    max_block_elems: int = 1 << 24,
    broad: BroadPhase | None = None,
) -> tuple[IntArray, IntArray]:
    """All pairs ``(a, b)``, ``a`` in ``rows``, ``b`` in ``cols``, ``a != b``, whose lower
    bound is at most ``dmax``: a superset of the pairs with ``D <= dmax``.

    Works in blocks of at most ``max_block_elems`` pairs (``close_pair_blocks``), so
    memory stays O(n + candidates) whatever the number of frames.
    """
    blocks = list(close_pair_blocks(feat, rows, cols, dmax, nu, x, norms, max_block_elems, broad))
    if not blocks:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty
    return np.concatenate([a for a, _ in blocks]), np.concatenate([b for _, b in blocks])


def close_pair_blocks(
    feat: FrameFeatures,
    rows: IntArray,
    cols: IntArray,
    dmax: float,
    nu: float,
    x: np.ndarray | None = None,
    norms: np.ndarray | None = None,
    max_block_elems: int = 1 << 24,
    broad: BroadPhase | None = None,
) -> Iterator[tuple[IntArray, IntArray]]:
    """``close_pairs``'s pairs a block of rows at a time (each block compares at most
    ``max_block_elems`` pairs), so that a caller can measure and filter them before
    the next block is searched.

    A group of at least ``BROAD_MIN_PAIRS`` comparisons is searched through a KD-tree of
    its columns (``BroadPhase``; ``broad``, when given, is that of ``cols``), which finds
    the same pairs under the bound without comparing every row with every column."""
    if x is None or norms is None:
        x, norms = lower_bound_features(feat, nu)
    rows = np.asarray(rows, dtype=np.int64)
    cols = np.asarray(cols, dtype=np.int64)
    if rows.size == 0 or cols.size == 0:
        return
    # float32 products: allow for their rounding relative to the magnitudes involved
    slack = 1e-5 * (1.0 + 4.0 * float(norms.max())) + 1e-6
    if broad is None and wants_broad(rows.size, cols.size):
        broad = BroadPhase.of(x, cols)
    if broad is not None:
        yield from broad.pairs(x, rows, dmax + slack)
        return
    xc = x[cols]
    nc = norms[cols].astype(np.float32)
    limit = np.float32(dmax + slack)
    step = max(1, max_block_elems // cols.size)
    for r0 in range(0, rows.size, step):
        rb = rows[r0 : r0 + step]
        g = x[rb] @ xc.T
        g *= np.float32(-2.0)
        g += norms[rb].astype(np.float32)[:, None]
        g += nc[None, :]
        ia, ib = np.nonzero(g <= limit)
        a = rb[ia]
        b = cols[ib]
        keep = a != b
        yield a[keep], b[keep]
