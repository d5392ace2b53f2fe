"""``mimic play``: steer the avatar on the live page by choosing its next action or by
drawing a path on the floor (Lee et al. §5.1 and §5.2), in real time."""

from __future__ import annotations

import argparse
import sys

from control.clusters import LayerSettings, cached_higher_layer
from control.motion import write_bvh
from control.progress import step
from vision import PlaySession, Stage

from .args import (
    MOST_MOTION_SECONDS,
    add_graph_args,
    add_library_args,
    add_offer_args,
    graph_for,
    number,
    start_frame,
)
from .outputs import check_outputs
from .perform import StopOnSignal

__all__ = ["add_play_command"]


def add_play_command(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "play",
        help="steer the avatar on the live page: choose its next action or draw its path",
        description="Serves the live page (http://127.0.0.1:PORT/, this machine only): the "
        "avatar moves in real time; the page offers a few actions to choose from (each "
        "with a moving preview) and follows a path you draw on the floor with the mouse. "
        "Stop with Ctrl-C; --out then holds the avatar's motion.",
    )
    add_library_args(p)
    add_graph_args(p)
    add_offer_args(p, most=12)  # (buttons on a page)
    p.add_argument(
        "--seconds",
        type=number(float, 0, MOST_MOTION_SECONDS, above=True),
        default=600.0,
        help="length of the session (default 600)",
    )
    p.add_argument("--start", help="start at CLIP:FRAME")
    p.add_argument("--seed", type=number(int, 0, 2**32 - 1), default=0)
    p.add_argument(
        "--live-port",
        type=number(int, 0, 65535),
        default=8765,
        help="the page's port on 127.0.0.1 (0: any free one)",
    )
    p.add_argument("--out", help="BVH of the avatar's motion, written at the end")
    p.set_defaults(func=_play)


def _play(args: argparse.Namespace) -> int:
    outputs = check_outputs(args, ["--out"])
    library, graph, _, _ = graph_for(args)
    with step("higher layer (clusters and trees)"):
        layer, _, _ = cached_higher_layer(
            graph, library.clips, LayerSettings(k=args.k, seed=args.seed)
        )
    try:
        stage = Stage(port=args.live_port)
    except OSError as exc:
        raise OSError(f"--live-port {args.live_port}: cannot serve the live page ({exc})") from None
    with stage, StopOnSignal() as stops:
        session = PlaySession(
            stage,
            library.clips,
            layer,
            start=start_frame(graph, args.start),
            seed=args.seed,
            options=args.options,
            lookahead=args.lookahead,
        )
        print(f"live page: {stage.url} (this machine only)", file=sys.stderr, flush=True)
        stopped = session.run(args.seconds, stops)
    choices = sum(p["kind"] == "choice" for p in session.performed)
    sketches = [p for p in session.performed if p["kind"] == "sketch"]
    print(
        f"{session.avatar.time:.1f} s of motion: {choices} actions chosen, "
        f"{len(sketches)} paths followed ({sum(s['followed'] for s in sketches)} to their end)"
        + (f"; stopped by {stopped}" if stopped else "")
    )
    if args.out:
        with outputs:
            out = outputs.find("--out")
            assert out is not None
            motion = session.avatar.motion().motion
            outputs.write(out, lambda p: write_bvh(motion, p))
            outputs.commit()
        print(f"wrote {args.out}")
    return 0
