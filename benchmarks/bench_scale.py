"""Past one machine (issue 21): how each build step grows with the library, up to 500,000
frames.

Usage: python -m benchmarks.bench_scale [LIBRARY_DIR] [--sizes 50000,200000,500000]
       [--steps graph,layer,bank,search,open] [--timeout 900] [--out FILE]
       [--cluster local:2] [--merge]

The synthetic library: every shared clip with the exercise subject's 31 joints, loaded
at 15, 16, 17, ... frames/s and each played back at 15 frames/s (so a clip loaded at
``f`` frames/s is the same motion slowed to ``15 / f`` of its tempo: new frames, new
velocities), each also mirrored left for right, joined in that order until ``N`` frames
(the last clip cut). Each step runs in a fresh process (its time, and its peak resident
memory, which includes the library's):

- ``graph``: ``build_graph`` with the options ``mimic perform`` builds it with (the
  default options in relative root coordinates), each job's pairs kept in a folder as
  the cache's build keeps them (so that a stopped build resumes);
- ``layer``: the higher layer as ``mimic perform`` builds it (2 s trees), on that graph;
- ``bank``: the default 18-view bank of the library's first 1,000 frames rendered by one
  worker, scaled to ``N`` frames per worker (the shards are independent), and the bank's
  size on disk at ``N`` frames (float32, and float16);
- ``search``: the whole-library window search (the faiss index and exact DTW) over the
  default bank's features of the shared library tiled to ``N`` frames (mirrored on every
  other copy), queried with the committed recording's 1 s windows: index build time and
  p50/p99 per query (its speed, not its accuracy: the tiles repeat);
- ``open``: the vision half of a ``perform`` start-up on a bank of ``N`` frames (tiled
  like ``search``'s, written to disk as ``build_bank`` writes one): opening the bank, its
  shape statistics, window tables and index, and the first search, cold and warm
  (``benchmarks/_scale_open.py``);

and a plot of each against frames (beside ``--out``: ``benchmarks/results/scale.png``),
and each measure's growth exponent with the frames (``growth``: 1 linear, 2 quadratic).
``--merge --steps ''`` runs nothing and writes the growth and the plot of what ``--out``
holds.
The library is ``../shared/mocap`` when it is beside the checkout (else the embedded one,
said on stderr; name it when running from a copy elsewhere). A step that passes
``--timeout`` seconds or fails (memory) is recorded as such, and a step that passed the
time limit is not run on the larger sizes.
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks._report import machine, save
from control.graph import GraphOptions
from control.jobs import CLUSTER_ENV, cluster_address
from control.motion import (
    EMBEDDED_LIBRARY,
    Clip,
    Contacts,
    cut,
    default_library_path,
    load_library,
)

HERE = Path(__file__).resolve().parent
#: the graph ``mimic perform`` builds: the default options in relative root coordinates
#: (``vision.VISION_COORDS``; ``mimic/run_args.py``)
PERFORM_GRAPH = GraphOptions(coords="relative")
RECORDING = HERE.parent / "recordings" / "13_29_first12s_160x120.mkv"


def synthetic_clips(root: Path, frames: int) -> list[Clip]:
    """The synthetic library of ``frames`` frames (see the module)."""
    out: list[Clip] = []
    total = 0
    for fps in itertools.count(15):
        for mirror in (False, True):
            lib = load_library(root, fps=float(fps), mirror=mirror)
            for c in lib.clips:
                if c.motion.skeleton.n_joints != 31:
                    continue
                take = min(c.motion.n_frames, frames - total)
                if take < 8:
                    return out
                m = cut(c.motion, 0, take)
                tag = f"{c.name}@{fps}{'m' if mirror else ''}"
                m = dataclasses.replace(m, fps=15.0, name=tag)
                st = c.contacts
                out.append(
                    dataclasses.replace(
                        c,
                        motion=m,
                        contacts=Contacts(st.states[:take], st.ankle_rest, st.toe_rest),
                        labels=c.labels[:take],
                        source_frames=c.source_frames[:take],
                    )
                )
                total += take
    return out


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _status_mb(field: str) -> float | None:
    """``VmRSS`` or ``VmHWM`` (the peak since ``_reset_peak``) of this process, in MB;
    ``None`` where ``/proc`` does not say (not Linux)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith(field + ":"):
                return float(line.split()[1]) / 1024.0
    except OSError:
        return None
    return None


def _reset_peak() -> bool:
    """Start this process's peak memory again from now (Linux's ``clear_refs``), so
    that a step's own peak is measured apart from what came before it."""
    try:
        Path("/proc/self/clear_refs").write_text("5")
    except OSError:
        return False
    return True


