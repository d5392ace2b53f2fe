"""``mimic library ...`` subcommands (the CLI itself lives in ``vision.cli``)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from .choose_cli import add_choose_command, start_frame
from .graph import (
    CONTACT_RULES,
    COORDS,
    GraphOptions,
    MotionGraph,
    cached_graph,
    joint_jumps,
    quality_summary,
    random_walk,
    save_graph,
    sole_speed,
    synthesize,
)
from .motion import (
    EMBEDDED_CLIPS,
    EMBEDDED_LIBRARY,
    EMBEDDED_MAX_BYTES,
    Library,
    embed_library,
    load_library,
    write_bvh,
)
from .progress import step

__all__ = [
    "add_graph_commands",
    "add_library_commands",
    "add_library_dir",
    "blend_seconds",
    "format_report",
    "library_dir",
    "library_summary",
    "start_frame",
]


def add_library_commands(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    lib = sub.add_parser("library", help="inspect a motion library")
    lib_sub = lib.add_subparsers(dest="library_command", required=True)
    info = lib_sub.add_parser(
        "info",
        help="clips, frames, duration, rate, joints and contact statistics",
        description="Load a motion library (ASF/AMC and/or BVH) and summarise it.",
    )
    add_library_dir(info)
    info.add_argument("--fps", type=float, default=15.0, help="resample to this rate (default 15)")
    info.add_argument("--mirror", action="store_true", help="add mirrored copies of every clip")
    info.add_argument(
        "--prefer",
        choices=("amc", "bvh"),
        default="amc",
        help="format to use for takes present in both (default amc)",
    )
    info.add_argument("--no-cache", action="store_true", help="neither read nor write the cache")
    info.add_argument("--json", action="store_true", help="print the summary as JSON")
    info.set_defaults(func=_info)
    embed = lib_sub.add_parser(
        "embed",
        help="convert a few clips into the package's embedded default library",
        description=(
            "Convert clips of a full library into compact motion arrays at 30 frames/s, "
            "with their labels and the CMU acknowledgement: the library used when neither "
            "$MIMIC_MOCAP nor ../shared/mocap exists."
        ),
    )
    embed.add_argument("dir", help="the full library folder (e.g. ../shared/mocap)")
    embed.add_argument(
        "--out", default=str(EMBEDDED_LIBRARY), help=f"output folder (default {EMBEDDED_LIBRARY})"
    )
    embed.add_argument(
        "--clips",
        default=",".join(EMBEDDED_CLIPS),
        help=f"comma-separated clip names (default {','.join(EMBEDDED_CLIPS)})",
    )
    embed.set_defaults(func=_embed)


def _embed(args: argparse.Namespace) -> int:
    sizes = embed_library(args.dir, args.out, [c for c in args.clips.split(",") if c])
    total = sum(sizes.values())
    print(f"wrote {len(sizes)} files to {args.out}: {total / 1e6:.2f} MB")
    if total > EMBEDDED_MAX_BYTES:
        print(f"warning: over the {EMBEDDED_MAX_BYTES / 1e6:g} MB the embedded library may use")
    return 0


def library_summary(library: Library) -> dict[str, Any]:
    """Per-clip and total figures of a loaded library, as plain JSON-able values."""
    clips = []
    for c in library.clips:
        st = c.contacts.states
        events = c.contacts.events()
        minutes = max(c.motion.n_frames / c.motion.fps / 60.0, 1e-9)
        clips.append(
            {
                "clip": c.name,
                "frames": c.motion.n_frames,
                "seconds": round(c.motion.n_frames / c.motion.fps, 2),
                "fps": c.motion.fps,
                "joints": c.motion.skeleton.n_joints,
                "contact_left": round(float(st[:, 0].mean()), 3),
                "contact_right": round(float(st[:, 1].mean()), 3),
                "airborne": round(float((~st.any(axis=1)).mean()), 3),
                "contact_changes_per_min": round(len(events) / minutes, 1),
                "labels": list(c.label_names),
                "description": c.description,
            }
        )
    all_states = np.concatenate([c.contacts.states for c in library.clips])
    return {
        "root": library.root,
        "clips": len(library.clips),
        "frames": library.n_frames,
        "seconds": round(library.duration, 1),
        "fps": library.fps,
        "skeletons": [s.n_joints for s in library.skeletons()],
        "contact_fraction": {
            "left": round(float(all_states[:, 0].mean()), 3),
            "right": round(float(all_states[:, 1].mean()), 3),
            "both": round(float(all_states.all(axis=1).mean()), 3),
            "none": round(float((~all_states.any(axis=1)).mean()), 3),
        },
        "contact_changes": int(sum(len(c.contacts.events()) for c in library.clips)),
        "per_clip": clips,
    }


def _info(args: argparse.Namespace) -> int:
    library = load_library(
        library_dir(args),
        fps=args.fps,
        mirror=args.mirror,
        prefer=args.prefer,
        use_cache=not args.no_cache,
    )
    summary = library_summary(library)
    if args.json:
        print(json.dumps(summary, indent=2))
        return 0
    print(
        f"{'clip':<14}{'frames':>7}{'sec':>8}{'fps':>6}{'joints':>7}"
        f"{'L cont':>7}{'R cont':>7}{'air':>6}{'chg/min':>8}  description"
    )
    for row in summary["per_clip"]:
        print(
            f"{row['clip']:<14}{row['frames']:>7}{row['seconds']:>8.1f}{row['fps']:>6g}"
            f"{row['joints']:>7}{row['contact_left']:>7.2f}{row['contact_right']:>7.2f}"
            f"{row['airborne']:>6.2f}{row['contact_changes_per_min']:>8.1f}  {row['description']}"
        )
    cf = summary["contact_fraction"]
    print(
        f"\nlibrary {summary['root']}: {summary['clips']} clips, {summary['frames']} frames, "
        f"{summary['seconds']:.1f} s at {summary['fps'] or 'native'} frames/s, skeletons with "
        f"{', '.join(map(str, summary['skeletons']))} joints; feet in contact: left "
        f"{cf['left']:.0%}, right {cf['right']:.0%}, both {cf['both']:.0%}, neither "
        f"{cf['none']:.0%}; {summary['contact_changes']} contact changes"
    )
    return 0


# --- mimic graph ---------------------------------------------------------------------------


def add_library_dir(p: argparse.ArgumentParser, positional: bool = True) -> None:
    """The library folder, given as ``--library DIR`` in every subcommand (and, where the
    command takes no other positional list, as its last positional argument too); read
    it with ``library_dir(args)``."""
    where = "default: $MIMIC_MOCAP, else ../shared/mocap, else the embedded library"
    if positional:
        p.add_argument("dir", nargs="?", default=None, help=f"library folder ({where})")
    p.add_argument("--library", default=None, metavar="DIR", help=f"library folder ({where})")


def library_dir(args: argparse.Namespace) -> str | None:
    """The library folder of ``add_library_dir``'s arguments (``None``: the default)."""
    pos, opt = getattr(args, "dir", None), getattr(args, "library", None)
    if pos is not None and opt is not None and Path(pos) != Path(opt):
        raise ValueError(f"two library folders given: {pos} and --library {opt}")
    return opt if opt is not None else pos


