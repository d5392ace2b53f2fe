"""Higher layer: BIC curves, clusters, forest sizes, seeding, a scripted choice session, speed.

Usage: python -m benchmarks.bench_clusters [LIBRARY_DIR] [--out FILE]

For the playground (subject 01, fixed coordinates, loose contacts, the paper's setting)
and the all-shared library (same graph options) at 15 frames/s: the BIC curve over
k = 5..60 (plain and with the effective sample size; PNG), the chosen k beside the
paper's 25, cluster sizes, a contact sheet (PNG) of each cluster's most typical pose
(the frame nearest its mean), keyframe seeding against 5 random restarts (final
log-likelihood), cluster-tree statistics, the time to fit and build the forest, the
options query and most-probable-motion latencies (p50/p99 over 500 random frames), and a
scripted 2-minute choice session on the playground. Targets (issue 4): fit + forest for
all-shared <= 60 s; options <= 1 ms p99; most probable motion <= 5 ms p99.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks._report import machine, save
from benchmarks.plots import bic_curve, pose_sheet
from control.avatar import Avatar
from control.choice import offer
from control.clusters import build_higher_layer, fit_mixture
from control.graph import FrameData, GraphOptions, build_graph
from control.motion import default_library_path, load_library, write_bvh

OUT = Path("benchmarks/results")


def run_library(root: Path, name: str, patterns: list[str] | None) -> dict[str, Any]:
    lib = load_library(root, clips=patterns)
    g = build_graph(lib.clips, GraphOptions())
    t = time.perf_counter()
    layer = build_higher_layer(g, lib.clips)
    fit_and_forest = time.perf_counter() - t
    c = layer.clustering
    bic_curve(layer.curve, f"{name}: BIC (chosen k = {c.k}; paper 25)", OUT / f"bic_{name}.png")
    # the frame nearest each cluster mean, drawn
    by_name = {cl.name: cl for cl in lib.clips}
    motions, frames, titles = [], [], []
    for k in range(c.k):
        members = np.flatnonzero(c.labels == k)
        if members.size == 0:
            continue
        d = ((layer.states[members] - c.means[k]) ** 2).sum(axis=1)
        f = int(members[np.argmin(d)])
        clip, i = g.locate(f)
        motions.append(by_name[clip].motion)
        frames.append(i)
        titles.append(f"{k}: {clip} {i / g.fps:.1f}s (n={members.size})")
    pose_sheet(motions, frames, titles, OUT / f"clusters_{name}.png")
    # seeding: keyframes vs random restarts at the chosen k and at 25
    seeding = {}
    for k in sorted({c.k, 25}):
        kf = fit_mixture(layer.states, k, seeding="keyframes")
        rr = fit_mixture(layer.states, k, seeding="random", restarts=5)
        seeding[str(k)] = {"keyframes": kf.log_likelihood, "random_5_restarts": rr.log_likelihood}
    # latencies
    data = FrameData(g, lib.clips)
    rng = np.random.default_rng(0)
    picks = rng.choice(np.flatnonzero(g.in_scc), 500)
    opt_ms, mpm_ms, n_opts = [], [], []
    for f in picks:
        avatar = Avatar(g, lib.clips, start=int(f))
        t = time.perf_counter()
        opts = offer(layer, avatar, data, lookahead=(0.0, 6.0))
        opt_ms.append((time.perf_counter() - t) * 1e3)
        n_opts.append(len(opts))
        tree = layer.forest.tree(int(f))
        leaf = int(rng.choice(tree.leaves()))
        t = time.perf_counter()
        layer.motion_to(int(f), leaf)
        mpm_ms.append((time.perf_counter() - t) * 1e3)
    return {
        "frames": g.n_frames,
        "graph_frames_in_component": int(g.in_scc.sum()),
        "fit_and_forest_seconds": fit_and_forest,
        "forest_seconds": layer.forest.report["seconds"],
        "chosen_k": c.k,
        "paper_k": 25,
        "curve": layer.curve,
        "cluster_sizes": c.sizes().tolist(),
        "seeding_log_likelihood": seeding,
        "forest": layer.forest.report,
        "frames_without_tree_in_component": int(np.sum(g.in_scc & (layer.forest.tree_of < 0))),
        "empty_trees": int(sum(t.size == 0 for t in layer.forest.trees)),
        "options_ms": {
            "p50": float(np.percentile(opt_ms, 50)),
            "p99": float(np.percentile(opt_ms, 99)),
        },
        "options_offered": np.bincount(n_opts, minlength=5).tolist(),
        "most_probable_motion_ms": {
            "p50": float(np.percentile(mpm_ms, 50)),
            "p99": float(np.percentile(mpm_ms, 99)),
        },
        "_layer": layer,
        "_lib": lib,
    }


def scripted_session(res: dict[str, Any], seconds: float = 120.0) -> dict[str, Any]:
    layer, lib = res["_layer"], res["_lib"]
    g = layer.graph
    data = FrameData(g, lib.clips)
    avatar = Avatar(g, lib.clips, seed=0)
    choices = [1, 2, 3, 4, 1, 3]
    taken = reached = 0
    while avatar.time < seconds:
        opts = offer(layer, avatar, data, lookahead=(0.0, 6.0))
        if not opts:  # nothing to choose within the look-ahead yet
            avatar.advance(0.5)
            continue
        o = opts[min(choices[taken % len(choices)], len(opts)) - 1]
        avatar.take(o.frames, o.edges)
        while avatar.busy:
            avatar.step()
        taken += 1
        reached += int(layer.labels[avatar.frame] == o.cluster)
        avatar.advance(0.5)  # half a second on its own between choices
    syn = avatar.motion()
    write_bvh(syn.motion, OUT / "choice_session.bvh")
    return {
        "seconds": avatar.time,
        "actions": taken,
        "reached": reached,
        "transitions": int(syn.jumps.size),
        "bvh": str(OUT / "choice_session.bvh"),
        "in_component": bool(g.in_scc[avatar.history()[0]].all()),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", nargs="?", default=str(default_library_path()))
    ap.add_argument("--out", default=str(OUT / "clusters.json"))
    args = ap.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    root = Path(args.root)
    result: dict[str, Any] = {
        "machine": machine(),
        "date": time.strftime("%Y-%m-%d"),
    }
    play = run_library(root, "playground", ["01_*"])
    result["session"] = scripted_session(play)
    result["playground"] = {k: v for k, v in play.items() if not k.startswith("_")}
    every = run_library(root, "all_shared", None)
    result["all_shared"] = {k: v for k, v in every.items() if not k.startswith("_")}
    save(result, args.out)


if __name__ == "__main__":
    main()
