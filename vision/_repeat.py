"""Whether the performer is doing again what they did a moment ago (issue 61).

A performer whose last ``REPEAT_SPAN`` seconds look much like a stretch of their own
last few seconds goes on with what they did: a cycle of jumping jacks comes back every
second, a held toe touch every frame, a second squat looks like the first. A ballot
that then names an action neither voted nor shown is most often the matcher's mistake:
on our simulated takes every wrong action switch of the avatar was a jump into such an
action, undone a moment later, and nothing the matcher logs told them from the right
ones (``benchmarks/HISTORY.md``, "what the switches left are"). How near the performer
comes to their own past does: the right jumps come while the performer does something
new, which no stretch of their last seconds is like ("Repeats").

The test compares the performer with themselves, so it needs no library and carries over
to any body or camera, and it is scaled by the median over the stretches, so it needs no
threshold in the descriptor's units.
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray

__all__ = ["REPEAT_GAP", "REPEAT_REACH", "REPEAT_SPAN", "repeat_frames", "repeated"]

#: seconds of the performer's latest motion compared (about half a cycle of the
#: library's exercises, so a cycle's turn is in it)
REPEAT_SPAN = 0.7
#: the nearest stretch compared ends this many seconds back: nearer ones overlap the
#: latest and are alike whatever the performer does
REPEAT_GAP = 0.4
#: the farthest stretch compared ends this many seconds back (two to three cycles)
REPEAT_REACH = 3.0
#: at least this many seconds of stretches are needed for their median to mean anything
REPEAT_LEAST = 1.0


def repeat_frames(fps: float) -> int:
    """The performer frames ``repeated`` reads at ``fps`` (the history it needs)."""
    return round((REPEAT_REACH + REPEAT_SPAN) * fps)


def repeated(history: NDArray[np.float64], fps: float, ratio: float) -> float | None:
    """How many seconds back the performer did what they do now: where their latest
    ``REPEAT_SPAN`` s of features (the last rows of ``history``, ``(T, F)`` at ``fps``;
    NaN rows: frames without a reading) come within ``ratio`` times the median distance
    of some stretch of their own ending ``REPEAT_GAP`` to ``REPEAT_REACH`` s back, the
    end of the nearest such stretch; ``None`` where none does, with ``ratio`` 0, or
    without enough history. Distances are the mean over the frames both have of each
    frame's Euclidean distance."""
    span = max(2, round(REPEAT_SPAN * fps))
    gap, reach = round(REPEAT_GAP * fps), round(REPEAT_REACH * fps)
    if ratio <= 0 or history.ndim != 2 or history.shape[0] < span + gap + REPEAT_LEAST * fps:
        return None
    latest = history[-span:]
    past = history[max(0, history.shape[0] - reach - span) : history.shape[0] - gap]
    stretches = sliding_window_view(past, span, axis=0).transpose(0, 2, 1)  # (S, span, F)
    frame = np.linalg.norm(stretches - latest[None], axis=2)  # (S, span)
    seen = np.isfinite(frame)
    counted = seen.sum(axis=1)
    ok = counted >= span / 2
    if ok.sum() < REPEAT_LEAST * fps:
        return None
    dist = np.where(ok, np.where(seen, frame, 0.0).sum(axis=1) / np.maximum(counted, 1), np.inf)
    median = float(np.median(dist[ok]))
    back = int(np.argmin(dist[::-1]))  # (the last stretch ends ``gap`` frames back; of
    # stretches alike, the latest)
    if not (median <= 0.0 or dist[-1 - back] < ratio * median):
        return None
    return (gap + back) / fps
