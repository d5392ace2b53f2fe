"""The ceiling of following by pose (issue 17): what the avatar's action would be if the
matcher knew the performer's true 3D pose.

At every decision (every 0.1 s from 1 s on), the library window of 1 s nearest the
performer's last second by DTW (band 4, as the matcher's) over the weighted joints'
squared half-angles (the graph's pose distance), and the action of its last frame,
against the performer's action ``lag`` seconds earlier; best over lags <= 1 s. Also with
the matcher's vote (``ActionSettings.vote``) over those windows: the action most voted for
over the last ``vote`` decisions, which changes only when another has more votes.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from vision import ActionVote, switch_delays

LAGS = (0.0, 0.25, 0.5, 0.75, 1.0)


def _window_costs(d: np.ndarray, n: int, band: int) -> np.ndarray:
    """DTW cost of the performer's ``n`` frames (rows of ``d``, ``(n, L)`` pose distances
    to every library frame) against every library window of ``n`` frames."""
    w = d.shape[1] - n + 1
    acc = np.full((n + 1, n + 1, w), np.inf)
    acc[0, 0] = 0.0
    for i in range(1, n + 1):
        for j in range(max(1, i - band), min(n, i + band) + 1):
            best = np.minimum(np.minimum(acc[i - 1, j], acc[i, j - 1]), acc[i - 1, j - 1])
            acc[i, j] = d[i - 1, j - 1 : j - 1 + w] + best
    return acc[n, n]


def _voted(keys: Sequence[str], vote: int) -> list[str]:
    """The matcher's vote (``ActionVote``) over a sequence of best windows' actions."""
    names = sorted(set(keys))
    ballot = ActionVote(vote, 0)
    ballot.actions = np.array([names.index(k) for k in keys], dtype=np.int64)
    out = []
    for i in range(len(keys)):
        ballot.cast(np.array([i], dtype=np.int64))
        out.append(names[ballot.voted])
    return out


def pose_oracle(
    lib_q: np.ndarray,
    lib_actions: np.ndarray,
    clip_start: np.ndarray,
    truth_q: np.ndarray,
    truth_labels: Sequence[str | None],
    fps: float,
    pose_dist: Callable[[np.ndarray, np.ndarray], np.ndarray],
    vote: int = 15,
    band: int = 4,
    motion_labels: Sequence[str | None] | None = None,
) -> dict[str, Any]:
    """Label agreement (best at lags <= 1 s) of the true-pose nearest window, alone and
    voted. ``lib_q``, ``truth_q``: weighted joints' rotations ``(F, K, 4)`` at ``fps``;
    ``lib_actions`` each library frame's action (its label, else its clip's name, as
    ``control.motion.action_keys`` tells them apart), ``truth_labels`` the performer's. Also
    ``pose_error``: the mean pose distance of each best window's last frame to the
    performer's frame at the decision (what an avatar showing it at once would score).
    ``motion_labels``: the performer's cleaned labels (where the motion changes action),
    for the lag counted from there too."""
    n = max(2, round(fps))
    d = np.stack([pose_dist(lib_q, q[None].repeat(lib_q.shape[0], 0)) for q in truth_q])
    w = lib_q.shape[0] - n + 1
    ok = np.ones(w, dtype=bool)
    for s in clip_start[1:-1]:  # a window inside one clip
        ok[max(0, s - n + 1) : min(s, w)] = False
    times = np.arange(1.0, truth_q.shape[0] / fps, 0.1)
    best: list[str] = []
    err: list[float] = []
    for t in times:
        e = round(t * fps)
        costs = _window_costs(d[e - n : e], n, band)
        costs[~ok] = np.inf
        end = int(np.argmin(costs)) + n - 1
        best.append(str(lib_actions[end]))
        err.append(float(d[e - 1, end]))  # its last frame against the performer's now

    def agreement(keys: Sequence[str]) -> float:
        scores = []
        for lag in LAGS:
            k = np.round((times - lag) * fps).astype(int)
            pairs = [
                (g, truth_labels[i])
                for g, i in zip(keys, k, strict=True)
                if 0 <= i < len(truth_labels) and truth_labels[i] is not None
            ]
            scores.append(float(np.mean([g == t for g, t in pairs])) if pairs else 0.0)
        return round(max(scores), 3)

    # how long after each of the performer's switches the nearest windows take the new
    # action up: the lag of a window this long even where the pose is exact
    labelled = {str(a) for a in lib_actions if not str(a).startswith("clip ")}
    k = np.clip(np.round(times * fps).astype(int), 0, len(truth_labels) - 1)
    performer = [truth_labels[i] for i in k]
    voted = _voted(best, vote)
    moved = None
    if motion_labels is not None:
        at = [motion_labels[i] for i in k]  # (the same take's frames as ``truth_labels``)
        moved = switch_delays(best, at, times.tolist(), labelled)
    return {
        "decisions": int(times.size),
        "pose_error": float(np.mean(err)),
        "best_at_lag_le_1s": agreement(best),
        f"voted_{vote}_best_at_lag_le_1s": agreement(voted),
        "switch_followed_after_s": switch_delays(best, performer, times.tolist(), labelled),
        f"voted_{vote}_switch_followed_after_s": switch_delays(
            voted, performer, times.tolist(), labelled
        ),
        "switch_followed_after_motion_s": moved,
    }
