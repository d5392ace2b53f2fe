"""Labels that mean what they say: where one labelled action gives way to the next.

A take's labelled stretches meet at single frames, and the motion does not change there:
the MoCap6 labels of the shared takes run on through the transition into the next
action, or start the next action before the last cycle of this one is over. An avatar
that plays a cycle across such a boundary seems to switch action and come back, and the
vote reads a window of the transition as the next action.

``clean_labels`` moves each boundary between two labelled stretches to where the motion
changes. A frame of a cyclic action recurs: a cycle later the performer is in nearly the
same pose. Near a boundary between actions ``A`` and ``B`` (up to ``reach`` seconds
either side, and at most half of either stretch), each frame is compared with the
frames of ``A``'s stretch and of ``B``'s stretch at least ``cycle`` seconds from it
(where it recurs, a cycle earlier or later), and the boundary splits the frames into
those that recur in ``A``, a
transition that recurs in neither, and those that recur in ``B`` (one split, the least
cost: a frame costs its distance to the cycle it is given, relative to how near that
cycle's own frames come to each other). The transition is kept with ``A``: it is the
way out of ``A``, and the next action begins where its cycle does.

Only boundaries between two labelled stretches of one clip move; an unlabelled stretch,
a stretch too short to hold a cycle and a clip's ends are left alone. The label files
are never changed: ``load_library(clean_labels=False)`` reads them as they are (as a
ground truth is read), and ``mimic library labels`` writes the cleaned ones and says
what moved.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["Boundary", "clean_labels", "pose_rows", "source_label_rows"]

#: a frame fits a cycle when it is nearer it than ``FIT`` times the cycle's own frames
#: are to each other (their median); a transition frame costs ``FIT``, a frame given to
#: a cycle its relative distance, at most ``CAP``
FIT = 2.0
CAP = 4.0

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Boundary:
    """One boundary between two labelled stretches, in frames of the clip: the source
    label's (the first frame of ``B``), the transition found (``[transition_start,
    cleaned)``; empty when the motion goes straight from ``A``'s cycle into ``B``'s),
    and the cleaned boundary."""

    before: int
    after: int
    source: int
    transition_start: int
    cleaned: int


def pose_rows(quats: FloatArray) -> FloatArray:
    """Per-frame pose rows ``(F, 4 (J - 1))`` of joint rotations ``(F, J, 4)``: every
    joint but the root (whose turn and place say where, not what), each quaternion on the
    hemisphere of ``w >= 0`` so that a rotation has one row."""
    q = np.asarray(quats, dtype=np.float64)[:, 1:]
    q = np.where(q[..., :1] < 0, -q, q)
    return q.reshape(q.shape[0], -1)


def _recurrence(rows: FloatArray, at: IntArray, lo: int, hi: int, gap: int) -> FloatArray:
    """Each frame ``at``'s distance to the nearest frame of ``rows[lo:hi]`` at least
    ``gap`` frames away from it (a cycle earlier or later; ``inf`` when none is)."""
    span = rows[lo:hi]
    d2 = (rows[at] ** 2).sum(1)[:, None] - 2.0 * rows[at] @ span.T + (span**2).sum(1)[None, :]
    near = np.abs(at[:, None] - np.arange(lo, hi)[None, :]) < gap
    d2[near] = np.inf
    return np.sqrt(np.maximum(d2.min(axis=1), 0.0))


def _split(cost_a: FloatArray, cost_b: FloatArray) -> tuple[int, int]:
    """The split ``p <= q`` of a run of frames into ``A`` before ``p``, a transition in
    ``[p, q)`` and ``B`` from ``q`` with the least cost: a frame given to a cycle costs
    its relative distance to it (at most ``CAP``), a transition frame ``FIT``."""
    n = cost_a.size
    a = np.concatenate([[0.0], np.cumsum(np.minimum(cost_a, CAP))])
    b = np.concatenate([[0.0], np.cumsum(np.minimum(cost_b, CAP))])
    best, where = np.inf, (0, 0)
    for p in range(n + 1):
        q = np.arange(p, n + 1)
        total = a[p] + FIT * (q - p) + b[n] - b[q]
        k = int(np.argmin(total))
        if total[k] < best - 1e-12:
            best, where = float(total[k]), (p, int(q[k]))
    return where


def clean_labels(
    quats: FloatArray, labels: IntArray, fps: float, reach: float = 1.5, cycle: float = 0.4
) -> tuple[IntArray, list[Boundary]]:
    """The cleaned labels of one clip (``labels``: an index per frame, -1 unlabelled)
    and each boundary's move (see the module). ``reach``: seconds either side of a source
    boundary in which it may move; ``cycle``: the least time between a frame and its
    recurrence (half the shortest cycle of the library's actions)."""
    labels = np.asarray(labels, dtype=np.int64)
    if labels.ndim != 1 or quats.shape[0] != labels.size:
        raise ValueError(f"one label per frame is needed ({labels.size} for {quats.shape[0]})")
    out = labels.copy()
    starts = np.concatenate([[0], np.flatnonzero(labels[1:] != labels[:-1]) + 1, [labels.size]])
    rows = pose_rows(quats)
    reach_n, gap = max(1, round(reach * fps)), max(1, round(cycle * fps))
    moves = []
    for i in range(1, starts.size - 1):
        a0, b0, b1 = int(starts[i - 1]), int(starts[i]), int(starts[i + 1])
        if labels[a0] < 0 or labels[b0] < 0:
            continue
        lo = max(a0 + (b0 - a0) // 2, b0 - reach_n)
        hi = min(b0 + (b1 - b0) // 2, b0 + reach_n)
        if b0 - a0 <= 2 * gap or b1 - b0 <= 2 * gap or hi <= lo:
            continue  # a stretch too short to hold a cycle: left as labelled
        # how near each stretch's frames come to their own recurrences (the median)...
        spread_a = np.median(_recurrence(rows, np.arange(a0, b0), a0, b0, gap))
        spread_b = np.median(_recurrence(rows, np.arange(b0, b1), b0, b1, gap))
        # ...and how near each frame about the boundary comes to a recurrence in each
        near = np.arange(lo, hi)
        cost_a = _recurrence(rows, near, a0, b0, gap) / max(float(spread_a), 1e-9)
        cost_b = _recurrence(rows, near, b0, b1, gap) / max(float(spread_b), 1e-9)
        p, q = _split(cost_a, cost_b)
        out[lo : lo + q] = labels[a0]
        out[lo + q : hi] = labels[b0]
        moves.append(Boundary(int(labels[a0]), int(labels[b0]), b0, lo + p, lo + q))
    return out, moves


def source_label_rows(
    labels: IntArray, names: tuple[str, ...], source_frames: FloatArray, source_length: int
) -> list[tuple[int, int, str]]:
    """A clip's ``labels`` (one per frame of the library, whose frame ``k`` shows source
    frame ``source_frames[k]``) as a label file's rows: ``(first, last, action)``, 1-based
    frames of the source's ``source_length``, each source frame taking the label of the
    library frame nearest it; unlabelled frames have no row."""
    src = np.asarray(source_frames, dtype=np.float64)
    at = np.clip(np.searchsorted(src, np.arange(source_length)), 0, src.size - 1)
    before = np.clip(at - 1, 0, src.size - 1)
    pick = np.where(
        np.abs(src[before] - np.arange(source_length))
        <= np.abs(src[at] - np.arange(source_length)),
        before,
        at,
    )
    per = np.asarray(labels, dtype=np.int64)[pick]
    rows = []
    start = 0
    for i in range(1, source_length + 1):
        if i == source_length or per[i] != per[start]:
            if per[start] >= 0:
                rows.append((start + 1, i, names[int(per[start])]))
            start = i
    return rows