def _graph(root: Path, n: int) -> dict[str, Any]:
    from control.graph import build_graph

    clips = synthetic_clips(root, n)
    build_graph(clips[:2], PERFORM_GRAPH)  # the kernels compiled outside the timing
    before = _peak_mb()
    with tempfile.TemporaryDirectory() as tmp:  # (each job kept, as the cache builds it)
        t = time.perf_counter()
        g = build_graph(clips, PERFORM_GRAPH, work=Path(tmp) / "parts")
        took = time.perf_counter() - t
    search = g.report["seconds"]["search"]
    return {
        "frames": g.n_frames,
        "coords": g.options.coords,
        "seconds": round(took, 2),
        "peak_rss_mb": round(_peak_mb(), 1),
        "rss_before_mb": round(before, 1),
        "edges": g.n_edges,
        "likely_pairs": g.report["likelihood"],  # (held until the similarity rule)
        "candidates": g.report["candidates"],  # (the lower bound's)
        "jobs": g.report["jobs"],
        "parts_seconds": g.report["seconds"],
        **_spread(took, search),
    }


def _spread(took: float, jobs_s: float) -> dict[str, Any]:
    """On a cluster (``--cluster``): its address, and the step's time extrapolated to 8
    workers from its jobs' time ``jobs_s``: the rest as it was, the jobs' seconds times
    the workers / 8 (each worker as fast as these, the scheduler not limiting)."""
    address = cluster_address()
    if address is None:
        return {}
    workers = int(address.split(":")[1]) if address.startswith("local:") else None
    out: dict[str, Any] = {"cluster": address, "jobs_seconds": round(jobs_s, 2)}
    if workers:
        out["extrapolated_8_workers_seconds"] = round(took - jobs_s + jobs_s * workers / 8, 1)
    return out


def _layer(root: Path, n: int) -> dict[str, Any]:
    from control.clusters import LayerSettings, build_higher_layer
    from control.graph import build_graph

    clips = synthetic_clips(root, n)
    g = build_graph(clips, PERFORM_GRAPH)
    before = _peak_mb()
    t = time.perf_counter()
    layer = build_higher_layer(g, clips, LayerSettings(bound_seconds=2.0))
    took = time.perf_counter() - t
    forest_s = float(layer.forest.report["seconds"])
    return {
        "frames": g.n_frames,
        "coords": g.options.coords,
        "seconds": round(took, 2),
        "peak_rss_mb": round(_peak_mb(), 1),
        "rss_before_mb": round(before, 1),
        "clusters": layer.clustering.k,
        "trees": layer.forest.report["trees"],
        "lazy": layer.forest.report["lazy"],  # (trees built on first use: none here)
        "forest_seconds": round(forest_s, 2),
        **_spread(took, forest_s),  # (the trees' jobs; the BIC search's fits not counted)
    }


def _bank(root: Path, n: int) -> dict[str, Any]:
    from silhouette_bank import BankSettings, build_bank

    clips = synthetic_clips(root, 1000)
    settings = BankSettings()
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()  # the shards alone: the metric's renders are a fixed cost
        plain = dataclasses.replace(settings, metric=0)
        bank = build_bank(clips, plain, Path(tmp) / "b", workers=1)
        took = time.perf_counter() - t
        size = sum(p.stat().st_size for p in (Path(tmp) / "b").iterdir() if p.is_file())
        half = bank.features.nbytes  # (stored at half precision: float32 doubles them)
        t = time.perf_counter()
        build_bank(clips, settings, Path(tmp) / "m", workers=1)
        metric = time.perf_counter() - t - took
    per_frame = took / bank.n_frames
    return {
        "frames": n,
        "sample_frames": bank.n_frames,
        "views": settings.n_views,
        "seconds_per_worker": round(per_frame * n, 1),
        "metric_seconds_fixed": round(metric, 1),
        "silhouettes_per_s_per_worker": round(bank.n_frames * settings.n_views / took, 1),
        "size_gb_float16": round(size / bank.n_frames * n / 1e9, 2),
        "size_gb_float32": round((size + half) / bank.n_frames * n / 1e9, 2),
        "peak_rss_mb": round(_peak_mb(), 1),
    }


