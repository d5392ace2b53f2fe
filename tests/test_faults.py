"""Faults in mimic's own files: a seeded fault-injection sweep over every artifact, and
the cache's bound and clearing.

Every damaged or edited file gives the same result, a rebuild with a warning naming it,
or an error naming it: never a traceback, never other data used silently. The wider
sweep, with its table, is ``benchmarks/bench_faults.py``.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np
import pytest

from control.artifacts import (
    bound_cache,
    build_lock,
    cache_entries,
    checksum,
    clear_cache,
    is_locked,
    verify_checksum,
)
from control.graph import cached_graph
from control.motion import load_library
from mimic.cli import main
from tests.faults import GOOD, sweep, table


@pytest.mark.slow
def test_every_damaged_artifact_is_rebuilt_or_named(mocap: Path) -> None:
    outcomes = sweep(mocap, flips=5, truncations=2, seed=19)
    bad = [o for o in outcomes if o.outcome not in GOOD]
    assert not bad, bad
    rows = table(outcomes)
    assert len(rows) == 12
    rebuilt = (
        "motion cache entry",
        "library cache entry",
        "graph (cache)",
        "higher layer (cache)",
        "bank.npz",
        "bank features.npy",
        "window tables (beside the bank)",
        "window tables manifest",
    )
    for name in (*rebuilt, "window index (beside the bank)"):
        assert rows[name].get("rebuilt", 0) >= 5, (name, rows[name])
    for name in ("graph file (load_graph)", "motion arrays (.motion.npz)"):
        assert rows[name].get("error", 0) >= 5, (name, rows[name])  # nothing to rebuild from
    # each consistent edit is caught: none is used as it stands
    edits = [o for o in outcomes if not o.case.startswith(("flip", "truncate"))]
    assert len(edits) == 38
    assert all(o.outcome in ("rebuilt", "error") for o in edits if o.case != "marked incomplete")


class _Err(ValueError):
    def __init__(self, path: Path, problem: str) -> None:
        super().__init__(f"{path}: {problem}")


def test_the_checksum_sees_a_manifest_edit_and_one_changed_value() -> None:
    arrays = {"a": np.arange(6, dtype=np.float32).reshape(2, 3), "s": np.array("text")}
    manifest = {"fps": 15.0, "names": ["x", "y"]}
    manifest["checksum"] = checksum(manifest, arrays)
    verify_checksum(manifest, arrays, Path("f.npz"), _Err)  # as written: no error
    with pytest.raises(_Err, match=r"f\.npz: checksum mismatch"):
        verify_checksum({**manifest, "fps": 30.0}, arrays, Path("f.npz"), _Err)
    changed = {**arrays, "a": arrays["a"].copy()}
    changed["a"][1, 2] = np.nextafter(np.float32(5), np.float32(6))
    with pytest.raises(_Err, match="checksum mismatch"):
        verify_checksum(manifest, changed, Path("f.npz"), _Err)
    with pytest.raises(_Err, match="checksum mismatch"):  # same bytes, other shape
        verify_checksum(manifest, {**arrays, "a": arrays["a"].reshape(3, 2)}, Path("f"), _Err)
    with pytest.raises(_Err, match="no checksum"):
        verify_checksum({"fps": 15.0}, arrays, Path("f.npz"), _Err)


def _entry(root: Path, rel: str, size: int, age_days: float) -> Path:
    p = root / rel
    p.parent.mkdir(parents=True, exist_ok=True)
    if rel.startswith("bank/"):
        p.mkdir()
        (p / "bank.npz").write_bytes(b"x" * size)
    else:
        p.write_bytes(b"x" * size)
    when = time.time() - age_days * 86400
    os.utime(p, (when, when))
    return p


def test_the_cache_keeps_its_bound_least_recently_used_first(tmp_path: Path) -> None:
    old = _entry(tmp_path, "motion/a.npz", 400, 3)
    bank = _entry(tmp_path, "bank/0123", 500, 2)
    graph = _entry(tmp_path, "graph/graph-1.npz", 300, 1)
    layer = _entry(tmp_path, "graph/layer-1.npz", 200, 0)
    assert [e.path for e in cache_entries(tmp_path)] == [old, bank, graph, layer]
    assert [e.kind for e in cache_entries(tmp_path)] == ["motion", "bank", "graph", "layer"]
    with build_lock(bank):  # being built by another process: kept too
        assert is_locked(bank)
        assert [e.path for e in bound_cache(limit=800, root=tmp_path)] == [old, graph]
    assert not is_locked(bank)
    when = time.time() - 2 * 86400  # (the lock's file made the folder look just used)
    os.utime(bank, (when, when))
    old, graph = (
        _entry(tmp_path, "motion/a.npz", 400, 3),
        _entry(tmp_path, "graph/graph-1.npz", 300, 1),
    )
    removed = bound_cache(keep=[bank], limit=800, root=tmp_path)
    assert [e.path for e in removed] == [old, graph]  # the bank is in use: kept
    assert bank.is_dir() and layer.is_file() and not old.exists() and not graph.exists()
    assert [e.path for e in clear_cache(["bank"], older_than_days=5, root=tmp_path)] == []
    assert [e.path for e in clear_cache(["bank"], older_than_days=1, root=tmp_path)] == [bank]
    with pytest.raises(ValueError, match="unknown cache kinds"):
        clear_cache(["banks"], root=tmp_path)


def test_a_limit_below_what_is_in_use_is_said(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """Eviction of entries unused for days is quiet; removing one used within the hour,
    or keeping more than the limit, says that the limit is too small."""
    _entry(tmp_path, "motion/a.npz", 400, 3)
    with caplog.at_level("WARNING", logger="control.artifacts"):
        assert len(bound_cache(limit=100, root=tmp_path)) == 1
        assert not caplog.records
        graph = _entry(tmp_path, "graph/graph-1.npz", 300, 0.001)  # a minute ago
        bank = _entry(tmp_path, "bank/0123", 500, 0)
        assert [e.path for e in bound_cache(keep=[bank], limit=100, root=tmp_path)] == [graph]
    said = caplog.records[-1].getMessage()
    assert "MIMIC_CACHE_MAX_GB" in said and "graph-1.npz" in said and "GB kept" in said


def test_a_new_graph_evicts_old_entries_beyond_the_limit(
    mocap: Path, monkeypatch: pytest.MonkeyPatch, fresh_cache: Path
) -> None:
    root = fresh_cache
    stale = _entry(root, "bank/stale", 10_000, 30)
    lib = load_library(mocap, clips=["02_0[1-4]"], workers=1)
    monkeypatch.setenv("MIMIC_CACHE_MAX_GB", "0.000005")  # 5 kB: only what is in use
    _, path, built = cached_graph(lib.clips)
    assert built and path.is_file() and not stale.exists()
    monkeypatch.setenv("MIMIC_CACHE_MAX_GB", "lots")
    with pytest.raises(ValueError, match="MIMIC_CACHE_MAX_GB"):
        bound_cache()


def test_mimic_cache_shows_and_clears(
    mocap: Path, capsys: pytest.CaptureFixture[str], fresh_cache: Path
) -> None:
    root = fresh_cache
    load_library(mocap, clips=["02_01"], workers=1)
    assert main(["cache"]) == 0
    out = capsys.readouterr().out
    # the parsed file's entry and the whole library's
    assert str(root) in out and "motion" in out and "2 entries" in out
    assert main(["cache", "clear", "--kind", "graph"]) == 0
    assert "removed 0 entries" in capsys.readouterr().out
    assert main(["cache", "clear"]) == 0
    assert "removed 2 entries" in capsys.readouterr().out
    assert not cache_entries(root)
    assert main(["cache", "clear", "--older-than", "-1"]) == 2
    assert "--older-than" in capsys.readouterr().err
