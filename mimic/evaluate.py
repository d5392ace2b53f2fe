"""``mimic evaluate``: a labelled video through perform's loop; agreement by lag, the
confusion matrix, JSON and a plot."""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path
from typing import Any

from control.artifacts import atomic_write
from control.motion import default_library_path
from control.progress import bar
from vision import (
    evaluation,
    motion_truth,
    open_source,
    perform,
    plot_evaluation,
    truth_for,
)

from .outputs import Output, OutputSet
from .run import (
    prepare,
    print_actions,
    warn_own_take,
    warn_source,
)
from .run_args import add_run_args, run_settings, silhouette_flag

__all__ = ["add_evaluate_command"]


def add_evaluate_command(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    e = sub.add_parser(
        "evaluate",
        help="how often the avatar does the performer's action: a labelled video in, "
        "agreement by lag, confusion matrix, JSON and a plot out",
        description="Replay a labelled performance (a recording with its sidecar, or any "
        "video with a labels CSV) through mimic perform's loop, with its defaults, and "
        "compare the avatar's action at every decision with the performer's, at lags of "
        "0-3 s (the avatar follows, so it may be late).",
    )
    e.add_argument("video", help="a recording (with its .json sidecar) or any video file")
    e.add_argument(
        "--labels", help="labels CSV (file,start,end,label) when the video has no sidecar"
    )
    add_run_args(e)
    e.add_argument("--json", required=True, help="the report (JSON) to write")
    e.add_argument("--png", help="a plot of agreement against lag and the confusion matrix")
    e.set_defaults(func=_evaluate)


def _write_report(path: Path, report: dict[str, object]) -> None:
    with atomic_write(path) as fh:
        fh.write(json.dumps(report, indent=1) + "\n")


def _evaluate(args: argparse.Namespace) -> int:
    truth = truth_for(args.video, args.labels)  # bad: LabelFileError, naming the file
    if truth is None:
        raise ValueError(
            f"{args.video}: no ground truth (no {Path(args.video).name}.json sidecar): "
            "give --labels CSV"
        )
    settings = run_settings(args)  # a bad setting is said before any work
    # a recording of a library take: the lag from where the motion changes too (a bad
    # sidecar is said before any work)
    root = settings.library.folder or default_library_path()
    motion = motion_truth(args.video, root) if args.labels is None else None
    outputs = OutputSet(  # a clash or an unwritable place: said before any work
        [
            Output("--json", Path(args.json)),
            Output("--png", Path(args.png)) if args.png else None,
        ],
        [
            ("the video", args.video),
            ("the video's sidecar", f"{args.video}.json"),
            ("--labels", args.labels),
        ],
    )
    source = open_source(None, args.video, None, silhouette=silhouette_flag(args))
    ready = prepare(settings, source)
    try:
        result = perform(
            source,
            ready.layer,
            ready.bank,
            ready.clips,
            ready.settings,
            start=ready.start,
            seed=args.seed,
            fallback=ready.fallback,
            voice=ready.voice,
            bars=bar,
        )
    finally:
        source.close()
    warn_own_take(args.video, ready.clips)
    warn_source(source)
    report = evaluation(result.decisions, ready.clips, truth, result.media_seconds, motion=motion)
    match = dataclasses.asdict(ready.settings.match)
    # the vote the run used (the default is the descriptor's own: ``switch_for``)
    action = ready.settings.match.action
    kind = ready.bank.settings.features.kind
    match["action"]["switch_chance"] = action.switch_for(kind, ready.voice is not None)
    report = {
        "video": str(args.video),
        "library": [c.name for c in ready.clips],
        "descriptor": ready.descriptor,
        "graph": {"coords": ready.graph.options.coords, "frames": ready.graph.n_frames},
        "match": match,
        **report,
    }
    with outputs:  # the report and its plot replaced together, or neither
        outputs.write(outputs.outputs[0], lambda p: _write_report(p, report))
        if args.png:
            title = f"{Path(args.video).name} against {truth.source}"
            outputs.write(outputs.outputs[1], lambda p: plot_evaluation(report, p, title=title))
        outputs.commit()
    print_actions(result.decisions, ready.clips)
    _print_figures(report)
    print(f"wrote {args.json}" + (f" and {args.png}" if args.png else ""))
    return 0


def _print_figures(report: dict[str, Any]) -> None:
    """The run's agreement, switches and decision points, as ``mimic evaluate`` prints
    them."""
    best = report["best_at_lag_le_1s"]
    sw = report["switches_per_minute"]
    print(
        "agreement (actions the library has): "
        + (f"{best:.2f} at lag {report['best_lag_s']:g} s" if best is not None else "none")
        + f"; chance {report['chance']}; per action "
        + ", ".join(f"{a} {v:.2f}" for a, v in report["per_action_at_best_lag"].items())
        + f"; switches a minute: avatar {sw['avatar']} (actions shown under 0.5 s: "
        f"{sw['avatar_brief_actions_under_0.5s']} a minute), performer {sw['performer']}"
    )
    after = report["switch_followed_after_s"]
    if "switch_followed_after_motion_s" in report and after["median_s"] is not None:
        moved = report["switch_followed_after_motion_s"]
        at = report["best_lag_from_motion_s"]
        print(
            f"a new action taken up a median {after['median_s']:g} s after the label file's "
            f"change, {moved['median_s']:g} s after the performer's motion changes "
            f"(the take's cleaned labels; agreement against them best at lag {at:g} s)"
        )
    points = report["decision_points"]
    print(
        f"decision points: {points['points']}, {points['decided']} decided"
        + "".join(
            f" ({n} by {k})" for k, n in points.get("decided_by", {}).items() if k != "landmarks"
        )
        + "; "
        f"{points['person_in_view_undecided']} undecided with a person in view"
        + "".join(f"; {why}: {n}" for why, n in points["undecided_by_reason"].items())
    )
