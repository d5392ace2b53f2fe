"""Motion graph: Table 1 reports, build time and memory, scaling, and random-walk quality.

Usage: python -m benchmarks.bench_graph [LIBRARY_DIR] [--walk-seconds S] [--out FILE]

Writes JSON (default ``benchmarks/results/graph.json``) and prints a summary:

- ``table1``: the Table 1 counts for the playground (subject 01, fixed coordinates,
  loose contact rule, as in the paper), terrain (subject 03, terrain coordinates, strict
  rule) and all-shared libraries (relative coordinates, loose and strict) at 15 frames/s.
- ``build``: graph build time (median of 3) and peak memory for the all-shared library at
  15 frames/s, each measured in a fresh process. Targets (issue 3): <= 5 s, <= 1 GB.
- ``scaling``: build time and peak memory from about 2k to 50k frames (the all-shared
  library at 30 frames/s, mirrored, and repeated to reach the larger sizes), with the
  fitted exponent of time against frames.
- ``walk``: a random walk on the playground library (default 10 minutes): transitions per
  minute, foot slide, the largest joint-angle jump at transitions against the raw data's
  99th percentile, jerk. ``walk_case4_pruned``: the same with case-4 transitions pruned.
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks._report import machine, save
from control.graph import (
    BlendSettings,
    GraphOptions,
    build_graph,
    joint_jumps,
    quality_summary,
    random_walk,
    sole_speed,
    synthesize,
)
from control.motion import Clip, Contacts, cut, default_library_path, load_library

TABLE1 = {
    "playground (01)": (["01_*"], GraphOptions(coords="fixed", contact="loose")),
    "terrain (03)": (["03_*"], GraphOptions(coords="terrain", contact="strict")),
    "all-shared, loose": (None, GraphOptions(coords="relative", contact="loose")),
    "all-shared, strict": (None, GraphOptions(coords="relative", contact="strict")),
}
PAPER = {
    "maze": [8318, 394284, 32229, None, 31469],
    "terrain": [12879, 520193, 60130, None, 59043],
    "step stool": [4576, 30058, 4964, None, 4831],
    "playground": [5971, 984152, 37209, 7091, 5458],
}


def _clips(root: Path, fps: float, mirror: bool, frames: int | None) -> list[Clip]:
    lib = load_library(root, fps=fps, mirror=mirror)
    clips = [c for c in lib.clips if c.motion.skeleton.n_joints == 31]
    if frames is None:
        return clips
    out: list[Clip] = []
    total = 0
    while total < frames:  # repeat the library when it is too small
        for c in clips:
            take = min(c.motion.n_frames, frames - total)
            if take < 2:
                break
            if take < c.motion.n_frames:
                m = cut(c.motion, 0, take)
                c = Clip(
                    m,
                    Contacts(c.contacts.states[:take], c.contacts.ankle_rest, c.contacts.toe_rest),
                    "",
                    c.labels[:take],
                    (),
                    c.source_frames[:take],
                    c.path,
                )
            out.append(c)
            total += take
        else:
            continue
        break
    return out


def one_build(
    root: Path, fps: float, mirror: bool, frames: int | None, repeat: int
) -> dict[str, Any]:
    """Build in this process (called in a fresh subprocess) and report time and memory."""
    clips = _clips(root, fps, mirror, frames)
    options = GraphOptions()
    build_graph(clips[:2], options)  # compile the numba kernels outside the timing
    rss_before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    times = []
    tracemalloc.start()
    for _ in range(repeat):
        t = time.perf_counter()
        g = build_graph(clips, options)
        times.append(time.perf_counter() - t)
    _, traced_peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return {
        "frames": g.n_frames,
        "seconds": statistics.median(times),
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "rss_before_build_mb": rss_before,
        "build_alloc_peak_mb": traced_peak / 2**20,
        "edges": g.n_edges,
        "candidates": g.report["candidates"],
    }


def _subprocess(
    root: Path, fps: float, mirror: bool, frames: int | None, repeat: int
) -> dict[str, Any]:
    cmd = [
        sys.executable,
        "-m",
        "benchmarks.bench_graph",
        str(root),
        "--one",
        json.dumps({"fps": fps, "mirror": mirror, "frames": frames, "repeat": repeat}),
    ]
    res = subprocess.run(cmd, capture_output=True, text=True, check=True)
    return dict(json.loads(res.stdout.strip().splitlines()[-1]))


def table1(root: Path) -> dict[str, Any]:
    out = {}
    for name, (patterns, options) in TABLE1.items():
        lib = load_library(root, clips=patterns)
        r = build_graph(lib.clips, options).report
        out[name] = {
            k: r[k]
            for k in (
                "frames",
                "contact",
                "likelihood",
                "similarity",
                "scc",
                "scc_frames",
                "components",
                "sigma",
                "excluded_clips",
            )
        }
        out[name]["options"] = options.to_dict()
    return out


def walk(root: Path, seconds: float, options: GraphOptions) -> dict[str, Any]:
    lib = load_library(root, clips=["01_*"])
    g = build_graph(lib.clips, options)
    n = round(seconds * g.fps)
    frames, jumps, edges = random_walk(g, n, seed=0)
    t = time.perf_counter()
    syn = synthesize(g, lib.clips, frames, jumps, edges)
    synth_s = time.perf_counter() - t
    raw = quality_summary([c.motion for c in lib.clips], [c.contacts.states for c in lib.clips])
    per_frame = np.concatenate([sole_speed(c.motion, c.contacts.states) for c in lib.clips])
    raw["foot_slide_visited"] = float(np.nanmean(per_frame[frames]))
    no_ik = synthesize(g, lib.clips, frames, jumps, edges, BlendSettings(ik=False))
    jj = joint_jumps(syn.motion)
    at = jj[jumps - 1]
    return {
        "options": options.to_dict(),
        "scc_frames": g.report["scc_frames"],
        "seconds": n / g.fps,
        "dead_ends": 0,  # random_walk raises on a dead end
        "in_component": bool(g.in_scc[frames].all()),
        "transitions": int(jumps.size),
        "transitions_per_minute": jumps.size / (n / g.fps / 60.0),
        "synthesis_seconds": synth_s,
        "raw": raw,
        "walk": quality_summary([syn.motion], [syn.states]),
        "walk_without_ik": quality_summary([no_ik.motion], [no_ik.states]),
        "transition_jump_max_deg": float(at.max()),
        "transition_jump_p99_deg": float(np.percentile(at, 99)),
        "transitions_above_raw_p99": int(np.sum(at > raw["jump_p99_deg"])),
        "unreachable_foot_frames": syn.unreachable,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", nargs="?", default=str(default_library_path()))
    ap.add_argument("--walk-seconds", type=float, default=600.0)
    ap.add_argument("--sizes", default="2000,5000,10000,20000,35000,50000")
    ap.add_argument("--out", default="benchmarks/results/graph.json")
    ap.add_argument("--one", help=argparse.SUPPRESS)
    args = ap.parse_args()
    root = Path(args.root)
    if args.one:
        spec = json.loads(args.one)
        print(
            json.dumps(one_build(root, spec["fps"], spec["mirror"], spec["frames"], spec["repeat"]))
        )
        return
    result: dict[str, Any] = {
        "machine": machine(),
        "date": time.strftime("%Y-%m-%d"),
        "paper_table1": PAPER,
    }
    result["table1"] = table1(root)
    result["build"] = _subprocess(root, 15.0, False, None, 3)
    sizes = [int(s) for s in args.sizes.split(",")]
    scaling = [_subprocess(root, 30.0, True, n, 1) for n in sizes]
    fr = np.log([s["frames"] for s in scaling])
    tm = np.log([s["seconds"] for s in scaling])
    result["scaling"] = {"points": scaling, "time_exponent": float(np.polyfit(fr, tm, 1)[0])}
    result["walk"] = walk(root, args.walk_seconds, GraphOptions())
    result["walk_case4_pruned"] = walk(root, args.walk_seconds, GraphOptions(case4="prune"))
    save(result, args.out)


if __name__ == "__main__":
    main()
