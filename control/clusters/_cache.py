"""The higher layer on disk, beside the graph it was built on: one ``.npz`` (no pickle)
with a JSON manifest, written atomically.

The file name hashes the layer version, the graph's own content (its transitions and
clips' digest) and the build settings, so a changed graph or setting never reuses a
stale layer; a file that cannot be used is rebuilt with a warning naming it. Only the
chosen mixture is stored (``fits`` holds just it after loading; ``curve`` keeps the
whole BIC curve).
"""

from __future__ import annotations

import hashlib
import json
import logging
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..artifacts import (
    atomic_write,
    bound_cache,
    cached_in_parts,
    checksum,
    read_npz,
    touch,
    verify_checksum,
)
from ..graph import MotionGraph, graph_cache_dir
from ..motion import Clip
from ._forest import ClusterForest, ClusterTree, lazy_forest
from ._gmm import Clustering
from ._layer import HigherLayer, LayerSettings, build_higher_layer
from ._paths import transition_log_probs

__all__ = ["LAYER_VERSION", "LayerFileError", "cached_higher_layer", "load_layer", "save_layer"]

log = logging.getLogger(__name__)

#: bump when the layer's construction changes, so that stale files are never used
LAYER_VERSION = 2  # 2: a checksum in the manifest

_CLUSTERING = ("labels", "posterior", "means", "variances", "weights", "seeds")
_TREES = ("root_frame", "parent", "cluster", "arrival", "truncated", "horizon", "offset")


class LayerFileError(ValueError):
    """A higher-layer file that cannot be used; the message names the file."""

    def __init__(self, path: str | Path, problem: str) -> None:
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{path}: {problem}")


def graph_digest(graph: MotionGraph) -> str:
    """A hash of what the higher layer is built from: the graph's clips and transitions."""
    h = hashlib.sha256(graph.library_digest.encode())
    h.update(json.dumps(graph.options.to_dict(), sort_keys=True).encode())
    for a in (graph.clip_start, graph.src, graph.dst, graph.dist, graph.in_scc):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def _key(graph: MotionGraph, settings: dict[str, Any]) -> str:
    blob = json.dumps(
        {"v": LAYER_VERSION, "graph": graph_digest(graph), **settings}, sort_keys=True
    )
    return hashlib.sha256(blob.encode()).hexdigest()[:24]


def save_layer(layer: HigherLayer, path: str | Path, key: str = "") -> Path:
    """Write ``layer`` to ``path`` (``.npz``) atomically."""
    path = Path(path)
    c = layer.clustering
    trees = layer.forest.trees  # (none for a lazy forest: its roots are stored)
    lazy = layer.forest.lazy
    sizes = np.array([t.size for t in trees], dtype=np.int64)
    roots = lazy.roots if lazy is not None else [t.root_frame for t in trees]
    manifest = {
        "format": "mimic-layer",
        "version": LAYER_VERSION,
        "key": key,
        "graph": graph_digest(layer.graph),
        "log_likelihood": c.log_likelihood,
        "bic": c.bic,
        "n_params": c.n_params,
        "seeding": c.seeding,
        "curve": layer.curve,
        "bound": layer.forest.bound,
        "report": layer.forest.report,
        "lazy": lazy is not None,
    }
    arrays: dict[str, np.ndarray] = {
        "states": layer.states,
        "q_hat": layer.q_hat,
        "tree_of": layer.forest.tree_of,
        **{f"c_{name}": getattr(c, name) for name in _CLUSTERING},
        "t_root_frame": np.array(roots, dtype=np.int64),
        "t_parent": np.concatenate([t.parent for t in trees]) if trees else np.zeros(0, int),
        "t_cluster": np.concatenate([t.cluster for t in trees]) if trees else np.zeros(0, int),
        "t_arrival": np.concatenate([t.arrival for t in trees]) if trees else np.zeros(0, int),
        "t_truncated": np.array([t.truncated for t in trees], dtype=bool),
        "t_horizon": np.array([t.horizon for t in trees], dtype=np.int64),
        "t_offset": np.concatenate(([0], np.cumsum(sizes))).astype(np.int64),
    }
    manifest["checksum"] = checksum(manifest, arrays)
    with atomic_write(path, "wb") as fh:  # (stored, not deflated: at 500,000 frames
        # inflating the graph and the layer took 1 s of each warm start-up, for 150 MB)
        np.savez(fh, manifest=np.array(json.dumps(manifest)), **arrays)  # type: ignore[arg-type]
    return path


def load_layer(path: str | Path, graph: MotionGraph) -> HigherLayer:
    """Read a layer written by ``save_layer`` for ``graph``; ``LayerFileError`` when the
    file is not one, is damaged, or belongs to another graph."""
    path = Path(path)
    keys = (
        "manifest",
        "states",
        "q_hat",
        "tree_of",
        *(f"c_{n}" for n in _CLUSTERING),
        *(f"t_{n}" for n in _TREES),
    )
    try:
        a = read_npz(path, keys, LayerFileError, "mimic higher layer")
        manifest: dict[str, Any] = json.loads(str(a.pop("manifest")))
    except LayerFileError:
        raise
    except ValueError as exc:
        raise LayerFileError(path, f"damaged file ({exc})") from exc
    if not isinstance(manifest, dict) or manifest.get("format") != "mimic-layer":
        raise LayerFileError(path, "not a mimic higher-layer file")
    if manifest.get("version") != LAYER_VERSION:
        raise LayerFileError(path, f"layer version {manifest.get('version')}, not {LAYER_VERSION}")
    verify_checksum(manifest, a, path, LayerFileError)
    if manifest.get("graph") != graph_digest(graph):
        raise LayerFileError(path, "built on another graph")
    lazy = manifest.get("lazy") is True
    _check_arrays(a, graph.n_frames, path, lazy)
    labels = a["c_labels"].astype(np.int64)
    clustering = Clustering(
        labels=labels,
        posterior=a["c_posterior"].astype(np.float64),
        means=a["c_means"].astype(np.float64),
        variances=a["c_variances"].astype(np.float64),
        weights=a["c_weights"].astype(np.float64),
        log_likelihood=float(manifest["log_likelihood"]),
        bic=float(manifest["bic"]),
        n_params=int(manifest["n_params"]),
        seeding=str(manifest["seeding"]),
        seeds=a["c_seeds"].astype(np.int64),
    )
    forest = _read_forest(a, manifest, graph, labels, path, lazy)
    return HigherLayer(
        graph,
        a["states"].astype(np.float64),
        a["q_hat"].astype(np.float64),
        clustering,
        (clustering,),
        dict(manifest.get("curve", {})),
        forest,
        transition_log_probs(graph),
    )


