"""Building, storing and walking the graph on real clips."""

from __future__ import annotations

import math
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from control.graph import (
    GraphFileError,
    GraphOptions,
    MotionGraph,
    build_graph,
    cached_graph,
    case4,
    frame_features,
    load_graph,
    pair_distances,
    random_walk,
    save_graph,
)
from control.graph._prune import contact_groups, local_maxima
from control.motion import Library


@pytest.mark.parametrize(
    "options",
    [
        GraphOptions(),
        GraphOptions(coords="relative", contact="strict", threshold=0.02),
        GraphOptions(coords="terrain", contact="loose", similarity=False),
    ],
)
def test_build_equals_brute_force(walk_lib: Library, options: GraphOptions) -> None:
    g = build_graph(walk_lib.clips, options)
    feat = frame_features(walk_lib.clips, options.coords)
    n = feat.n
    a = np.repeat(np.arange(n), n)
    b = np.tile(np.arange(n), n)
    d, _ = pair_distances(feat, a, b, options.nu, options.block)
    allowed = np.zeros((n, n), dtype=bool)
    for rows, cols in contact_groups(feat.states, feat.clip_start, options.contact):
        allowed[np.ix_(rows, cols)] = True
    np.fill_diagonal(allowed, False)
    dmax = g.sigma * math.log(1.0 / options.threshold)
    ok = allowed.ravel() & (d <= dmax)
    assert g.report["contact"] == int(allowed.sum())
    assert g.report["likelihood"] == int(ok.sum())
    ea, eb, ed = a[ok], b[ok], d[ok]
    if options.use_similarity:
        keep = local_maxima(ea, eb, ed, feat.clip_start)
        ea, eb, ed = ea[keep], eb[keep], ed[keep]
        assert g.report["similarity"] == ea.size
    else:
        assert g.report["similarity"] is None
    inside = g.in_scc[ea] & g.in_scc[eb + 1]
    got = set(zip(g.src.tolist(), (g.dst - 1).tolist(), strict=True))
    assert got == set(zip(ea[inside].tolist(), eb[inside].tolist(), strict=True))


