"""``mimic evaluate``'s figures: how often the avatar did the performer's action.

From a performance (``perform``'s result) and its ground truth: agreement against lag
(over every labelled decision, and over those whose action the library has), the best at
a lag of at most 1 s, the confusion matrix and per-action agreement at that lag, chance
(the avatar at a random library frame), the avatar's and the performer's action switches
a minute, the avatar's brief actions a minute (flicker: ``brief_actions_per_minute``),
how long after each of the performer's switches the avatar took the new action up
(``switch_delays``: the lag as a viewer sees it, to the decision), for a recording of a
library take also against where the performer's motion changes (``motion_truth``),
the decision points without a decision, per reason (``decision_points``), and the
decision latency. ``plot_evaluation`` draws agreement against lag beside
the confusion matrix (matplotlib, headless).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from control.artifacts import atomic_write
from control.motion import Clip

from ._truth import LAGS, Truth, agreement, avatar_labels, library_actions

__all__ = [
    "UNSEEN_REASONS",
    "brief_actions_per_minute",
    "decision_points",
    "evaluation",
    "plot_evaluation",
    "plot_timeline",
    "switch_delays",
]

#: an action the avatar shows for less than this (seconds) is flicker: it is gone before
#: a viewer could take it for what the avatar does
BRIEF_S = 0.5


def _switches_per_minute(labels: Sequence[str | None], seconds: float) -> float:
    runs = [k for k, _ in itertools.groupby(x for x in labels if x)]
    return round(max(len(runs) - 1, 0) / max(seconds / 60.0, 1e-9), 2)


def brief_actions_per_minute(
    labels: Sequence[str | None], times: Sequence[float], seconds: float, brief: float = BRIEF_S
) -> float:
    """How often a minute the action at ``times`` (``labels``; ``None``: none, skipped)
    changes to one that lasts less than ``brief`` seconds before the next change: the
    flicker among the switches (the first and last actions, cut by the recording, are
    not counted)."""
    kept = [(x, float(t)) for x, t in zip(labels, times, strict=True) if x]
    starts = [next(g)[1] for _, g in itertools.groupby(kept, key=lambda p: p[0])]
    n = sum(b - a < brief for a, b in itertools.pairwise(starts[1:]))
    return round(n / max(seconds / 60.0, 1e-9), 2)


#: a performer's switch that the avatar has not followed within this many seconds is
#: missed (``switch_delays``): by then the avatar is doing something else for good
FOLLOW_WITHIN_S = 4.0


def switch_delays(
    avatar: Sequence[str | None],
    performer: Sequence[str | None],
    times: Sequence[float],
    known: set[str] | None = None,
    within: float = FOLLOW_WITHIN_S,
) -> dict[str, Any]:
    """How long after each switch of the performer's action (``performer`` at ``times``,
    ``None``: unlabelled) into an action the library has (``known``; default: every
    action the avatar shows) the avatar first shows it (``avatar``): the lag of the
    action as a viewer sees it, switch by switch, where the best lag of the agreement
    curve is one number over its coarse steps. A switch is where the performer's label
    changes into such an action, from another or from an unlabelled stretch (standing
    between squats); one not followed within ``within`` seconds is ``missed``, and one
    the recording's end cuts off before then is not counted. ``median_s`` and ``mean_s``
    are over the followed."""
    have = {a for a in avatar if a} if known is None else known
    t = [float(x) for x in times]
    each: list[float] = []
    missed = 0
    for i in range(1, len(performer)):
        new, old = performer[i], performer[i - 1]
        if not new or new == old or new not in have:
            continue
        j = next((j for j in range(i, len(t)) if t[j] - t[i] > within or avatar[j] == new), None)
        if j is not None and avatar[j] == new:
            each.append(round(t[j] - t[i], 3))
        elif j is not None:  # (else cut off by the end)
            missed += 1
    return {
        "switches": len(each) + missed,
        "missed": missed,
        "median_s": round(float(np.median(each)), 3) if each else None,
        "mean_s": round(float(np.mean(each)), 3) if each else None,
        "each_s": each,
    }


#: reasons for no decision that are no failure to follow a person in view: nobody is, the
#: first window is still filling, or the avatar is on its way to a window it chose
UNSEEN_REASONS = ("nobody in view", "no silhouette", "no picture", "filling buffer", "en route")


def decision_points(decisions: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """How many decision points gave no decision, per reason (the log's ``reason``), and
    the share of them at which a person was in view (a reason not in
    ``UNSEEN_REASONS``): the points at which the avatar ignored someone it could see.
    ``decided_by``: how many decisions each kind of evidence made (the log's ``by``:
    landmarks, or the silhouette where they failed), for a run that logs it."""
    reasons: dict[str, int] = {}
    by: dict[str, int] = {}
    for d in decisions:
        if d.get("by") and d.get("decision") is not None:
            by[str(d["by"])] = by.get(str(d["by"]), 0) + 1
        if d.get("decision") is None:
            # (a reason's figures in brackets, a cost, say, are the point's own)
            why = str(d.get("reason") or "no decision").split(" (")[0]
            reasons[why] = reasons.get(why, 0) + 1
    ignored = sum(n for why, n in reasons.items() if why not in UNSEEN_REASONS)
    return {
        "points": len(decisions),
        "decided": len(decisions) - sum(reasons.values()),
        **({"decided_by": dict(sorted(by.items()))} if by else {}),
        "undecided_by_reason": dict(sorted(reasons.items(), key=lambda kv: -kv[1])),
        "person_in_view_undecided": ignored,
        "person_in_view_undecided_share": round(ignored / max(len(decisions), 1), 4),
    }


def evaluation(
    decisions: Sequence[dict[str, Any]],
    clips: Sequence[Clip],
    truth: Truth,
    media_seconds: float,
    lags: Sequence[float] = LAGS,
    motion: Truth | None = None,
) -> dict[str, Any]:
    """The figures of a performance against its ``truth`` (see the module); with
    ``motion`` (``motion_truth``: where the performer's motion changes action), the
    agreement by lag and the lag of each change against it too."""
    known = library_actions(clips)
    every = agreement(decisions, clips, truth, lags)
    have = agreement(decisions, clips, truth, lags, known=known)
    conf = have["confusion_at_best_lag"]
    per_action = {
        a: round(row.get(a, 0) / max(sum(row.values()), 1), 3) for a, row in sorted(conf.items())
    }
    mine = avatar_labels(decisions, clips)
    theirs = [truth.label_at(float(d["t"])) for d in decisions]
    at = [float(d["t"]) for d in decisions]
    # what a viewer compares: the performer's action and the avatar's, on one time axis
    timeline: dict[str, list[Any]] = {"t": [round(x, 3) for x in at], "performer": theirs}
    from_motion: dict[str, Any] = {}
    if motion is not None:
        timeline["motion"] = [motion.label_at(t) for t in at]
        moved = agreement(decisions, clips, motion, lags, known=known)
        from_motion = {
            "motion_truth": motion.source,
            "agreement_known_actions_by_lag_from_motion_s": moved["by_lag_s"],
            "best_at_lag_le_1s_from_motion": moved["best_at_lag_le_1s"],
            "best_lag_from_motion_s": moved["best_lag_s"],
            "switch_followed_after_motion_s": switch_delays(mine, timeline["motion"], at, known),
        }
    return {
        "truth": truth.source,
        "decisions": len(decisions),
        "media_seconds": round(media_seconds, 3),
        "library_actions": sorted(known),
        "performer_actions": sorted({s[2] for s in truth.spans}),
        "agreement_by_lag_s": every["by_lag_s"],
        "decisions_by_lag_s": every["decisions_by_lag_s"],
        "agreement_known_actions_by_lag_s": have["by_lag_s"],
        "decisions_known_actions_by_lag_s": have["decisions_by_lag_s"],
        "best_at_lag_le_1s": have["best_at_lag_le_1s"],
        "best_lag_s": have["best_lag_s"],
        "per_action_at_best_lag": per_action,
        "confusion_at_best_lag": conf,
        "chance": _chance(decisions, clips, truth, have["best_lag_s"] or 0.0, known),
        "switches_per_minute": {
            "avatar": _switches_per_minute(mine, media_seconds),
            "performer": _switches_per_minute(theirs, media_seconds),
            f"avatar_brief_actions_under_{BRIEF_S:g}s": brief_actions_per_minute(
                mine, at, media_seconds
            ),
        },
        "switch_followed_after_s": switch_delays(mine, theirs, at, known),
        **from_motion,
        "decision_points": decision_points(decisions),
        "timeline": {**timeline, "avatar": mine},
        "latency_ms": _latency(decisions),
    }


def _chance(
    decisions: Sequence[dict[str, Any]],
    clips: Sequence[Clip],
    truth: Truth,
    lag: float,
    known: set[str],
) -> float | None:
    """The agreement of an avatar at a random library frame with the performer's actions
    the library has (``known``), at ``lag``."""
    lib = np.array([(c.label_at(i) or "").lower() for c in clips for i in range(c.motion.n_frames)])
    truths = [truth.label_at(float(d["t"]) - lag) for d in decisions]
    truths = [t for t in truths if t is not None and t in known]
    return round(float(np.mean([np.mean(lib == t) for t in truths])), 3) if truths else None


def _latency(decisions: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """The decisions' latency: p50, p99 and the slowest (ms), and how many took over
    0.1 s, the decision interval."""
    made = [d for d in decisions if d.get("decision") is not None and "latency_ms" in d]
    lat = np.array([d["latency_ms"] for d in made], dtype=np.float64)
    return {
        "p50": round(float(np.percentile(lat, 50)), 3) if lat.size else None,
        "p99": round(float(np.percentile(lat, 99)), 3) if lat.size else None,
        "max": round(float(lat.max()), 3) if lat.size else None,
        "over_100ms": int((lat > 100.0).sum()),
    }


#: the timeline's rows, top to bottom, and what each is called on the plot
TIMELINE_ROWS = {
    "performer": "performer",
    "motion": "performer's motion",  # (a recording of a library take: ``motion_truth``)
    "avatar": "avatar",
}


def _timeline(ax: Any, timeline: dict[str, list[Any]] | None) -> None:
    """Rows of coloured spans, the performer's actions (by the labels, and where a
    recording of a library take has them, by where its motion changes) over the avatar's,
    one colour an action: where they differ, and for how long, shows at a glance."""
    if not timeline or not timeline["t"]:
        ax.set_axis_off()
        return
    t = timeline["t"]
    step = float(np.median(np.diff(t))) if len(t) > 1 else 0.1
    keys = [k for k in TIMELINE_ROWS if k in timeline][::-1]  # bottom row first
    names = sorted({x for k in keys for x in timeline[k] if x})
    colours = {n: _colour(i) for i, n in enumerate(names)}
    for row, key in enumerate(keys):
        for label, group in itertools.groupby(zip(t, timeline[key], strict=True), lambda p: p[1]):
            span = list(group)
            if label:
                start, end = span[0][0], span[-1][0] + step
                ax.broken_barh([(start, end - start)], (row - 0.4, 0.8), color=colours[label])
    ax.set_yticks(range(len(keys)), [TIMELINE_ROWS[k] for k in keys])
    ax.set(xlabel="media time (s)", xlim=(t[0], t[-1] + step), title="actions over time")
    handles = [_patch(colours[n], n) for n in names]
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=7)


def _colour(i: int) -> Any:
    """The ``i``-th of 20 distinct colours (matplotlib's tab20)."""
    from matplotlib import colormaps

    return colormaps["tab20"](i % 20)


def _patch(colour: Any, name: str) -> Any:
    from matplotlib.patches import Patch

    return Patch(color=colour, label=name)


def plot_timeline(timeline: dict[str, list[Any]], path: str | Path, title: str = "") -> None:
    """The performer's actions over the avatar's on one time axis (``timeline``: ``t``,
    ``performer``, ``avatar`` and optionally ``motion``, one entry a decision point), as a
    PNG written through a temporary file."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(12, 2.4))
    _timeline(fig.add_subplot(1, 1, 1), timeline)
    _save(fig, path, title, fontsize=9)


def _save(fig: Any, path: str | Path, title: str, fontsize: float | None = None) -> None:
    """``fig`` with its ``title`` as a PNG written through a temporary file; closed."""
    import matplotlib.pyplot as plt

    if title:
        fig.suptitle(title, **({} if fontsize is None else {"fontsize": fontsize}))
    fig.tight_layout()
    try:
        with atomic_write(path, "wb") as fh:
            fig.savefig(fh, format="png", dpi=100)
    finally:
        plt.close(fig)


def plot_evaluation(report: dict[str, Any], path: str | Path, title: str = "") -> None:
    """Agreement against lag (top left), the confusion matrix at the best lag (top
    right) and the performer's and the avatar's actions on one time axis (below), as a
    PNG written through a temporary file."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(12, 7.2))
    grid = fig.add_gridspec(2, 2, width_ratios=[1, 1.2], height_ratios=[2, 1])
    ax, cm = fig.add_subplot(grid[0, 0]), fig.add_subplot(grid[0, 1])
    _timeline(fig.add_subplot(grid[1, :]), report.get("timeline"))
    for key, name in (
        ("agreement_known_actions_by_lag_s", "actions the library has"),
        ("agreement_known_actions_by_lag_from_motion_s", "the same, from the motion"),
        ("agreement_by_lag_s", "every labelled decision"),
    ):
        pts = [(float(k), v) for k, v in report.get(key, {}).items() if v is not None]
        if pts:
            ax.plot(*zip(*pts, strict=True), marker="o", label=name)
    if report.get("chance") is not None:
        ax.axhline(report["chance"], color="grey", linestyle=":", label="chance")
    ax.axvline(1.0, color="grey", linewidth=0.5)
    ax.set(xlabel="lag (s)", ylabel="agreement", ylim=(0, 1), title="the avatar's action")
    ax.legend(loc="lower right")
    conf = report["confusion_at_best_lag"]
    rows = sorted(conf)
    # the performer's actions first, in the rows' order, so that agreement is the diagonal
    cols = rows + sorted({c for r in conf.values() for c in r} - set(rows))
    m = np.array([[conf[r].get(c, 0) for c in cols] for r in rows], dtype=float)
    share = m / np.maximum(m.sum(axis=1, keepdims=True), 1)
    cm.imshow(share if m.size else np.zeros((1, 1)), vmin=0, vmax=1, cmap="Blues", aspect="auto")
    cm.set_xticks(range(len(cols)), cols, rotation=60, ha="right", fontsize=8)
    cm.set_yticks(range(len(rows)), rows, fontsize=8)
    for (i, j), v in np.ndenumerate(m):
        if v:
            cm.text(j, i, str(int(v)), ha="center", va="center", fontsize=7)
    lag = report.get("best_lag_s")
    cm.set(xlabel="avatar", ylabel="performer", title=f"confusion at lag {lag} s")
    _save(fig, path, title)
