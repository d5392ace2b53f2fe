"""The higher layer cached beside the graph: round trip, stale and damaged files."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from control.clusters import (
    LayerFileError,
    LayerSettings,
    build_higher_layer,
    cached_higher_layer,
    load_layer,
)
from control.graph import GraphOptions, build_graph


@pytest.fixture(scope="module")
def graph(walk_lib):
    return build_graph(walk_lib.clips, GraphOptions(coords="relative", threshold=0.2))


#: small layers (2 s trees): these tests are about the cache, not the trees
SMALL = {"bound_seconds": 2.0}  # (with k, a LayerSettings)


def test_a_cached_layer_is_the_built_one(graph, walk_lib, tmp_path) -> None:
    built, path, was_built = cached_higher_layer(
        graph, walk_lib.clips, LayerSettings(k=4, **SMALL), cache_dir=tmp_path
    )
    assert was_built and path.is_file()
    again, path2, was_built2 = cached_higher_layer(
        graph, walk_lib.clips, LayerSettings(k=4, **SMALL), cache_dir=tmp_path
    )
    assert path2 == path and not was_built2
    assert np.array_equal(again.labels, built.labels)
    assert np.array_equal(again.states, built.states)
    assert np.array_equal(again.forest.tree_of, built.forest.tree_of)
    assert len(again.forest.trees) == len(built.forest.trees)
    for a, b in zip(again.forest.trees, built.forest.trees, strict=True):
        assert a.root_frame == b.root_frame and a.truncated == b.truncated
        assert np.array_equal(a.parent, b.parent) and np.array_equal(a.cluster, b.cluster)
        assert np.array_equal(a.arrival, b.arrival)
    f = int(np.flatnonzero(graph.in_scc)[0])
    node = again.forest.tree(f).size - 1
    m1, m2 = again.motion_to(f, node), built.motion_to(f, node)
    assert (m1 is None) == (m2 is None)
    if m1 is not None and m2 is not None:
        assert np.array_equal(m1.frames, m2.frames)
    # another setting is another file
    _, path3, built3 = cached_higher_layer(
        graph, walk_lib.clips, LayerSettings(k=5, **SMALL), cache_dir=tmp_path
    )
    assert built3 and path3 != path


def test_a_damaged_or_foreign_layer_is_rebuilt_with_a_warning(
    graph, walk_lib, tmp_path, caplog
) -> None:
    _, path, _ = cached_higher_layer(
        graph, walk_lib.clips, LayerSettings(k=4, **SMALL), cache_dir=tmp_path
    )
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))
    with pytest.raises(LayerFileError, match=str(path)):
        load_layer(path, graph)
    with caplog.at_level(logging.WARNING):
        layer, _, built = cached_higher_layer(
            graph, walk_lib.clips, LayerSettings(k=4, **SMALL), cache_dir=tmp_path
        )
    assert built and str(path) in caplog.text
    assert load_layer(path, graph).clustering.k == layer.clustering.k
    other = build_graph(walk_lib.clips, GraphOptions(coords="relative", threshold=0.3))
    with pytest.raises(LayerFileError, match="another graph"):
        load_layer(path, other)
    path.write_text("not a zip")
    with pytest.raises(LayerFileError, match=str(path)):
        load_layer(path, graph)


def test_a_lazy_layer_builds_the_eager_trees_before_and_after_the_cache(
    graph, walk_lib, tmp_path, monkeypatch
) -> None:
    from control.clusters import _forest

    eager, _, _ = cached_higher_layer(
        graph, walk_lib.clips, LayerSettings(k=4, **SMALL), cache_dir=tmp_path
    )
    assert not eager.forest.report["lazy"] and eager.forest.lazy is None
    # a forest projected past LAZY_SECONDS (here: any) is lazy
    monkeypatch.setattr(_forest, "LAZY_SECONDS", 0.0)
    monkeypatch.setattr(_forest, "_SAMPLE", 4)
    lazy, _, built = cached_higher_layer(
        graph, walk_lib.clips, LayerSettings(k=4, **SMALL), cache_dir=tmp_path / "lazy"
    )
    assert built and lazy.forest.report["lazy"] and lazy.forest.report["sampled"] == 4
    assert lazy.forest.trees == () and lazy.forest.n_trees == eager.forest.n_trees
    again, _, built_again = cached_higher_layer(
        graph, walk_lib.clips, LayerSettings(k=4, **SMALL), cache_dir=tmp_path / "lazy"
    )
    assert not built_again and again.forest.lazy is not None and not again.forest.lazy.built
    np.testing.assert_array_equal(again.forest.tree_of, eager.forest.tree_of)
    for forest in (lazy.forest, again.forest):
        for f in np.flatnonzero(eager.forest.tree_of >= 0):
            a, b = forest.tree(int(f)), eager.forest.tree(int(f))
            assert a.root_frame == b.root_frame and a.truncated == b.truncated
            for name in ("parent", "cluster", "arrival"):
                np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        assert len(forest.lazy.built) == eager.forest.n_trees  # each built once, then kept


def test_layer_settings_are_checked_and_keyed_as_before() -> None:
    for bad in ({"k": 0}, {"ks": ()}, {"seeding": "kmeans++"}, {"bound_seconds": 0.0}):
        with pytest.raises(ValueError):
            LayerSettings(**bad)  # type: ignore[arg-type]
    # (the cache's key of the defaults is what the eight keyword arguments made)
    assert LayerSettings(bound_seconds=15).key() == {
        "k": None,
        "ks": list(range(5, 61, 5)),
        "seeding": "keyframes",
        "seed": 0,
        "bound_seconds": 15.0,
        "max_nodes": 4096,
        "max_states": 200_000,
    }


def test_a_layer_over_its_sample_is_clustered_from_a_sample_and_refit(graph, walk_lib) -> None:
    ks = {"ks": (3, 5, 8), **SMALL}
    whole = build_higher_layer(graph, walk_lib.clips, LayerSettings(sample=0, **ks))
    n = whole.states.shape[0]
    # at least as many as the states: exactly the search over every state
    big = build_higher_layer(graph, walk_lib.clips, LayerSettings(sample=n, **ks))
    np.testing.assert_array_equal(big.labels, whole.labels)
    assert "sample" not in big.curve
    said: list[tuple[int, int]] = []
    sampled = build_higher_layer(
        graph,
        walk_lib.clips,
        LayerSettings(sample=n // 2, **ks),
        progress=lambda *a: said.append(a),
    )
    assert said == [(1, 4), (2, 4), (3, 4), (4, 4)]  # three candidates, then the full fit
    assert sampled.curve["sample"] == n // 2 and sampled.labels.size == n
    assert sampled.clustering.k in ks["ks"] and all(f.labels.size == n // 2 for f in sampled.fits)
    assert LayerSettings(sample=n).key() != LayerSettings(sample=0).key()
    with pytest.raises(ValueError, match="sample"):
        LayerSettings(sample=-1)
