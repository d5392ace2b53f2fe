"""``mimic choose``: the choice interface in the terminal (Lee et al. §5.1)."""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from control.avatar import AVATAR_BLENDING, Avatar
from control.choice import Option, offer
from control.clusters import DEFAULT_KS, HigherLayer, LayerSettings, cached_higher_layer
from control.graph import FrameData, MotionGraph
from control.motion import Library, write_bvh
from control.progress import step

from .args import (
    MOST_MOTION_SECONDS,
    add_graph_args,
    add_library_args,
    add_offer_args,
    blend_seconds,
    graph_for,
    number,
    start_frame,
)
from .outputs import check_outputs

__all__ = ["add_choose_command", "parse_ks", "read_script", "run_choice_session"]


def parse_ks(text: str) -> list[int]:
    """``"5:60:5"`` (start:stop:step, stop included) or ``"10,20,25"``."""
    try:
        if ":" in text:
            a, b, *c = (int(v) for v in text.split(":"))
            ks = list(range(a, b + 1, c[0] if c else 1))
        else:
            ks = [int(v) for v in text.split(",")]
    except ValueError as exc:
        raise ValueError(
            f"--ks must be START:STOP:STEP or a list like 10,20,25, not {text!r}"
        ) from exc
    if not ks or min(ks) < 1:
        raise ValueError(f"--ks must list positive numbers of clusters, not {text!r}")
    return ks