def _add_library_args(p: argparse.ArgumentParser) -> None:
    add_library_dir(p)
    p.add_argument(
        "--clips",
        action="append",
        metavar="PATTERN",
        help="only clips whose name matches (shell pattern, repeatable): --clips '01_*'",
    )
    p.add_argument("--fps", type=float, default=15.0, help="library frame rate (default 15)")
    p.add_argument("--mirror", action="store_true", help="add mirrored copies of every clip")


def _add_graph_args(p: argparse.ArgumentParser) -> None:
    d = GraphOptions()
    p.add_argument(
        "--coords", choices=COORDS, default=d.coords, help="root coordinates (default fixed)"
    )
    p.add_argument(
        "--contact",
        choices=CONTACT_RULES,
        default=d.contact,
        help="contact pruning rule (default loose)",
    )
    sim = p.add_mutually_exclusive_group()
    sim.add_argument(
        "--similarity",
        dest="similarity",
        action="store_true",
        default=None,
        help="keep only local maxima (default: on unless --contact strict)",
    )
    sim.add_argument("--no-similarity", dest="similarity", action="store_false")
    p.add_argument(
        "--threshold",
        type=float,
        default=d.threshold,
        help=f"likelihood threshold relative to playing on (default {d.threshold})",
    )
    p.add_argument(
        "--sigma-scale",
        type=float,
        default=d.sigma_scale,
        help="sigma = this x the median distance between frames 1/15 s apart",
    )
    p.add_argument("--nu", type=float, default=d.nu, help=f"velocity weight, s^2 (default {d.nu})")
    p.add_argument("--block", type=float, default=d.block, help="terrain block size, metres")
    p.add_argument(
        "--case4",
        choices=("slip", "prune"),
        default=d.case4,
        help="transitions whose blend a foot contact spans: keep and let the foot slip "
        "(default) or prune them",
    )
    p.add_argument(
        "--blend",
        type=float,
        default=None,
        help=f"blend interval b, seconds, of the avatar's transitions and jumps (default "
        f"{d.blend:g}; sketch on block terrain 0.3); with --case4 prune also the interval "
        "the pruning assumes",
    )
    p.add_argument("--rebuild", action="store_true", help="ignore a cached graph")


