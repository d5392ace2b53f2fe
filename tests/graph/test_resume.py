"""A graph build stopped midway resumes from the jobs it finished (``control.jobs.JobStore``),
and gives the graph of one build without a stop."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from control.artifacts import cache_entries
from control.graph import GraphOptions, build_graph, cached_graph
from control.motion import Library

ARRAYS = ("src", "dst", "dist", "align", "in_scc")


class _Stop(Exception):
    """The user's Ctrl-C, as the build sees it between two jobs."""


def _counted_jobs(monkeypatch: pytest.MonkeyPatch) -> list[Any]:
    """Every job the search runs from now on, recorded."""
    from control.graph import _pairs

    ran: list[Any] = []
    real = _pairs._pairs_job

    def job(shared: Any, one: Any) -> Any:
        ran.append(one)
        return real(shared, one)

    monkeypatch.setattr(_pairs, "_pairs_job", job)
    return ran


def test_a_stopped_graph_build_runs_only_the_jobs_it_had_not_finished(
    medium_lib: Library,
    monkeypatch: pytest.MonkeyPatch,
    tmp_path: Path,
    caplog: pytest.LogCaptureFixture,
) -> None:
    from control.graph import _pairs

    options = GraphOptions(coords="relative")
    whole = build_graph(medium_lib.clips, options)
    monkeypatch.setattr(_pairs, "_JOB_ELEMS", medium_lib.n_frames * 200)  # many small jobs
    work = tmp_path / "graph.parts"

    def stop_after_five(done: int, total: int) -> None:
        if done == 5:
            raise _Stop

    with pytest.raises(_Stop):
        build_graph(medium_lib.clips, options, work=work, jobs=stop_after_five)
    kept = sorted(work.glob("part-*.npz"))
    assert len(kept) == 5
    # one finished part damaged (a disk fault, a copy cut short): said, and run again
    kept[2].write_bytes(kept[2].read_bytes()[:100])
    ran = _counted_jobs(monkeypatch)
    seen: list[tuple[int, int]] = []
    with caplog.at_level(logging.WARNING, logger="control.jobs"):
        again = build_graph(
            medium_lib.clips, options, work=work, jobs=lambda d, t: seen.append((d, t))
        )
    total = again.report["jobs"]
    assert total > 15 and again.report["resumed_jobs"] == 4
    assert len(ran) == total - 4  # the four intact parts were not searched again
    assert seen[0] == (4, total) and seen[-1] == (total, total)
    assert any(kept[2].name in r.getMessage() for r in caplog.records)
    for name in ARRAYS:
        assert np.array_equal(getattr(whole, name), getattr(again, name)), name
    counts = ("contact", "candidates", "likelihood", "similarity", "scc")
    assert {k: whole.report[k] for k in counts} == {k: again.report[k] for k in counts}


def test_parts_of_another_build_are_not_mixed_in(
    medium_lib: Library, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """A folder left by a build with other job sizes is emptied, not read."""
    from control.graph import _pairs

    options = GraphOptions(coords="relative")
    work = tmp_path / "graph.parts"
    monkeypatch.setattr(_pairs, "_JOB_ELEMS", medium_lib.n_frames * 200)

    def stop(done: int, total: int) -> None:
        if done == 3:
            raise _Stop

    with pytest.raises(_Stop):
        build_graph(medium_lib.clips, options, work=work, jobs=stop)
    monkeypatch.setattr(_pairs, "_JOB_ELEMS", medium_lib.n_frames * 500)
    ran = _counted_jobs(monkeypatch)
    g = build_graph(medium_lib.clips, options, work=work)
    assert g.report["resumed_jobs"] == 0 and len(ran) == g.report["jobs"]


def test_the_cache_keeps_a_stopped_builds_jobs_and_drops_them_once_stored(
    medium_lib: Library, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    from control.graph import _pairs

    monkeypatch.setattr(_pairs, "_JOB_ELEMS", medium_lib.n_frames * 200)
    monkeypatch.setenv("MIMIC_CACHE", str(tmp_path))
    folder = tmp_path / "graph"

    def stop(done: int, total: int) -> None:
        if done == 2:
            raise _Stop

    with pytest.raises(_Stop):
        cached_graph(medium_lib.clips, cache_dir=folder, progress=stop)
    (parts,) = folder.glob("graph-*.parts")
    assert len(list(parts.glob("part-*.npz"))) == 2
    # a stopped build's jobs are the cache's, counted and cleared with it
    assert [e.kind for e in cache_entries(tmp_path) if e.path == parts] == ["graph"]
    ran = _counted_jobs(monkeypatch)
    graph, path, built = cached_graph(medium_lib.clips, cache_dir=folder)
    assert built and path.is_file() and not parts.exists()
    assert graph.report["resumed_jobs"] == 2 and len(ran) == graph.report["jobs"] - 2