def read_script(path: str | Path) -> list[tuple[int, str, float]]:
    """Scripted choices: one per line, ``N`` (take option N), ``wait SECONDS`` or ``quit``;
    ``#`` starts a comment. Returns ``(line, command, value)``."""
    path = Path(path)
    out: list[tuple[int, str, float]] = []
    for no, raw in enumerate(path.read_text().splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        parts = line.split()
        if parts[0] == "quit" and len(parts) == 1:
            out.append((no, "quit", 0.0))
        elif parts[0] == "wait" and len(parts) == 2:
            try:
                seconds = float(parts[1])
            except ValueError:
                seconds = -1.0
            if not seconds >= 0:
                raise ValueError(f"{path}:{no}: wait needs a number of seconds, got {parts[1]!r}")
            out.append((no, "wait", seconds))
        elif len(parts) == 1 and parts[0].isdigit() and int(parts[0]) >= 1:
            out.append((no, "take", float(parts[0])))
        else:
            raise ValueError(f"{path}:{no}: expected an option number, 'wait S' or 'quit': {raw!r}")
    return out


def _describe(option: Option, layer: HigherLayer, library: Library) -> str:
    graph = layer.graph
    clip_name, f = graph.locate(option.key_frame)
    clip = library.clip(clip_name)
    what = clip.label_at(f) or clip.description or ""
    move = option.root_path[-1] - option.root_path[0]
    return (
        f"cluster {option.cluster:>2} in {option.seconds:4.1f} s: pose of {clip_name} at "
        f"{f / graph.fps:5.1f} s{f' ({what})' if what else ''}; root moves "
        f"{np.hypot(move[0], move[2]):.1f} m"
    )


def _commands(args: argparse.Namespace) -> Iterator[tuple[str, str, float]]:
    """``(where, command, value)`` from the script or, without one, from stdin."""
    if args.script:
        for no, cmd, value in read_script(args.script):
            yield f"{args.script}:{no}", cmd, value
        return
    for no, raw in enumerate(sys.stdin, 1):
        line = raw.strip()
        if line in ("q", "quit"):
            yield f"stdin:{no}", "quit", 0.0
        elif line.isdigit() and int(line) >= 1:
            yield f"stdin:{no}", "take", float(line)
        elif line.startswith("wait") or line == "":
            parts = line.split()
            try:
                yield f"stdin:{no}", "wait", float(parts[1]) if len(parts) > 1 else 1.0
            except ValueError:
                print("  (type an option number, 'wait S', or 'q')")
        else:
            print("  (type an option number, 'wait S', or 'q')")


def run_choice_session(
    args: argparse.Namespace, library: Library, graph: MotionGraph, layer: HigherLayer
) -> dict[str, Any]:
    data = FrameData(graph, library.clips)
    start = start_frame(graph, args.start)
    blend = dataclasses.replace(AVATAR_BLENDING, seconds=blend_seconds(args))
    avatar = Avatar(graph, library.clips, start=start, seed=args.seed, blend_settings=blend)
    lookahead = None if args.lookahead <= 0 else (0.0, args.lookahead)
    region = None
    if args.region:
        try:
            x, z, r = (float(v) for v in args.region.split(","))
        except ValueError as exc:
            raise ValueError(f"--region must be X,Z,RADIUS, not {args.region!r}") from exc
        region = (x, z, r)
    performed: list[dict[str, Any]] = []
    commands = _commands(args)
    while avatar.time < args.seconds:
        options = offer(layer, avatar, data, n=args.options, lookahead=lookahead, region=region)
        clip, f = graph.locate(avatar.frame)
        print(
            f"t={avatar.time:6.1f} s  avatar at {clip} {f / graph.fps:5.1f} s, "
            f"cluster {layer.labels[avatar.frame]}"
        )
        for i, o in enumerate(options, 1):
            print(f"  [{i}] {_describe(o, layer, library)}")
        if not options:
            print("  (nothing to choose yet: moving on)")
            avatar.advance(0.5)
            continue
        where, cmd, value = next(commands, ("end", "wait", args.seconds))
        if cmd == "quit":
            break
        if cmd == "wait":
            avatar.advance(min(value, args.seconds - avatar.time) if value > 0 else 1.0 / graph.fps)
            continue
        k = int(value)
        if k > len(options):
            raise ValueError(f"{where}: option {k} chosen but {len(options)} offered")
        o = options[k - 1]
        avatar.take(o.frames, o.edges)
        while avatar.busy:
            avatar.step()
        reached = bool(layer.labels[avatar.frame] == o.cluster)
        performed.append(
            {"option": k, "cluster": o.cluster, "seconds": o.seconds, "reached": reached}
        )
        print(f"  -> took [{k}]: {'reached' if reached else 'did not reach'} cluster {o.cluster}")
    syn = avatar.motion()
    write_bvh(syn.motion, args.out)
    return {
        "out": args.out,
        "seconds": round(avatar.time, 2),
        "actions": len(performed),
        "reached": sum(p["reached"] for p in performed),
        "transitions": int(syn.jumps.size),
        "clusters": layer.clustering.k,
        "performed": performed,
    }


def add_choose_command(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "choose",
        help="steer the avatar by picking among offered actions (terminal), write BVH",
        description="Every decision offers a few well-dispersed actions from the avatar's "
        "cluster tree; type a number to take one, 'wait S' to let it move on its own, "
        "'q' to stop. --script reads the same commands from a file.",
    )
    add_library_args(p)
    add_graph_args(p)
    add_offer_args(p, most=100)
    p.add_argument("--ks", default="5:60:5", help="cluster counts BIC chooses from (5:60:5)")
    p.add_argument("--seeding", choices=("keyframes", "random"), default="keyframes")
    p.add_argument(
        "--bound",
        type=number(float, 0, 3600, above=True),
        default=15.0,
        help="cluster tree time bound, s",
    )
    p.add_argument("--region", help="only actions whose root ends in the circle X,Z,RADIUS")
    p.add_argument(
        "--seconds",
        type=number(float, 0, MOST_MOTION_SECONDS, above=True),
        default=120.0,
        help="length of the session",
    )
    p.add_argument("--script", help="file of choices: N, 'wait S' or 'quit' per line")
    p.add_argument("--start", help="start at CLIP:FRAME")
    p.add_argument("--seed", type=number(int, 0, 2**32 - 1), default=0)
    p.add_argument("--out", required=True, help="BVH file to write")
    p.set_defaults(func=_choose)


def _choose(args: argparse.Namespace) -> int:
    check_outputs(args, ["--out"], ["--script"])
    if args.script and not Path(args.script).is_file():
        raise FileNotFoundError(f"no script file {args.script}")
    if args.script:
        read_script(args.script)  # report a bad script before any work
    if not args.seconds > 0 or args.options < 1:
        raise ValueError("--seconds must be positive and --options at least 1")
    ks = parse_ks(args.ks) if args.k is None else list(DEFAULT_KS)
    library, graph, _, _ = graph_for(args)
    with step("higher layer (clusters and trees)"):
        settings = LayerSettings(
            k=args.k, ks=tuple(ks), seeding=args.seeding, seed=args.seed, bound_seconds=args.bound
        )
        layer, _, _ = cached_higher_layer(graph, library.clips, settings)
    print(
        f"{layer.clustering.k} clusters; {layer.forest.report['trees']} cluster trees "
        f"(median {layer.forest.report['nodes']['median']:.0f} nodes)"
    )
    summary = run_choice_session(args, library, graph, layer)
    print(
        f"wrote {summary['out']}: {summary['seconds']} s, {summary['actions']} actions taken, "
        f"{summary['reached']} reached their cluster, {summary['transitions']} transitions"
    )
    return 0
