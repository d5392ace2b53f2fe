"""The sketch interface (Lee et al. §5.2, issue 7): following a drawn path.

Usage: python -m benchmarks.bench_sketch [LIBRARY_DIR] [--out FILE]

- Maze run: the walking clips (02_01-02_03, 03_*; relative coordinates, as the paper's
  maze) follow ``benchmarks/sketch/maze_path.json`` through ``maze.json``, with eq. 8
  (c = 0.5 m) and the same search without the facing term (c = 0): whether the sketch is
  followed, mean and max deviation of the root from the sketch, nearest obstacle; and the
  paper's first approach on the same maze (the cluster-tree action whose root path is
  nearest the sketch by DTW, default higher layer): the same figures and the time per
  choice. Writes ``results/sketch_maze.png``.
- Terrain run: the terrain clips (03_*; terrain coordinates on the block grid found
  under their feet) follow ``terrain_path.json`` over ``terrain.json`` (blocks up to
  three levels high), with and without the facing term: deviation, and the foot-height
  error at planted frames of the synthesized motion (toe above the top of the block under
  the foot). Writes ``results/sketch_terrain.png``.
- Planning speed on the all-shared library (every 31-joint clip, relative coordinates) in
  an open field, along a 40 m zig-zag drawn in 2 m segments while the avatar moves:
  seconds of motion planned per second of compute (target >= 20x), and the time from a
  newly drawn segment to the first frames planned toward it, p50 / p99 / max (target
  <= 50 ms).
"""

from __future__ import annotations

import argparse
import itertools
import time
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks._report import machine, save
from control.clusters import build_higher_layer
from control.graph import GraphOptions, build_graph, terrain_options
from control.motion import default_library_path, load_library
from control.sketch import (
    SketchSettings,
    SketchTracker,
    draw_top_down,
    path_deviation,
    read_environment,
    read_sketch,
)

HERE = Path(__file__).resolve().parent
WALKS = ["02_01", "02_02", "02_03", "03_01", "03_02", "03_03", "03_04"]


def maze(root: Path, png: Path) -> dict[str, Any]:
    lib = load_library(root, clips=WALKS)
    g = build_graph(lib.clips, GraphOptions(coords="relative"))
    sketch = read_sketch(HERE / "sketch" / "maze_path.json")
    env = read_environment(HERE / "sketch" / "maze.json")
    out: dict[str, Any] = {"library": WALKS, "frames": g.n_frames, "edges": g.n_edges}
    roots = {}
    for name, c in (("eq. 8 (c = 0.5 m)", 0.5), ("no facing term (c = 0)", 0.0)):
        t = SketchTracker(g, lib.clips, sketch, env, SketchSettings(c=c))
        t0 = time.perf_counter()
        t.run(120.0)
        out[name] = t.summary(time.perf_counter() - t0)
        roots[name] = t.root_path()
    # the first approach: actions of the cluster trees chosen by DTW
    t0 = time.perf_counter()
    layer = build_higher_layer(g, lib.clips)
    out["higher_layer"] = {
        "clusters": layer.clustering.k,
        "build_seconds": round(time.perf_counter() - t0, 1),
        "tree_nodes_median": layer.forest.report["nodes"]["median"],
        "tree_horizon_seconds_median": layer.forest.report["horizon_seconds"]["median"],
    }
    name = "first approach: actions by DTW"
    t = SketchTracker(g, lib.clips, sketch, env, SketchSettings(), layer=layer)
    t0 = time.perf_counter()
    t.run(120.0)
    out[name] = t.summary(time.perf_counter() - t0)
    ms = np.array(t.step_seconds) * 1e3
    out[name]["choices"] = len(t.step_seconds)
    out[name]["actions_compared_mean"] = round(float(np.mean(t.expansions)), 1)
    out[name]["choice_ms"] = {
        "p50": round(float(np.percentile(ms, 50)), 1),
        "p99": round(float(np.percentile(ms, 99)), 1),
    }
    roots[name] = t.root_path()
    draw_top_down(png, sketch, env, roots)
    return out


