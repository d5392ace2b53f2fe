"""The whole-library window search: the fast index (faiss broad phase + exact DTW) against
brute force (issue 17).

Usage: python -m benchmarks.bench_search [LIBRARY_DIR] [--variants] [--out FILE]

On every shared clip (relative-coordinate graph, every window of the library, as the
vision interface's jumps search it), with the default multigrid bank or ``--variants``
(8 bodies and shadows per view): index build time and size, per-search time on one core
(p50, p99, max) for the committed recording's 1 s windows, and how often the index's
best is the brute-force best. Target: p99 <= 5 ms with the variants bank; the exact best
in >= 99% of queries. Beside it, the search the action vote makes when none of the best
windows shows the voted action: within the library's squat windows only.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks._report import machine, save
from control.graph import GraphOptions, build_graph
from control.motion import action_keys, default_library_path, load_library
from silhouette_bank import BankSettings, cached_bank, robust_settings, silhouette_features
from vision import ActionVote, Matcher, MatchSettings, VideoSource, best_window

RECORDING = Path("recordings/13_29_first12s_160x120.mkv")


class _Layer:
    """The matcher's search needs the graph only."""

    def __init__(self, graph: Any) -> None:
        self.graph = graph


def _within_one_action(m: Matcher, clips: Any, perf: np.ndarray) -> dict[str, Any]:
    """The search the vote makes when none of the best windows shows the voted action:
    the recording (jumping jacks) against the library's squat windows only."""
    keys = action_keys(clips)
    start = m.graph.clip_start  # (``clips`` are the graph's)
    squat = next(
        (int(start[i]) + f)
        for i, c in enumerate(clips)
        for f in range(c.motion.n_frames)
        if c.label_at(f) == "Squat"
    )
    assert keys is not None
    vote = ActionVote(1, m.n // 2)
    vote.actions, vote.voted = keys, int(keys[squat])
    only = vote.starts(m.n)
    shape, centre, starts = m.windows.tables()
    allowed = starts[only[starts]]
    t = time.perf_counter()
    m.windows.index().prepare(np.where(only, 0, -1))  # (as a performance does when it starts)
    made = (time.perf_counter() - t) * 1e3
    times, hits, total = [], 0, 0
    for end in range(m.n, perf.shape[0] + 1):
        queries = m.queries(perf[end - m.n : end])
        assert queries is not None
        t = time.perf_counter()
        st = m.settings
        got = m.windows.index().search(
            queries, st.band, st.landing.top_windows, only, recency=st.recency
        )
        times.append((time.perf_counter() - t) * 1e3)
        if end % 4 == 0:
            b = best_window(queries, shape, centre, allowed, m.n, st.band, st.recency)
            hits += bool(got and got[0][2] <= b[2] + 1e-9)
            total += 1
    return {
        "windows": int(allowed.size),
        "made_ms": round(made, 2),
        "ms": {"p50": float(np.percentile(times, 50)), "p99": float(np.percentile(times, 99))},
        "exact_best": f"{hits}/{total}",
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", nargs="?", default=str(default_library_path()))
    ap.add_argument("--variants", action="store_true", help="the bank with body variants")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    lib = load_library(args.root)
    g = build_graph(lib.clips, GraphOptions(coords="relative"))
    settings = robust_settings(BankSettings()) if args.variants else BankSettings()
    bank, _, _ = cached_bank(lib.clips, settings)
    m = Matcher(_Layer(g), bank, MatchSettings())  # type: ignore[arg-type]
    t0 = time.perf_counter()
    index = m.windows.index()
    build = time.perf_counter() - t0
    src = VideoSource(RECORDING, silhouette=True)
    feats = []
    while (f := src.read()) is not None:
        if f.index % 2 == 0:
            mask = np.asarray(f.mask, np.uint8)
            feats.append(silhouette_features(mask, descriptor=bank.settings.descriptor))
    perf = np.array(feats)
    fast, brute, hits = [], [], 0
    m.search(perf[: m.n], top=m.settings.landing.top_windows)  # compile
    for end in range(m.n, perf.shape[0] + 1):
        window = perf[end - m.n : end]
        t = time.perf_counter()
        got = m.search(window, top=m.settings.landing.top_windows)
        fast.append((time.perf_counter() - t) * 1e3)
        if end % 4 == 0:
            t = time.perf_counter()
            exact = m.search(window, exact=True)
            brute.append((time.perf_counter() - t) * 1e3)
            hits += bool(got and exact and got[0][2] <= exact[0][2] + 1e-9)
    in_graph = set(g.clip_names)  # (the graph leaves out clips of other skeletons)
    within = _within_one_action(m, [c for c in lib.clips if c.name in in_graph], perf)
    result = {
        "machine": machine(),
        "date": time.strftime("%Y-%m-%d"),
        "frames": g.n_frames,
        "bank_views": int(bank.features.shape[1]),
        "windows_indexed": index.size,
        "index": "IVF-SQ8" if index.nprobe else "flat",
        "nprobe": index.nprobe,
        "index_build_seconds": round(build, 2),
        "queries": len(fast),
        "index_ms": {
            "p50": float(np.percentile(fast, 50)),
            "p99": float(np.percentile(fast, 99)),
            "max": float(np.max(fast)),
        },
        "brute_force_ms": {"p50": float(np.median(brute)), "max": float(np.max(brute))},
        "exact_best": f"{hits}/{len(brute)}",
        "within_one_action": within,
    }
    out = args.out or f"benchmarks/results/search{'_variants' if args.variants else ''}.json"
    save(result, out)


if __name__ == "__main__":
    main()
