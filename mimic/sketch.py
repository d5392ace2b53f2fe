"""``mimic sketch``: the avatar follows a path drawn on the ground (Lee et al. §5.2)."""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

import numpy as np

from control.clusters import HigherLayer, LayerSettings, cached_higher_layer
from control.graph import CapturedTerrain, MotionGraph, Synthesis, terrain_options
from control.motion import Library, write_bvh
from control.progress import step
from control.sketch import (
    Environment,
    SketchSettings,
    SketchTracker,
    draw_top_down,
    environment_mesh,
    read_environment,
    read_sketch,
)
from silhouette_bank import MP4_FOURCC

from .args import (
    MOST_MOTION_SECONDS,
    add_graph_args,
    add_library_args,
    blend_seconds,
    graph_for,
    graph_options,
    library_for,
    number,
    start_frame,
)
from .outputs import OutputSet, check_outputs

__all__ = ["add_sketch_command"]


def add_sketch_command(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "sketch",
        help="follow a sketched ground path (through a maze or over blocks), write BVH, "
        "PNG and MP4",
        description="The path (JSON {'points': [[x, z], ...]} or CSV x,z lines, metres) is "
        "the centre of mass on the ground. Best-first search in the motion graph with the "
        "objective of Lee et al. eq. 8 commits a fixed number of frames per step; paths that "
        "come within --radius of an obstacle of --env are rejected. On a terrain --env the "
        "graph uses terrain coordinates (quarter turns, whole-block shifts and lifts, with the "
        "block grid found under the clips' feet) and planted feet must land on blocks of the "
        "level they were captured on: pass the clips captured on blocks (CMU: --clips '03_*').",
    )
    add_library_args(p)
    add_graph_args(p)
    # the maze of the paper used relative coordinates; a terrain env makes them "terrain"
    p.set_defaults(coords="relative")
    p.add_argument("--path", required=True, help="the sketch: JSON or CSV file")
    p.add_argument("--env", help="environment JSON: a maze of polygon obstacles or block terrain")
    p.add_argument("--out", required=True, help="BVH file to write")
    p.add_argument("--png", help="top-down picture of sketch, obstacles and root path")
    p.add_argument("--video", help="MP4 of the avatar (shaded, camera following)")
    d = SketchSettings()
    p.add_argument(
        "--c", type=number(float, 0, 1000), default=d.c, help=f"facing weight of eq. 8 (m, {d.c})"
    )
    p.add_argument(
        "--step-frames", type=number(int, 1, 1000), default=d.step_frames, help="frames per step"
    )
    p.add_argument(
        "--radius", type=number(float, 0, 100), default=d.body_radius, help="obstacle clearance, m"
    )
    p.add_argument(
        "--seconds",
        type=number(float, 0, MOST_MOTION_SECONDS, above=True),
        help="most motion to plan (default: from length)",
    )
    p.add_argument("--baseline", action="store_true", help="also run without the facing term")
    p.add_argument(
        "--approach",
        choices=("search", "actions"),
        default="search",
        help="search: best-first search of eq. 8 (default); actions: the paper's first "
        "approach, the cluster-tree action whose root path is nearest the sketch by DTW "
        "(builds the higher layer first: slower)",
    )
    p.add_argument(
        "--k", type=number(int, 1, 10000), help="actions: number of clusters (default: by BIC)"
    )
    p.add_argument(
        "--bound",
        type=number(float, 0, 3600, above=True),
        default=15.0,
        help="actions: cluster tree bound, s",
    )
    p.add_argument(
        "--tree-nodes",
        type=number(int, 1, 10**8),
        default=4096,
        help="actions: most nodes per cluster tree",
    )
    p.add_argument("--start", help="start at CLIP:FRAME")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=_sketch)


def _inputs(args: argparse.Namespace) -> tuple[np.ndarray, Environment | None, float]:
    """The sketch, its environment and the seconds to track it for, each checked before
    any work (a bad file named)."""
    sketch = read_sketch(args.path)
    env = read_environment(args.env) if args.env else None
    if env is not None and np.any(env.clearance(sketch[:1]) < 0):
        raise ValueError(f"{args.path}: the sketch starts inside an obstacle of {args.env}")
    if args.step_frames < 1 or args.radius < 0 or args.c < 0:
        raise ValueError("--step-frames must be at least 1, --radius and --c not negative")
    length = float(np.linalg.norm(np.diff(sketch, axis=0), axis=1).sum())
    seconds = args.seconds if args.seconds is not None else 10.0 + length / 0.3
    if not seconds > 0:
        raise ValueError("--seconds must be positive")
    return sketch, env, seconds