def test_blocks_and_chunks_give_the_same_graph(
    medium_lib: Library, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The likely pairs measured a few at a time and the local maxima looked up in small
    chunks (as at 500,000 frames) give the graph of one pass, array for array."""
    from control.graph import _pairs, _prune

    options = GraphOptions(coords="relative")
    whole = build_graph(medium_lib.clips, options)
    monkeypatch.setattr(_pairs, "_MEASURE", 997)
    monkeypatch.setattr(_prune, "_CHUNK", 613)
    parts = build_graph(medium_lib.clips, options)
    assert whole.n_edges > 100 and parts.report["likelihood"] > 10 * 997
    for name in ("src", "dst", "dist", "align", "in_scc"):
        assert np.array_equal(getattr(whole, name), getattr(parts, name)), name
    counts = ("contact", "candidates", "likelihood", "similarity", "scc")
    assert {k: whole.report[k] for k in counts} == {k: parts.report[k] for k in counts}


def test_the_kd_tree_broad_phase_gives_the_graph_of_the_blocked_search(
    medium_lib: Library, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Every contact group searched through a KD-tree of its columns' principal
    directions (``BroadPhase``, as past 2,048 x 2,048 frames), a few rows at a time,
    gives the graph of the blocked matrix products, array for array."""
    from control.graph import _broad

    options = GraphOptions(coords="relative")
    monkeypatch.setattr(_broad, "BROAD_MIN_PAIRS", 1 << 62)
    blocked = build_graph(medium_lib.clips, options)
    made: list[int] = []
    real = _broad.BroadPhase.of.__func__  # type: ignore[attr-defined]

    def counted(cls: type, x: np.ndarray, cols: np.ndarray, *args: Any) -> Any:
        made.append(len(cols))
        return real(cls, x, cols, *args)

    monkeypatch.setattr(_broad.BroadPhase, "of", classmethod(counted))
    monkeypatch.setattr(_broad, "BROAD_MIN_PAIRS", 1)
    monkeypatch.setattr(_broad, "_ROWS", 101)
    tree = build_graph(medium_lib.clips, options)
    assert len(made) > 1 and max(made) > 500
    assert blocked.n_edges > 100
    for name in ("src", "dst", "dist", "align", "in_scc"):
        assert np.array_equal(getattr(blocked, name), getattr(tree, name)), name
    # the same lower bound, in float64 instead of float32 products: at most a few
    # candidates at its rounding's edge differ
    assert tree.report["likelihood"] == blocked.report["likelihood"]
    assert abs(tree.report["candidates"] - blocked.report["candidates"]) <= max(
        10, 1e-4 * blocked.report["candidates"]
    )
    # dense blocks cut into runs of at most about 3,000 pairs, by counting one row in 3
    monkeypatch.setattr(_broad, "_ROWS", 1024)
    monkeypatch.setattr(_broad, "_MAX_PAIRS", 3000)
    monkeypatch.setattr(_broad, "_STRIDE", 3)
    runs: list[int] = []
    real_split = _broad.BroadPhase._split

    def split(self: Any, x: np.ndarray, rb: np.ndarray, radius: float) -> Any:
        got = real_split(self, x, rb, radius)
        assert np.array_equal(np.concatenate(got), rb) and min(r.size for r in got) > 0
        runs.append(len(got))
        return got

    monkeypatch.setattr(_broad.BroadPhase, "_split", split)
    cut = build_graph(medium_lib.clips, options)
    assert max(runs) > 3
    for name in ("src", "dst", "dist", "align", "in_scc"):
        assert np.array_equal(getattr(blocked, name), getattr(cut, name)), name
    assert cut.report["candidates"] == tree.report["candidates"]


def test_a_graph_built_on_a_two_worker_cluster_is_the_local_build(
    medium_lib: Library, monkeypatch: pytest.MonkeyPatch, dask_cluster: str
) -> None:
    """The likely pairs searched and measured as jobs on a local Dask cluster of two
    workers (blocks of rows, the frame features and the groups' KD-trees sent once)
    give the local graph."""
    from control.graph import _broad, _pairs

    monkeypatch.setattr(_broad, "BROAD_MIN_PAIRS", 1 << 18)  # the larger groups' trees
    options = GraphOptions(coords="relative")
    here = build_graph(medium_lib.clips, options)
    jobs: list[int] = []
    real = _pairs.run_jobs

    def counted(*args: Any, **kwargs: Any) -> None:
        jobs.append(len(args[1]))
        real(*args, **kwargs)

    monkeypatch.setattr(_pairs, "_JOB_ELEMS", medium_lib.n_frames * 50)  # many small jobs
    monkeypatch.setattr(_pairs, "run_jobs", counted)
    there = build_graph(medium_lib.clips, options, cluster=dask_cluster)
    assert jobs and jobs[0] > 10
    for name in ("src", "dst", "dist", "align", "in_scc"):
        assert np.array_equal(getattr(here, name), getattr(there, name)), name
    counts = ("contact", "candidates", "likelihood", "similarity", "scc")
    assert {k: here.report[k] for k in counts} == {k: there.report[k] for k in counts}


def _check_component(g: MotionGraph) -> None:
    plays = g.plays_on()
    indptr = g.indptr
    for f in np.flatnonzero(g.in_scc):
        exits = g.dst[indptr[f] : indptr[f + 1]]
        assert plays[f] or exits.size, f"frame {f} is a dead end"
        assert g.in_scc[exits].all()


def test_report_counts_shrink_and_component_has_no_dead_end(medium_lib: Library) -> None:
    g = build_graph(medium_lib.clips, GraphOptions(coords="relative"))
    r = g.report
    assert r["frames"] == medium_lib.n_frames == g.n_frames
    assert r["possible"] >= r["contact"] >= r["likelihood"] >= r["similarity"] >= r["scc"] > 0
    assert 0.3 * r["frames"] < r["scc_frames"] <= r["frames"]
    assert np.all(g.dist <= r["max_distance"] + 1e-6)
    assert np.all(np.diff(g.src) >= 0)
    _check_component(g)
    # every transition lands inside a clip, after the frame it resembles
    starts = set(g.clip_start[:-1].tolist())
    assert not any(int(t) in starts for t in g.dst)


def test_walk_never_leaves_the_component(medium_lib: Library) -> None:
    g = build_graph(medium_lib.clips, GraphOptions(coords="relative"))
    frames, jumps, edges = random_walk(g, 3000, seed=7)
    assert g.in_scc[frames].all()
    step = np.diff(frames)
    played = np.ones(frames.size - 1, dtype=bool)
    played[jumps - 1] = False
    assert np.all(step[played] == 1)
    assert np.array_equal(g.src[edges], frames[jumps - 1])
    assert np.array_equal(g.dst[edges], frames[jumps])
    assert jumps.size > 10
    again = random_walk(g, 3000, seed=7)
    assert np.array_equal(again[0], frames)
    with pytest.raises(ValueError, match="not in the graph's component"):
        random_walk(g, 10, start=int(np.flatnonzero(~g.in_scc)[0]))


def test_route_is_the_shortest_way_through_the_component(medium_lib: Library) -> None:
    g = build_graph(medium_lib.clips, GraphOptions(coords="relative"))
    frames, _, _ = random_walk(g, 400, seed=3)
    start, target = int(frames[0]), int(frames[-1])
    way = g.route(start, target, 400)
    assert way is not None
    path, through = way
    assert path[0] == start and path[-1] == target and through.size == path.size - 1
    assert path.size <= frames.size  # no longer than the walk that got there
    play = through < 0
    assert np.all(path[1:][play] == path[:-1][play] + 1)  # playing on: the next frame
    assert np.array_equal(g.src[through[~play]], path[:-1][~play])
    assert np.array_equal(g.dst[through[~play]], path[1:][~play])
    assert g.in_scc[path].all()
    # shortest: breadth first finds nothing in fewer steps
    assert g.route(start, target, path.size - 2) is None
    here = g.route(start, start, 5)
    assert here is not None and here[0].tolist() == [start] and here[1].size == 0
    outside = int(np.flatnonzero(~g.in_scc)[0])
    assert g.route(start, outside, 10_000) is None


def test_artifact_round_trip_and_bad_files(walk_lib: Library, tmp_path: Path) -> None:
    g = build_graph(walk_lib.clips, GraphOptions(coords="relative"))
    path = save_graph(g, tmp_path / "g.npz")
    h = load_graph(path)
    assert h.options == g.options and h.clip_names == g.clip_names
    assert h.library_digest == g.library_digest and h.sigma == g.sigma
    for name in ("clip_start", "src", "dst", "dist", "align", "in_scc"):
        assert np.array_equal(getattr(h, name), getattr(g, name))
    data = path.read_bytes()
    (tmp_path / "cut.npz").write_bytes(data[: len(data) // 2])
    with pytest.raises(GraphFileError, match=r"cut\.npz: unreadable, truncated or damaged"):
        load_graph(tmp_path / "cut.npz")
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    with pytest.raises(GraphFileError, match="not a mimic graph"):
        load_graph(tmp_path / "other.npz")
    with zipfile.ZipFile(path) as z:
        members = {m: z.read(m) for m in z.namelist()}
    with zipfile.ZipFile(tmp_path / "bad.npz", "w") as z:
        for m, blob in members.items():
            if m == "in_scc.npy":
                np.save(tmp_path / "x.npy", np.ones(3, dtype=bool))
                blob = (tmp_path / "x.npy").read_bytes()
            z.writestr(m, blob)
    with pytest.raises(GraphFileError, match=r"bad\.npz: checksum mismatch"):
        load_graph(tmp_path / "bad.npz")
    with pytest.raises(FileNotFoundError):
        load_graph(tmp_path / "missing.npz")


def test_cache_reuses_and_never_serves_a_stale_graph(medium_lib: Library, tmp_path: Path) -> None:
    clips = medium_lib.clips
    g1, p1, built1 = cached_graph(clips, GraphOptions(), cache_dir=tmp_path)
    g2, p2, built2 = cached_graph(clips, GraphOptions(), cache_dir=tmp_path)
    assert built1 and not built2 and p1 == p2 and g2.n_edges == g1.n_edges
    _, p3, built3 = cached_graph(clips[:-1], GraphOptions(), cache_dir=tmp_path)
    assert built3 and p3 != p1  # other clips: another graph
    _, p4, built4 = cached_graph(clips, GraphOptions(threshold=0.2), cache_dir=tmp_path)
    assert built4 and p4 != p1  # other options: another graph
    p1.write_bytes(b"garbage")
    _, p5, built5 = cached_graph(clips, GraphOptions(), cache_dir=tmp_path)
    assert built5 and p5 == p1 and load_graph(p1).n_edges == g1.n_edges


def test_options_are_checked() -> None:
    with pytest.raises(ValueError, match="coords"):
        GraphOptions(coords="polar")
    with pytest.raises(ValueError, match="threshold"):
        GraphOptions(threshold=1.5)
    with pytest.raises(ValueError, match="nu"):
        GraphOptions(nu=-1.0)


def test_case4_prune_drops_them_before_the_component(medium_lib: Library) -> None:
    g = build_graph(medium_lib.clips, GraphOptions(coords="relative", case4="prune", blend=1.0))
    r = g.report
    assert r["similarity"] >= r["case4"] >= r["scc"] > 0
    states = np.concatenate([c.contacts.states for c in medium_lib.clips])
    assert not case4(states, g.clip_start, g.src, g.dst, 15).any()
    _check_component(g)
    assert build_graph(medium_lib.clips, GraphOptions(coords="relative")).report["case4"] is None
