"""Peng et al.'s preprocess on the all-shared library: clustering and candidate paths.

Usage: python -m benchmarks.bench_transition [LIBRARY_DIR] [--out FILE]

Two-pass clustering (radius = 5, 10 and 20 times the graph's sigma, relative
coordinates) and the candidate-path precomputation (5 paths per node pair), timed
(median of 3). The paper: 0.76 s clustering and 463 s precomputation for 3,648 frames;
targets (issue 8): precomputation <= 5 s, synthesis <= 0.1 ms per frame (the chain of
jumping jack, squat, punch, walk and back, 10 times).
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks._report import machine, save
from control.motion import default_library_path, load_library
from control.transition import build_transition_graph, candidate_paths, two_pass_clusters
from control.transition._chain import Chainer


def _timed(fn: Any) -> tuple[float, Any]:
    times, out = [], None
    for _ in range(3):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times), out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", nargs="?", default=str(default_library_path()))
    ap.add_argument("--out", default="benchmarks/results/transition.json")
    args = ap.parse_args()
    lib = load_library(Path(args.root))
    chainer = Chainer(lib.clips)  # its features and sigma serve the timings below too
    feat, sigma = chainer.feat, chainer.sigma
    rows = []
    for mult in (5, 10, 20):
        t_cluster, clusters = _timed(lambda mult=mult: two_pass_clusters(feat, mult * sigma))
        t_graph, graph = _timed(lambda clusters=clusters: build_transition_graph(feat, clusters))
        t_paths, paths = _timed(lambda graph=graph: candidate_paths(graph))
        n = clusters.k
        rows.append(
            {
                "radius_sigmas": mult,
                "clusters": n,
                "edges": int(graph.edge_nodes.shape[0]),
                "transition_clips": int(graph.clip_edge.size),
                "pairs_with_paths": int(paths.pairs.shape[0]),
                "pairs": n * (n - 1),
                "paths": int(paths.cost.size),
                "cluster_seconds": t_cluster,
                "graph_seconds": t_graph,
                "paths_seconds": t_paths,
            }
        )
    from control.graph import joint_jumps

    order = ["label:JumpJack", "label:Squat", "02_05", "02_01"]
    t = time.perf_counter()
    runs = [chainer.chain(order if i % 2 == 0 else order[::-1]) for i in range(10)]
    frames = sum(r.motion.n_frames for r in runs)
    from control.graph import foot_slide, quality_summary

    states_all = np.concatenate([c.contacts.states for c in chainer.clips])

    def slide(r: Any) -> float:
        st = np.where(r.sources[:, None] >= 0, states_all[np.maximum(r.sources, 0)], False)
        return float(foot_slide(r.motion, st).mean())

    raw = quality_summary(
        [c.motion for c in chainer.clips], [c.contacts.states for c in chainer.clips]
    )
    chain = {
        "foot_slide_mean": float(np.mean([slide(r) for r in runs])),
        "raw": raw,
        "actions": order,
        "frames": frames,
        "ms_per_frame": (time.perf_counter() - t) / frames * 1e3,
        "max_joint_jump_deg": float(max(joint_jumps(r.motion).max() for r in runs)),
        "bezier_transitions": sum(r.bezier for r in runs),
    }
    # Bezier against linear interpolation where no path exists (paths withheld)
    from control.motion import qconj, qlog, qmul
    from control.transition._tgraph import CandidatePaths

    empty = CandidatePaths(
        chainer.paths.n_nodes,
        np.zeros((0, 2), dtype=np.int64),
        np.zeros(1, dtype=np.int64),
        np.zeros(0),
        np.zeros(1, dtype=np.int64),
        np.zeros(0, dtype=np.int64),
        5,
        0.0,
    )

    def end_kinks(r: Any) -> list[float]:
        """Largest per-joint change of angular velocity (deg/frame) at both ends of
        every interpolated stretch."""
        q = r.motion.quats
        out: list[float] = []
        inter = np.flatnonzero(r.sources < 0)
        if inter.size == 0:
            return out
        cuts = np.flatnonzero(np.diff(inter) != 1)
        starts = np.concatenate(([inter[0]], inter[cuts + 1]))
        stops = np.concatenate((inter[cuts], [inter[-1]]))
        for t in np.concatenate((starts, stops + 1)):
            if 2 <= t < q.shape[0] - 1:
                w0 = qlog(qmul(q[t], qconj(q[t - 1])))
                w1 = qlog(qmul(q[t + 1], qconj(q[t])))
                out.append(float(np.degrees(np.linalg.norm(w1 - w0, axis=-1)).max()))
        return out

    out_dir = Path("benchmarks/results")
    from control.motion import write_bvh
    from silhouette_bank import render_motion_video

    for name, r in (("chain", runs[0]), ("chain_reverse", runs[1])):
        write_bvh(r.motion, out_dir / f"{name}.bvh")
        render_motion_video(r.motion, out_dir / f"{name}.mp4")
    compare = {}
    for kind in ("bezier", "linear"):
        ch = Chainer(lib.clips, fallback=kind)
        ch.paths = empty
        rs = [ch.chain(order), ch.chain(order[::-1])]
        if kind == "bezier":
            write_bvh(rs[0].motion, out_dir / "chain_bezier.bvh")
            render_motion_video(rs[0].motion, out_dir / "chain_bezier.mp4")
        kinks = [k for r in rs for k in end_kinks(r)]
        compare[kind] = {
            "interpolations": sum(r.bezier for r in rs),
            "end_kink_deg_mean": float(np.mean(kinks)),
            "end_kink_deg_max": float(np.max(kinks)),
            "max_joint_jump_deg": float(max(joint_jumps(r.motion).max() for r in rs)),
        }
    result = {
        "chain": chain,
        "no_path_interpolation": compare,
        "machine": machine(),
        "date": time.strftime("%Y-%m-%d"),
        "frames": feat.n,
        "sigma": sigma,
        "runs": rows,
    }
    save(result, args.out)


if __name__ == "__main__":
    main()