def terrain(root: Path, png: Path) -> dict[str, Any]:
    lib = load_library(root, clips=["03_*"])
    env = read_environment(HERE / "sketch" / "terrain.json")
    assert env.terrain is not None
    sketch = read_sketch(HERE / "sketch" / "terrain_path.json")
    options, cap = terrain_options(lib.clips, env.terrain.block)
    g = build_graph(lib.clips, options)
    out: dict[str, Any] = {
        "library": "03_*",
        "frames": g.n_frames,
        "edges": g.n_edges,
        "captured_terrain": cap.to_dict(),
    }
    roots = {}
    for name, c in (("eq. 8 (c = 0.5 m)", 0.5), ("no facing term (c = 0)", 0.0)):
        t = SketchTracker(g, lib.clips, sketch, env, SketchSettings(c=c), captured=cap)
        t0 = time.perf_counter()
        t.run(60.0)
        out[name] = t.summary(time.perf_counter() - t0)
        out[name]["feet"] = t.terrain_report(t.motion())
        roots[name] = t.root_path()
    draw_top_down(png, sketch, env, roots)
    return out


def speed(root: Path) -> dict[str, Any]:
    everything = load_library(root)
    clips = [c for c in everything.clips if c.motion.skeleton.n_joints == 31]
    g = build_graph(clips, GraphOptions(coords="relative"))
    # a zig-zag drawn 2 m at a time
    corners = np.array([[0.0, 0.0]] + [[4.0 * (i % 2), 4.0 * (i + 1)] for i in range(10)])
    pts = np.concatenate([np.linspace(a, b, 3)[1:] for a, b in itertools.pairwise(corners)])
    t = SketchTracker(g, clips, np.vstack((corners[:1], pts[:1])))
    respond = []
    compute = 0.0
    for k in range(1, len(pts)):
        # the avatar moves on while the next segment is drawn: finish the current goals
        while not t.done:
            t0 = time.perf_counter()
            t.step()
            compute += time.perf_counter() - t0
        if t.stuck:
            break
        t0 = time.perf_counter()
        t.extend(pts[k : k + 1])
        t.step()
        took = time.perf_counter() - t0
        respond.append(took)
        compute += took
    while not t.done:
        t0 = time.perf_counter()
        t.step()
        compute += time.perf_counter() - t0
    ms = np.array(respond) * 1e3
    sketch = np.vstack((corners[:1], pts))
    dev = path_deviation(t.root_path(), sketch)
    return {
        "library_frames": g.n_frames,
        "edges": g.n_edges,
        "sketch_m": float(np.linalg.norm(np.diff(sketch, axis=0), axis=1).sum()),
        "followed": bool(t.goal >= len(t.goals) and not t.stuck),
        "motion_seconds": round((len(t.frames) - 1) / g.fps, 2),
        "compute_seconds": round(compute, 3),
        "realtime_factor": round((len(t.frames) - 1) / g.fps / compute, 1),
        "respond_ms": {
            "p50": round(float(np.percentile(ms, 50)), 2),
            "p99": round(float(np.percentile(ms, 99)), 2),
            "max": round(float(ms.max()), 2),
            "segments": int(ms.size),
        },
        "deviation_mean_m": round(float(dev.mean()), 3),
        "deviation_max_m": round(float(dev.max()), 3),
        "expansions_per_step_mean": round(float(np.mean(t.expansions)), 1),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", nargs="?", default=str(default_library_path()))
    ap.add_argument("--out", default="benchmarks/results/sketch.json")
    args = ap.parse_args()
    root = Path(args.root)
    result = {
        "machine": machine(),
        "date": time.strftime("%Y-%m-%d"),
        "maze": maze(root, Path(args.out).with_name("sketch_maze.png")),
        "speed_all_shared": speed(root),
        "terrain": terrain(root, Path(args.out).with_name("sketch_terrain.png")),
    }
    save(result, args.out)


if __name__ == "__main__":
    main()
