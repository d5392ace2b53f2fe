"""How fast a blended motion's joints may turn from one frame to the next.

A blend carries the jump in pose from one clip to the next over ``b`` frames as an offset
that fades. Where the avatar jumps every few tenths of a second (the vision interface's
direct jumps) offsets pile up, and where one fades while the joint also moves fast in its
source frames, the joint can turn faster in a frame than it ever does in the library
(45 degrees in a frame at 15 frames/s where the library's 99th percentile is 31).
``follow_turns`` lets each joint turn at most ``step`` a frame, or as far as its source
frame itself turns, whichever is more; the rest of the change is put off to the frames
after, which catch up where the source moves more slowly.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from ..motion import FloatArray, qconj, qlog, qmul
from ._ik import turn_toward

__all__ = ["follow_turns", "own_turns"]


@numba.njit(cache=True)
def _follow_turns(want: FloatArray, cap: FloatArray) -> FloatArray:  # pragma: no cover
    out = want.copy()
    n, joints = want.shape[0], want.shape[1]
    for i in range(1, n):
        for j in range(joints):
            p, q = out[i - 1, j], want[i, j]
            w, x, y, z = turn_toward(p[0], p[1], p[2], p[3], q[0], q[1], q[2], q[3], cap[i, j])
            out[i, j, 0], out[i, j, 1], out[i, j, 2], out[i, j, 3] = w, x, y, z
    return out


def own_turns(src_q: FloatArray, jumps: NDArray[np.int64], before: FloatArray) -> FloatArray:
    """Radians ``(T, J)`` each joint of the source frames ``src_q`` ``(T, J, 4)`` turns
    from the frame before; at output frames ``jumps`` ``(M,)``, from the frame ``before``
    ``(M, J, 4)`` that leads into the new clip's frame (its virtual predecessor)."""
    turn = np.zeros(src_q.shape[:2])
    turn[1:] = np.linalg.norm(qlog(qmul(qconj(src_q[:-1]), src_q[1:])), axis=-1)
    ok = np.asarray(jumps) >= 1
    at = np.asarray(jumps, dtype=np.int64)[ok]
    turn[at] = np.linalg.norm(qlog(qmul(qconj(before[ok]), src_q[at])), axis=-1)
    return turn


def follow_turns(want: FloatArray, own: FloatArray, step: float) -> FloatArray:
    """Rotations ``(T, J, 4)`` that follow ``want`` ``(T, J, 4)``, each joint turning
    from its previous frame by at most ``step`` degrees or ``own`` ``(T, J)`` (radians:
    how far its source frame turns, ``own_turns``), whichever is more; where ``want``
    turns further, the joint goes that far along the shorter arc and catches up later."""
    want = np.ascontiguousarray(want, dtype=np.float64)
    own = np.asarray(own, dtype=np.float64)
    if want.ndim != 3 or want.shape[2] != 4 or own.shape != want.shape[:2]:
        raise ValueError(f"want must be (T, J, 4) with own (T, J), not {want.shape}, {own.shape}")
    if not step > 0:
        raise ValueError(f"step must be degrees > 0, got {step}")
    cap = np.ascontiguousarray(np.maximum(own, math.radians(step)))
    return _follow_turns(want, cap)
