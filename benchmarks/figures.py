"""The headline figures of following, made from ``benchmarks/results/*.json``: the table
in ``README.md`` and ``benchmarks/README.md`` is this script's output, so that the figures
a reader sees cannot drift from the results (``tests/test_figures.py`` fails when they do).

Usage: python -m benchmarks.figures [--write]

Without ``--write`` the table is printed; with it, the block between the markers
``<!-- figures:start -->`` and ``<!-- figures:end -->`` of each of the two files is
replaced (through a temporary file). A results file that is missing or lacks a figure
is an error naming it.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
PAGES = (HERE.parent / "README.md", HERE / "README.md")
START, END = "<!-- figures:start -->", "<!-- figures:end -->"
#: the option of the rows below the defaults' (the filter alone, steadier and later)
STEADY = "`--steady` (the filter alone)"


def _load(name: str) -> dict[str, Any]:
    path = RESULTS / name
    try:
        return dict(json.loads(path.read_text()))
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path}: cannot be read ({exc})") from None


def _runs(name: str) -> dict[str, float]:
    """Means over a ``bench_accuracy`` result's runs: agreement (actions the library
    has, the best lag within 1 s), pose score, the avatar's and the performers' action
    switches a minute, and the brief ones; and the median delay with which the avatar
    took up the performers' changes of action, over every run's: from where the label
    files put them, and from where the motion changes (the takes' cleaned labels)."""
    agree, pose, avatar, brief, performer, after, moved = [], [], [], [], [], [], []
    known: list[float] = []  # (results written before the figure existed lack it)
    try:
        for fold in _load(name)["folds"]:
            for run in fold["runs"]:
                after += run.get("switch_followed_after_s", {}).get("each_s", [])
                moved += (run.get("switch_followed_after_motion_s") or {}).get("each_s", [])
                curve = [c for c in run["curve"] if c["lag"] <= 1.0]
                agree.append(max(c["label_agreement_known_actions"] or 0.0 for c in curve))
                pose.append(max(c["score"] for c in curve))
                if all(c.get("score_known_actions") is not None for c in curve):
                    known.append(max(c["score_known_actions"] for c in curve))
                sw = run["switches_per_minute"]
                avatar.append(sw["avatar"])
                brief.append(sw["avatar_brief_actions_under_0.5s"])
                performer.append(sw["performer"])
    except (KeyError, TypeError) as exc:
        raise ValueError(f"{RESULTS / name}: not a bench_accuracy result ({exc})") from None
    if not agree:
        raise ValueError(f"{RESULTS / name}: no runs")
    return {
        "runs": len(agree),
        "agreement": float(np.mean(agree)),
        "pose": float(np.mean(pose)),
        # the pose score where the performer does an action the library has
        "pose_known": float(np.mean(known)) if len(known) == len(pose) else float("nan"),
        "switches": float(np.mean(avatar)),
        "brief": float(np.mean(brief)),
        "performer": float(np.mean(performer)),
        # how long after the performer's changes of action the avatar took them up
        "followed": float(np.median(after)) if after else float("nan"),
        "followed_motion": float(np.median(moved)) if moved else float("nan"),
    }


def _from_motion(runs: dict[str, float]) -> str:
    """`` (X s after the motion changes)`` where the result has that figure, else ``""``."""
    x = runs["followed_motion"]
    return "" if np.isnan(x) else f" ({x:.1f} s after the motion changes)"


def _known(runs: dict[str, float]) -> str:
    """`` (X where the library has the performer's action)`` where the result has that
    figure, else ``""``: another person's own actions leave the avatar no near pose."""
    x = runs["pose_known"]
    return "" if np.isnan(x) else f" ({x:.3f} where the library has the performer's action)"


def _views(name: str = "views.json") -> tuple[str, float, float, float, str]:
    """Agreement by azimuth (a ``bench_views`` result), and the avatar's action switches
    a minute, its brief ones and the performers' switches; and the agreement by azimuth
    against where the motion changes, where the result has it (else ``""``)."""
    data = _load(name)
    try:
        by = sorted(data["by_azimuth"].items(), key=lambda kv: float(kv[0]))
        cells = " / ".join(f"{v['agreement_mean']:.2f}" for _, v in by)
        moved = [v.get("agreement_from_motion_mean") for _, v in by]
        from_motion = " / ".join(f"{x:.2f}" for x in moved) if None not in moved else ""
        azimuths = " / ".join(f"{float(k):g}" for k, _ in by)
        sw = [r["switches_per_minute"] for r in data["runs"]]
        avatar = float(np.mean([s["avatar"] for s in sw]))
        brief = float(np.mean([s["avatar_brief_actions_under_0.5s"] for s in sw]))
        performer = float(np.mean([s["performer"] for s in sw]))
    except (KeyError, TypeError) as exc:
        raise ValueError(f"{RESULTS / name}: not a bench_views result ({exc})") from None
    return f"{cells} (azimuth {azimuths} degrees)", avatar, brief, performer, from_motion


def _squats() -> tuple[float, float]:
    """The real squat clip's agreement at the best lag within 1 s, and that lag."""
    data = _load("real_video.json")
    try:
        clip = data["agreement"]["per_video"]["pose_squats.mp4"]
        by_lag = {float(k): v for k, v in clip["agreement_by_lag_s"].items() if float(k) <= 1}
    except (KeyError, TypeError) as exc:
        raise ValueError(f"{RESULTS / 'real_video.json'}: no squat clip ({exc})") from None
    lag = max(by_lag, key=lambda k: (by_lag[k], -k))
    return float(clip["best_at_lag_le_1s"]), lag


def table() -> str:
    """The headline table (Markdown)."""
    takes, sil = _runs("accuracy_pose_recordings.json"), _runs("accuracy_recordings.json")
    person, sil_person = _runs("accuracy_pose_person.json"), _runs("accuracy_person.json")
    views, v_avatar, v_brief, v_performer, v_motion = _views()
    squats, squat_lag = _squats()
    page = _load("page.json")["pose_squats"]
    steady, s_views = _runs("accuracy_pose_recordings_steady.json"), _views("views_steady.json")
    rows = [
        (
            f"other takes of the same person, simulated landmarks ({takes['runs']} runs)",
            f"{takes['agreement']:.3f}",
            f"pose score {takes['pose']:.3f}; {takes['switches']:.0f} action switches a "
            f"minute ({takes['brief']:.0f} brief) against the performer's "
            f"{takes['performer']:.0f}; a new action taken up a median "
            f"{takes['followed']:.1f} s after the performer's label changes{_from_motion(takes)}",
        ),
        (
            f"the same, silhouette videos ({sil['runs']} runs)",
            f"{sil['agreement']:.3f}",
            f"pose score {sil['pose']:.3f}; {sil['switches']:.0f} switches a minute "
            f"({sil['brief']:.0f} brief) against the performer's {sil['performer']:.0f}; "
            f"the landmarks read from the silhouettes weigh in where the silhouette is "
            f"unsure, and the vote is filtered as the landmarks' is",
        ),
        (
            f"another person, simulated landmarks ({person['runs']} runs)",
            f"{person['agreement']:.3f}",
            f"pose score {person['pose']:.3f}{_known(person)}; "
            f"{person['switches']:.0f} switches a minute against {person['performer']:.0f}; "
            f"new actions taken up after {person['followed']:.1f} s{_from_motion(person)}",
        ),
        (
            f"another person, silhouettes ({sil_person['runs']} runs)",
            f"{sil_person['agreement']:.3f}",
            f"pose score {sil_person['pose']:.3f}{_known(sil_person)}, "
            f"{sil_person['switches']:.0f} "
            f"switches a minute ({sil_person['brief']:.0f} brief) against "
            f"{sil_person['performer']:.0f}",
        ),
        (
            "another person read by MediaPipe, by camera azimuth",
            views,
            f"{v_avatar:.0f} switches a minute ({v_brief:.0f} brief) against {v_performer:.0f}"
            + (f"; against where the motion changes {v_motion}" if v_motion else ""),
        ),
        (
            "a real person squatting (`../shared/video/pose_squats.mp4`)",
            f"{squats:.3f}",
            f"at a lag of {squat_lag:g} s",
        ),
        (
            "the same clip as the live page's camera (`--camera browser`)",
            f"{page['agreement_best_lag_le_1s']:.3f}",
            f"camera frame to avatar pose p50 {page['camera_to_avatar_ms_p50']:.0f} ms, "
            f"p99 {page['camera_to_avatar_ms_p99']:.0f} ms (headless Chromium here)",
        ),
        (
            f"{STEADY}: other takes, simulated landmarks ({steady['runs']} runs)",
            f"{steady['agreement']:.3f}",
            f"pose score {steady['pose']:.3f}; {steady['switches']:.0f} switches a minute "
            f"({steady['brief']:.0f} brief); taken up after {steady['followed']:.1f} s"
            f"{_from_motion(steady)}",
        ),
        (
            f"{STEADY}: another person read by MediaPipe",
            s_views[0],
            f"{s_views[1]:.0f} switches a minute ({s_views[2]:.0f} brief)"
            + (f"; against where the motion changes {s_views[4]}" if s_views[4] else ""),
        ),
    ]
    lines = ["| performer | agreement | note |", "|---|---|---|"]
    lines += [f"| {a} | {b} | {c} |" for a, b, c in rows]
    return "\n".join(lines) + "\n"


def replaced(text: str, block: str, name: str) -> str:
    """``text`` with the block between the markers replaced by ``block``."""
    if text.count(START) != 1 or text.count(END) != 1 or text.index(START) > text.index(END):
        raise ValueError(f"{name}: needs one {START} and one {END} after it")
    head, rest = text.split(START)
    _, tail = rest.split(END)
    return f"{head}{START}\n{block}{END}{tail}"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="replace the tables in the pages")
    a = ap.parse_args()
    try:
        block = table()
        if not a.write:
            print(block, end="")
            return 0
        from control.artifacts import atomic_write

        for page in PAGES:
            new = replaced(page.read_text(), block, str(page))
            with atomic_write(page) as fh:
                fh.write(new)
            print(f"wrote the table into {page}")
    except (OSError, ValueError) as exc:
        print(f"figures: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