def _read_forest(
    a: dict[str, np.ndarray],
    manifest: dict[str, Any],
    graph: MotionGraph,
    labels: NDArray[np.int64],
    path: Path,
    lazy: bool,
) -> ClusterForest:
    """The forest of a layer file's checked arrays ``a``: its trees, or a lazy forest's
    roots, whose trees are grown when asked for (``lazy_forest``)."""
    report = dict(manifest.get("report", {}))
    tree_of, bound = a["tree_of"].astype(np.int64), int(manifest["bound"])
    if lazy:
        try:
            caps = int(report["max_nodes"]), int(report["max_states"])
        except (KeyError, TypeError, ValueError) as exc:
            raise LayerFileError(path, f"a lazy forest without its caps ({exc!r})") from None
        roots = a["t_root_frame"].astype(np.int64)
        return lazy_forest(graph, labels, roots, tree_of, bound, *caps, report)
    off = a["t_offset"].astype(np.int64)
    trees = tuple(
        ClusterTree(
            root_frame=int(a["t_root_frame"][i]),
            parent=a["t_parent"][off[i] : off[i + 1]].astype(np.int64),
            cluster=a["t_cluster"][off[i] : off[i + 1]].astype(np.int64),
            arrival=a["t_arrival"][off[i] : off[i + 1]].astype(np.int64),
            truncated=bool(a["t_truncated"][i]),
            horizon=int(a["t_horizon"][i]),
        )
        for i in range(a["t_root_frame"].size)
    )
    return ClusterForest(trees, tree_of, bound, report)


def _check_arrays(a: dict[str, np.ndarray], n: int, path: Path, lazy: bool) -> None:
    """``LayerFileError`` unless the arrays fit one another and a graph of ``n`` frames
    (a lazy forest's: its roots, and no tree)."""
    off = a["t_offset"].astype(np.int64)
    n_trees = a["t_root_frame"].size
    labels = a["c_labels"].astype(np.int64)
    built = 0 if lazy else n_trees
    try:
        ok = (
            labels.shape == (n,)
            and a["c_posterior"].shape == (n,)
            and a["states"].shape[0] == n
            and a["tree_of"].shape == (n,)
            and off.shape == (built + 1,)
            and off[0] == 0
            and bool(np.all(np.diff(off) >= 1))
            and off[-1] == a["t_parent"].size == a["t_cluster"].size == a["t_arrival"].size
            and a["t_truncated"].shape == a["t_horizon"].shape == (built,)
            and int(a["tree_of"].max(initial=-1)) < n_trees
            and int(a["t_root_frame"].max(initial=0)) < n
            and int(a["t_root_frame"].min(initial=0)) >= 0
            and labels.min(initial=0) >= 0
            and labels.max(initial=0) < a["c_means"].shape[0]
            and all(np.isfinite(a[k]).all() for k in ("states", "c_posterior", "c_means"))
        )
    except (TypeError, ValueError, IndexError):
        ok = False
    if not ok:
        raise LayerFileError(path, "arrays of inconsistent shapes or values")


def _load_cached(path: Path, graph: MotionGraph) -> HigherLayer | None:
    """The cached layer at ``path`` when it loads, else ``None`` (with a warning)."""
    try:
        layer = load_layer(path, graph)
        touch(path)
        return layer
    except LayerFileError as exc:
        log.warning("rebuilding the higher layer: %s", exc)
    return None


def cached_higher_layer(
    graph: MotionGraph,
    clips: Sequence[Clip],
    settings: LayerSettings | None = None,
    cache_dir: str | Path | None = None,
    rebuild: bool = False,
    cluster: str | None = None,
    progress: Callable[[int, int], None] | None = None,
    trees: Callable[[int, int], None] | None = None,
) -> tuple[HigherLayer, Path, bool]:
    """The higher layer of ``graph`` with ``settings`` from the cache (beside the
    graphs), built and stored when missing, stale or unreadable (with a warning naming
    the file; its trees built on ``cluster`` where one is named; ``progress`` and
    ``trees``: as ``build_higher_layer`` calls them). Returns ``(layer, path, built)``.
    A build stopped midway keeps its finished fits and trees beside the layer's file
    (``layer-<key>.parts/``) and resumes from them; they are removed once it is
    stored."""
    settings = settings or LayerSettings()
    key = _key(graph, settings.key())
    folder = Path(cache_dir) if cache_dir is not None else graph_cache_dir()
    path = folder / f"layer-{key}.npz"

    layer, built = cached_in_parts(
        path,
        lambda: _load_cached(path, graph),
        lambda parts: build_higher_layer(graph, clips, settings, cluster, progress, parts, trees),
        lambda layer: save_layer(layer, path, key),
        rebuild,
    )
    if built and cache_dir is None:
        bound_cache(keep=[path])
    return layer, path, built