def _sketch(args: argparse.Namespace) -> int:
    outputs = check_outputs(
        args, ["--out", "--png", "--video"], ["--path", "--env"], videos={"--video": MP4_FOURCC}
    )
    sketch, env, seconds = _inputs(args)
    captured: CapturedTerrain | None = None
    if env is not None and env.terrain is not None:
        library, graph, captured = _terrain_graph(args, env.terrain.block)
    else:
        library, graph, _, _ = graph_for(args)
    start = start_frame(graph, args.start)
    layer = None
    if args.approach == "actions":
        if captured is not None:
            raise ValueError("--approach actions does not handle block terrain")
        with step("higher layer (clusters and trees)"):
            layer, _, _ = cached_higher_layer(
                graph,
                library.clips,
                LayerSettings(k=args.k, bound_seconds=args.bound, max_nodes=args.tree_nodes),
            )
    # (name, c, layer): the chosen approach first; --baseline adds its comparison (eq. 8
    # without the facing term, or for actions the eq. 8 search)
    plan: list[tuple[str, float, HigherLayer | None]] = [
        ("actions (DTW)", args.c, layer) if layer is not None else ("eq. 8", args.c, None)
    ]
    if args.baseline:
        plan.append(("eq. 8", args.c, None) if layer is not None else ("no facing term", 0.0, None))
    runs: dict[str, SketchTracker] = {}
    summary: dict[str, Any] = {}
    for name, c, with_layer in plan:
        settings = SketchSettings(c=c, step_frames=args.step_frames, body_radius=args.radius)
        tracker = SketchTracker(
            graph,
            library.clips,
            sketch,
            env,
            settings,
            start=start,
            captured=captured,
            layer=with_layer,
        )
        t0 = time.perf_counter()
        tracker.run(seconds)
        summary[name] = tracker.summary(time.perf_counter() - t0)
        runs[name] = tracker
    first = plan[0][0]
    main = runs[first]
    syn = main.motion(blend=blend_seconds(args) if args.blend is not None else None)
    if captured is not None:
        summary[first]["terrain"] = main.terrain_report(syn)
    _write(outputs, syn, runs, first, sketch, env)
    if args.json:
        print(json.dumps({"out": str(args.out), **summary}, indent=2))
    else:
        _print_summary(summary)
        print(f"wrote {args.out}" + "".join(f", {p}" for p in (args.png, args.video) if p))
    return 0 if main.goal >= len(main.goals) else 1


def _write(
    outputs: OutputSet,
    syn: Synthesis,
    runs: dict[str, SketchTracker],
    first: str,
    sketch: np.ndarray,
    env: Environment | None,
) -> None:
    """The BVH of the ``first`` run's motion ``syn``, and where asked the picture of every
    run's path and the video, replaced together or none."""
    main = runs[first]
    with outputs:
        out, png, video = (outputs.find(o) for o in ("--out", "--png", "--video"))
        assert out is not None
        outputs.write(out, lambda p: write_bvh(syn.motion, p))
        if png is not None:
            roots = {k: v.root_path() for k, v in runs.items()}
            outputs.write(png, lambda p: draw_top_down(p, sketch, env, roots))
        if video is not None:
            from silhouette_bank import render_motion_video

            rise = main.captured.rise if main.captured is not None else 0.0
            scenery = environment_mesh(env, rise) if env is not None else None
            outputs.write(video, lambda p: render_motion_video(syn.motion, p, scenery=scenery))
        outputs.commit()


def _print_summary(summary: dict[str, Any]) -> None:
    """A line per approach (and the feet on the blocks, on terrain)."""
    for name, s in summary.items():
        state = "followed" if s["followed"] else ("stuck" if s["stuck"] else "out of time")
        near = f"; nearest obstacle {s['min_clearance_m']} m" if "min_clearance_m" in s else ""
        print(
            f"{name}: {state} after {s['motion_seconds']} s; deviation mean "
            f"{s['deviation_mean_m']} m, max {s['deviation_max_m']} m; planned "
            f"{s['realtime_factor']}x real time{near}"
        )
        if "terrain" in s:
            t = s["terrain"]
            print(
                f"  feet at contacts, height above the block top: mean |error| "
                f"{t['foot_height_error_mean_m']} m, 95% {t['foot_height_error_p95_m']} m, "
                f"max {t['foot_height_error_max_m']} m; {t['planted_off_block']} of "
                f"{t['planted_frames']} planted frames off by more than half a block"
            )


def _terrain_graph(
    args: argparse.Namespace, block: float
) -> tuple[Library, MotionGraph, CapturedTerrain]:
    """The terrain graph of the chosen clips, on the block grid found under their feet."""
    if not args.clips:
        raise ValueError(
            f"{args.env}: a terrain environment needs the clips captured on blocks: "
            "pass --clips (for the CMU library: --clips '03_*')"
        )
    if args.mirror != "none":
        raise ValueError("--mirror cannot be used on terrain: mirrored clips leave the block grid")
    library = library_for(args)
    options, captured = terrain_options(library.clips, block, graph_options(args))
    _, graph, _, _ = graph_for(args, library, options)
    return library, graph, captured
