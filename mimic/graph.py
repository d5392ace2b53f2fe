"""``mimic graph build`` and ``mimic graph walk``."""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np

from control.graph import (
    BlendSettings,
    joint_jumps,
    quality_summary,
    random_walk,
    save_graph,
    sole_speed,
    synthesize,
)
from control.jobs import cluster_address
from control.motion import write_bvh

from .args import (
    MOST_MOTION_SECONDS,
    add_graph_args,
    add_library_args,
    blend_seconds,
    graph_for,
    number,
    start_frame,
)
from .outputs import check_outputs

__all__ = ["add_graph_commands", "format_report"]


def add_graph_commands(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    graph = sub.add_parser("graph", help="the motion graph (lower layer)")
    gsub = graph.add_subparsers(dest="graph_command", required=True)
    build = gsub.add_parser(
        "build",
        help="build (or load from the cache) the motion graph and print the Table 1 report",
        description="Frame distances, eq. 1 likelihoods and the four pruning rules of "
        "Lee et al. Table 1. The graph is cached by a hash of the library and the options.",
    )
    add_library_args(build)
    add_graph_args(build)
    build.add_argument(
        "--cluster",
        help="search the frame pairs on a Dask cluster: a scheduler's address "
        "(tcp://host:8786) or local:N (default: $MIMIC_CLUSTER, else this machine); "
        "the graph is the one this machine builds",
    )
    build.add_argument("--out", help="also write the graph to this .npz file")
    build.add_argument("--json", action="store_true", help="print the report as JSON")
    build.set_defaults(func=_graph_build)
    walk = gsub.add_parser(
        "walk",
        help="a random walk through the graph, written as BVH",
        description="Probabilistic motion (eq. 1) with blended transitions and planted feet.",
    )
    add_library_args(walk)
    add_graph_args(walk)
    walk.add_argument(
        "--seconds",
        type=number(float, 0, MOST_MOTION_SECONDS, above=True),
        required=True,
        help="length of the walk",
    )
    walk.add_argument("--out", required=True, help="BVH file to write")
    walk.add_argument(
        "--seed", type=number(int, 0, 2**32 - 1), default=0, help="random seed (default 0)"
    )
    walk.add_argument("--start", help="start at CLIP:FRAME (default: a random frame)")
    walk.add_argument("--no-ik", action="store_true", help="do not keep planted feet in place")
    walk.add_argument(
        "--quality",
        action="store_true",
        help="also measure foot slide, joint jumps and jerk against the raw clips",
    )
    walk.add_argument("--json", action="store_true", help="print the summary as JSON")
    walk.set_defaults(func=_graph_walk)


def format_report(report: dict[str, Any]) -> str:
    """The Table 1 line of a graph report, with a header."""
    sim = "N/A" if report["similarity"] is None else f"{report['similarity']:,}"
    head = f"{'frames':>8} {'possible':>14} {'contact':>12} {'likelihood':>11} {'similarity':>11}"
    row = (
        f"{report['frames']:>8,} {report['possible']:>14,} {report['contact']:>12,} "
        f"{report['likelihood']:>11,} {sim:>11}"
    )
    if report.get("case4") is not None:
        head += f" {'case 4':>8}"
        row += f" {report['case4']:>8,}"
    return f"{head} {'SCC':>8}\n{row} {report['scc']:>8,}"


def _graph_build(args: argparse.Namespace) -> int:
    check_outputs(args, ["--out"])  # before minutes of building
    cluster_address(args.cluster)  # and a bad cluster address
    _, graph, path, built = graph_for(args)
    if args.out:
        save_graph(graph, args.out)
    r = graph.report
    if args.json:
        print(json.dumps({"graph": str(path), "built": built, **r}, indent=2))
        return 0
    print(format_report(r))
    excluded = r["excluded_clips"]
    print(
        f"\n{r['clips']} clips at {r['fps']:g} frames/s, coords {graph.options.coords}, "
        f"contact rule {graph.options.contact}; sigma {r['sigma']:.4f}, transitions kept at "
        f"distance <= {r['max_distance']:.4f}; largest strongly connected component: "
        f"{r['scc_frames']:,} of {r['frames']:,} frames ({r['components']:,} components)"
    )
    if excluded:
        print(f"left out (other joints): {', '.join(excluded)}")
    how = f"built in {r['seconds']['total']:.2f} s" if built else "loaded from the cache"
    print(f"graph {path} ({how})")
    return 0


def _graph_walk(args: argparse.Namespace) -> int:
    check_outputs(args, ["--out"])
    if not args.seconds > 0:
        raise ValueError("--seconds must be positive")
    library, graph, path, _ = graph_for(args)
    start = start_frame(graph, args.start)
    n = max(1, round(args.seconds * graph.fps))
    frames, jumps, edges = random_walk(graph, n, seed=args.seed, start=start)
    blend = BlendSettings(seconds=blend_seconds(args), ik=not args.no_ik)
    syn = synthesize(graph, library.clips, frames, jumps, edges, blend)
    write_bvh(syn.motion, args.out)
    minutes = n / graph.fps / 60.0
    summary: dict[str, Any] = {
        "out": args.out,
        "graph": str(path),
        "seconds": round(n / graph.fps, 2),
        "frames": n,
        "transitions": int(jumps.size),
        "transitions_per_minute": round(jumps.size / minutes, 1),
        "clips_visited": len({graph.locate(int(f))[0] for f in frames}),
        "unreachable_foot_frames": syn.unreachable,
    }
    if args.quality:
        chosen = [library.clip(c) for c in graph.clip_names]
        raw = quality_summary([c.motion for c in chosen], [c.contacts.states for c in chosen])
        per_frame = np.concatenate([sole_speed(c.motion, c.contacts.states) for c in chosen])
        raw["foot_slide_visited"] = float(np.nanmean(per_frame[frames]))
        out = quality_summary([syn.motion], [syn.states])
        jj = joint_jumps(syn.motion)
        at = jj[jumps - 1] if jumps.size else np.zeros(1)
        summary["quality"] = {
            "raw": raw,
            "walk": out,
            "transition_jump_max_deg": float(at.max()),
            "transition_jump_p99_deg": float(np.percentile(at, 99)),
        }
    if args.json:
        print(json.dumps(summary, indent=2))
        return 0
    print(
        f"wrote {args.out}: {summary['seconds']} s, {summary['transitions']} transitions "
        f"({summary['transitions_per_minute']}/min) through {summary['clips_visited']} clips"
    )
    if args.quality:
        q = summary["quality"]
        print(f"{'':28}{'raw clips':>12}{'walk':>12}")
        for key, label in (
            ("foot_slide_mean", "foot slide, m/s (mean)"),
            ("jump_p99_deg", "joint jump p99, deg"),
            ("jerk_mean", "jerk, m/s^3 (mean)"),
        ):
            print(f"{label:<28}{q['raw'][key]:>12.3f}{q['walk'][key]:>12.3f}")
            if key == "foot_slide_mean":
                print(
                    f"{'  raw, frames the walk shows':<28}{q['raw']['foot_slide_visited']:>12.3f}"
                )
        print(
            f"largest joint jump at a transition: {q['transition_jump_max_deg']:.1f} deg "
            f"(raw 99th percentile {q['raw']['jump_p99_deg']:.1f})"
        )
    return 0