def add_graph_commands(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    graph = sub.add_parser("graph", help="the motion graph (lower layer)")
    gsub = graph.add_subparsers(dest="graph_command", required=True)
    build = gsub.add_parser(
        "build",
        help="build (or load from the cache) the motion graph and print the Table 1 report",
        description="Frame distances, eq. 1 likelihoods and the four pruning rules of "
        "Lee et al. Table 1. The graph is cached by a hash of the library and the options.",
    )
    _add_library_args(build)
    _add_graph_args(build)
    build.add_argument("--out", help="also write the graph to this .npz file")
    build.add_argument("--json", action="store_true", help="print the report as JSON")
    build.set_defaults(func=_graph_build)
    walk = gsub.add_parser(
        "walk",
        help="a random walk through the graph, written as BVH",
        description="Probabilistic motion (eq. 1) with blended transitions and planted feet.",
    )
    _add_library_args(walk)
    _add_graph_args(walk)
    walk.add_argument("--seconds", type=float, required=True, help="length of the walk")
    walk.add_argument("--out", required=True, help="BVH file to write")
    walk.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    walk.add_argument("--start", help="start at CLIP:FRAME (default: a random frame)")
    walk.add_argument("--no-ik", action="store_true", help="do not keep planted feet in place")
    walk.add_argument(
        "--quality",
        action="store_true",
        help="also measure foot slide, joint jumps and jerk against the raw clips",
    )
    walk.add_argument("--json", action="store_true", help="print the summary as JSON")
    walk.set_defaults(func=_graph_walk)
    add_choose_command(sub, _add_library_args, _add_graph_args, _graph_for)


def _options(args: argparse.Namespace) -> GraphOptions:
    return GraphOptions(
        coords=args.coords,
        contact=args.contact,
        similarity=args.similarity,
        nu=args.nu,
        sigma_scale=args.sigma_scale,
        threshold=args.threshold,
        block=args.block,
        case4=args.case4,
        # only pruning reads the blend: elsewhere it must not change the graph's cache key
        blend=blend_seconds(args) if args.case4 == "prune" else GraphOptions().blend,
    )


def blend_seconds(args: argparse.Namespace, default: float | None = None) -> float:
    """``--blend``, else ``default``, else the graph options' default (1 s)."""
    if args.blend is not None:
        if not (args.blend > 0 and np.isfinite(args.blend)):
            raise ValueError(f"--blend must be positive seconds, not {args.blend}")
        return float(args.blend)
    return GraphOptions().blend if default is None else default


def _graph_for(args: argparse.Namespace) -> tuple[Library, MotionGraph, Path, bool]:
    if args.fps is None or args.fps <= 0:
        raise ValueError("--fps must be positive")
    options = _options(args)
    with step("motion library"):
        library = load_library(
            library_dir(args), fps=args.fps, mirror=args.mirror, clips=args.clips
        )
    with step("motion graph"):
        graph, path, built = cached_graph(library.clips, options, rebuild=args.rebuild)
    return library, graph, path, built


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
    _, graph, path, built = _graph_for(args)
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
    if not args.seconds > 0:
        raise ValueError("--seconds must be positive")
    library, graph, path, _ = _graph_for(args)
    start = start_frame(graph, args.start)
    n = max(1, round(args.seconds * graph.fps))
    frames, jumps, edges = random_walk(graph, n, seed=args.seed, start=start)
    syn = synthesize(
        graph, library.clips, frames, jumps, edges, blend=blend_seconds(args), ik=not args.no_ik
    )
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