def _search(root: Path, n: int) -> dict[str, Any]:
    from silhouette_bank import BankSettings, cached_bank, silhouette_features
    from vision import (
        MatchSettings,
        VideoSource,
        WindowIndex,
        performer_queries,
        shape_stats,
        window_tables,
    )

    lib = load_library(root)
    clips = [c for c in lib.clips if c.motion.skeleton.n_joints == 31]
    bank, _, _ = cached_bank(clips, BankSettings())
    desc = bank.settings.features
    reps = -(-n // bank.n_frames)
    features = np.empty((n, *bank.features.shape[1:]), dtype=np.float32)  # (no copies)
    moves = np.empty((n, *bank.root_motion.shape[1:]), dtype=np.float32)
    for i in range(reps):
        a, b = i * bank.n_frames, min(n, (i + 1) * bank.n_frames)
        tile = bank.features if i % 2 == 0 else desc.mirror(bank.features)
        features[a:b] = tile[: b - a]
        moves[a:b] = (bank.root_motion * (1 if i % 2 == 0 else [-1, 1]))[: b - a]
    big = dataclasses.replace(
        bank,
        features=features,
        root_motion=moves,
        clip_start=np.unique(
            np.concatenate([bank.clip_start + i * bank.n_frames for i in range(reps)] + [[n]]).clip(
                0, n
            )
        ),
    )
    del features, moves
    st = MatchSettings()
    length = round(st.window * 15.0)
    mean, proj = shape_stats(bank)
    cs = big.clip_start
    starts = np.concatenate([np.arange(a, b - length + 1) for a, b in itertools.pairwise(cs)])
    rss_before = _status_mb("VmRSS")
    reset = _reset_peak()
    t = time.perf_counter()
    shape, centre = window_tables(big, np.arange(n), cs, mean, proj, st.centre_weight)
    index = WindowIndex(shape, centre, starts.astype(np.int64), length)
    build = time.perf_counter() - t
    build_peak = _status_mb("VmHWM") if reset else None
    src = VideoSource(RECORDING, silhouette=True)
    feats = []
    while (f := src.read()) is not None:
        if f.index % 2 == 0:
            feats.append(silhouette_features(np.asarray(f.mask, np.uint8), descriptor=desc.name))
    perf = np.array(feats)
    times = []
    for end in range(length, perf.shape[0] + 1):
        qs = performer_queries(perf[end - length : end], desc, mean, proj, st.centre_weight)
        t = time.perf_counter()
        index.search(qs, st.band, st.landing.top_windows)
        times.append((time.perf_counter() - t) * 1e3)
    return {
        "frames": n,
        "windows": index.size,
        "index": "IVF-SQ8" if index.nprobe else "flat",
        "build_seconds": round(build, 1),
        "index_seconds": {k: round(v, 2) for k, v in index.seconds.items()},
        "query_ms_p50": round(float(np.median(times[1:])), 2),
        "query_ms_p99": round(float(np.percentile(times[1:], 99)), 2),
        "peak_rss_mb": round(_peak_mb(), 1),
        # the tables and the index built beside the bank (the bank, tiled to n frames,
        # is what the process held before: ``rss_before_build_mb``)
        "rss_before_build_mb": None if rss_before is None else round(rss_before, 1),
        "build_peak_rss_mb": None if build_peak is None else round(build_peak, 1),
        # (its jobs: the summaries', and the encoding's for the trained lists)
        **_spread(build, index.seconds.get("jobs", 0.0) + index.seconds.get("encode", 0.0)),
    }


def _open(root: Path, n: int) -> dict[str, Any]:
    from benchmarks._scale_open import open_step

    return open_step(root, n, RECORDING)


STEPS = {"graph": _graph, "layer": _layer, "bank": _bank, "search": _search, "open": _open}


def _run(root: Path, step: str, n: int, timeout: float) -> dict[str, Any]:
    cmd = [sys.executable, "-m", "benchmarks.bench_scale", str(root), "--one", f"{step}:{n}"]
    t = time.perf_counter()
    try:
        res = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"frames": n, "failed": f"did not finish in {timeout:.0f} s"}
    if res.returncode != 0:
        tail = (res.stderr or res.stdout).strip().splitlines()[-1:] or [""]
        return {"frames": n, "failed": f"exit {res.returncode}: {tail[0][:200]}"}
    out = dict(json.loads(res.stdout.strip().splitlines()[-1]))
    out["wall_seconds"] = round(time.perf_counter() - t, 1)
    return out


#: the measures whose growth with the library's frames is reported (``_growth``)
GROWTH = {
    "graph": ("seconds", "peak_rss_mb"),
    "layer": ("seconds", "peak_rss_mb"),
    "bank": ("seconds_per_worker",),
    "search": ("build_seconds", "build_peak_rss_mb", "query_ms_p99"),
    "open": ("warm_seconds",),
}


