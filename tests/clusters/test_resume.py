"""A higher layer's build stopped midway resumes from the fits and trees it kept, and
gives the layer of one build without a stop."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from control.artifacts import cache_entries
from control.clusters import HigherLayer, LayerSettings, build_higher_layer, cached_higher_layer
from control.graph import GraphOptions, build_graph

#: a BIC search of three candidates on 80 of the 164 states, then the full fit; 2 s trees
SETTINGS = LayerSettings(ks=(3, 5, 8), sample=80, bound_seconds=2.0)


class _Stop(Exception):
    """The user's Ctrl-C."""


@pytest.fixture(scope="module")
def graph(walk_lib):
    return build_graph(walk_lib.clips, GraphOptions(coords="relative", threshold=0.2))


def _same(a: HigherLayer, b: HigherLayer) -> None:
    assert np.array_equal(a.labels, b.labels)
    assert [f.bic for f in a.fits] == [f.bic for f in b.fits]
    assert np.array_equal(a.forest.tree_of, b.forest.tree_of)
    assert len(a.forest.trees) == len(b.forest.trees) > 0
    for s, t in zip(a.forest.trees, b.forest.trees, strict=True):
        assert (s.root_frame, s.truncated, s.horizon) == (t.root_frame, t.truncated, t.horizon)
        for name in ("parent", "cluster", "arrival"):
            assert np.array_equal(getattr(s, name), getattr(t, name)), name


def _counting(monkeypatch: pytest.MonkeyPatch) -> dict[str, int]:
    """The fits and trees made from now on, counted."""
    from control.clusters import _forest, _gmm, _layer

    made = {"fits": 0, "trees": 0}
    fit, tree = _gmm.fit_mixture, _forest._build_tree

    def counted_fit(*args: Any, **kwargs: Any) -> Any:
        made["fits"] += 1
        return fit(*args, **kwargs)

    def counted_tree(*args: Any) -> Any:
        made["trees"] += 1
        return tree(*args)

    monkeypatch.setattr(_gmm, "fit_mixture", counted_fit)
    monkeypatch.setattr(_layer, "fit_mixture", counted_fit)
    monkeypatch.setattr(_forest, "_build_tree", counted_tree)
    return made


def test_a_layer_stopped_in_its_bic_search_resumes_with_the_fits_it_kept(
    graph, walk_lib, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    whole = build_higher_layer(graph, walk_lib.clips, SETTINGS)
    work = tmp_path / "layer.parts"

    def stop_after_two(done: int, total: int) -> None:
        if done == 2:
            raise _Stop

    with pytest.raises(_Stop):
        build_higher_layer(graph, walk_lib.clips, SETTINGS, progress=stop_after_two, work=work)
    assert len(list((work / "fits").glob("part-*.npz"))) == 2
    made = _counting(monkeypatch)
    again = build_higher_layer(graph, walk_lib.clips, SETTINGS, work=work)
    assert made["fits"] == 2  # the third candidate and the full fit
    _same(whole, again)


def test_a_layer_stopped_in_its_trees_resumes_with_the_trees_it_kept(
    graph, walk_lib, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    from control.clusters import _forest

    original = _forest._build_tree
    monkeypatch.setattr(_forest, "_TREES_PER_JOB", 3)
    monkeypatch.setattr(_forest, "_SAMPLE", 1)  # (the tree timed to judge laziness)
    whole = build_higher_layer(graph, walk_lib.clips, SETTINGS)
    n_trees = len(whole.forest.trees)
    assert n_trees > 40
    work = tmp_path / "layer.parts"
    made = _counting(monkeypatch)
    real = _forest._build_tree  # (counted)

    def stop_late(*args: Any) -> Any:
        if made["trees"] >= n_trees // 2:
            raise _Stop
        return real(*args)

    monkeypatch.setattr(_forest, "_build_tree", stop_late)
    with pytest.raises(_Stop):
        build_higher_layer(graph, walk_lib.clips, SETTINGS, work=work)
    kept = len(list((work / "trees").glob("part-*.npz")))
    assert kept > 3
    monkeypatch.setattr(_forest, "_build_tree", original)
    made = _counting(monkeypatch)
    seen: list[tuple[int, int]] = []
    again = build_higher_layer(
        graph, walk_lib.clips, SETTINGS, work=work, trees=lambda d, t: seen.append((d, t))
    )
    assert made["fits"] == 0  # every fit was kept
    # the trees counted as their jobs finish, from those kept
    assert seen[0][0] > 3 * kept and seen[-1] == (n_trees, n_trees)
    # the kept jobs' trees are read back; the rest built, and the one timed
    assert made["trees"] <= n_trees - 3 * kept + 1
    _same(whole, again)


def test_the_cache_keeps_a_stopped_layers_jobs_and_drops_them_once_stored(
    graph, walk_lib, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setenv("MIMIC_CACHE", str(tmp_path))
    folder = tmp_path / "graph"

    def stop(done: int, total: int) -> None:
        if done == 3:
            raise _Stop

    with pytest.raises(_Stop):
        cached_higher_layer(graph, walk_lib.clips, SETTINGS, cache_dir=folder, progress=stop)
    (parts,) = folder.glob("layer-*.parts")
    assert [e.kind for e in cache_entries(tmp_path) if e.path == parts] == ["layer"]
    made = _counting(monkeypatch)
    layer, path, built = cached_higher_layer(graph, walk_lib.clips, SETTINGS, cache_dir=folder)
    assert built and path.is_file() and not parts.exists()
    assert made["fits"] == 1  # the full fit alone
    # the layer of a build without a stop
    assert np.array_equal(layer.labels, build_higher_layer(graph, walk_lib.clips, SETTINGS).labels)