def _growth(result: dict[str, Any]) -> dict[str, dict[str, dict[str, float]]]:
    """Each measure's growth exponent: ``log(y2 / y1) / log(n2 / n1)`` between each pair
    of sizes measured in a row, and over the smallest and largest of 50k and up (1:
    linear in the frames; 2: quadratic)."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    for step, keys in GROWTH.items():
        for key in keys:
            pts = sorted(
                (int(p["frames"]), float(p[key]))
                for p in result["steps"].get(step, [])
                if isinstance(p.get(key), (int, float)) and p[key] > 0 and p["frames"] >= 50_000
            )
            if len(pts) < 2:
                continue
            pairs = [*itertools.pairwise(pts)]
            if len(pts) > 2:
                pairs.append((pts[0], pts[-1]))
            out.setdefault(step, {})[key] = {
                f"{a[0] // 1000}k-{b[0] // 1000}k": round(
                    float(np.log(b[1] / a[1]) / np.log(b[0] / a[0])), 2
                )
                for a, b in pairs
            }
    return out


def _plot(result: dict[str, Any], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for step, key, ax in (
        ("graph", "seconds", 0),
        ("layer", "seconds", 0),
        ("bank", "seconds_per_worker", 0),
        ("search", "build_seconds", 0),
        ("search", "query_ms_p99", 1),
        ("open", "warm_seconds", 0),
        ("graph", "peak_rss_mb", 1),
        ("layer", "peak_rss_mb", 1),
    ):
        pts = [p for p in result["steps"].get(step, []) if key in p]
        if pts:
            axes[ax].loglog(
                [p["frames"] for p in pts], [p[key] for p in pts], "o-", label=f"{step} {key}"
            )
    axes[0].set_title("time (s) against frames")
    axes[1].set_title("memory (MB) and search p99 (ms) against frames")
    for a in axes:
        a.set_xlabel("frames")
        a.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", nargs="?", default=str(default_library_path()))
    ap.add_argument("--sizes", default="50000,200000,500000")
    ap.add_argument("--steps", default="graph,layer,bank,search,open")
    ap.add_argument("--timeout", type=float, default=900.0)
    ap.add_argument("--out", default="benchmarks/results/scale.json")
    ap.add_argument(
        "--merge",
        action="store_true",
        help="keep the results already in --out of the other steps and sizes",
    )
    ap.add_argument(
        "--cluster",
        help="run the graph's, the layer's and the window index's jobs on this Dask "
        "cluster (local:2: two worker processes here); each result says it, and its time "
        "extrapolated to 8 workers from its jobs' time",
    )
    ap.add_argument("--one", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.cluster:
        os.environ[CLUSTER_ENV] = args.cluster  # (read by each step's own process too)
    root = Path(args.root)
    if args.one:
        step, n = args.one.split(":")
        print(json.dumps(STEPS[step](root, int(n))))
        return
    sizes = [int(v) for v in args.sizes.split(",")]
    result: dict[str, Any] = {"machine": machine(), "date": time.strftime("%Y-%m-%d")}
    result["steps"] = {}
    if args.merge and Path(args.out).is_file():  # (each step says its own date)
        result["steps"] = json.loads(Path(args.out).read_text())["steps"]
    if root.resolve() == EMBEDDED_LIBRARY.resolve():
        print(
            f"note: measuring synthetic copies of the embedded library ({root}), not of "
            "../shared/mocap (not found beside this checkout): name the library to compare "
            "with the README's figures",
            file=sys.stderr,
        )
    result["library"] = str(root)
    for step in [s for s in args.steps.split(",") if s]:  # (--merge --steps '': growth)
        # --merge: the sizes not run now keep their earlier results
        result["steps"][step] = [
            e for e in result["steps"].get(step, []) if e.get("frames") not in sizes
        ]
        too_long = False
        for n in sizes:
            if too_long:  # a smaller library already passed the time limit
                got = {
                    "frames": n,
                    "failed": f"not run: a smaller size passed {args.timeout:.0f} s",
                }
            else:
                got = _run(root, step, n, args.timeout)
                got["date"] = time.strftime("%Y-%m-%d %H:%M")
                too_long = str(got.get("failed", "")).startswith("did not finish")
            result["steps"][step].append(got)
            result["steps"][step].sort(key=lambda e: int(e.get("frames", 0)))
            print(step, json.dumps(got), flush=True)
            save(result, args.out)  # (so far, should a later step be stopped)
    result["growth"] = _growth(result)
    _plot(result, Path(args.out).with_suffix(".png"))
    save(result, args.out)


if __name__ == "__main__":
    main()
