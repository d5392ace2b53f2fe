"""The graph on disk: one ``.npz`` (no pickle) with a JSON manifest, written atomically.

File names are content hashes of the graph version, the clips' digest and the options,
so a changed library or setting never reuses a stale graph.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..artifacts import (
    atomic_write,
    bound_cache,
    cache_root,
    cached_in_parts,
    checksum,
    read_npz,
    touch,
    verify_checksum,
)
from ..motion import Clip
from ._graph import (
    GRAPH_VERSION,
    GraphOptions,
    MotionGraph,
    build_graph,
    clips_digest,
    select_clips,
)
from ._graph import options_key as _key

__all__ = ["GraphFileError", "cached_graph", "graph_cache_dir", "load_graph", "save_graph"]

log = logging.getLogger(__name__)

_ARRAYS = ("clip_start", "src", "dst", "dist", "align", "in_scc")


class GraphFileError(ValueError):
    """A graph file that cannot be used; the message names the file and the problem."""

    def __init__(self, path: str | Path, problem: str) -> None:
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{path}: {problem}")


def graph_cache_dir() -> Path:
    """The graphs' folder of the cache: ``cache_root() / "graph"``."""
    return cache_root() / "graph"


def save_graph(graph: MotionGraph, path: str | Path) -> Path:
    """Write ``graph`` to ``path`` (``.npz``) atomically and return the path."""
    path = Path(path)
    manifest = {
        "format": "mimic-graph",
        "version": GRAPH_VERSION,
        "options": graph.options.to_dict(),
        "clip_names": list(graph.clip_names),
        "fps": graph.fps,
        "sigma": graph.sigma,
        "library_digest": graph.library_digest,
        "report": graph.report,
    }
    arrays = {name: np.asarray(getattr(graph, name)) for name in _ARRAYS}
    manifest["checksum"] = checksum(manifest, arrays)
    with atomic_write(path, "wb") as fh:  # (stored, not deflated: at 500,000 frames
        # inflating the graph and the layer took 1 s of each warm start-up, for 150 MB)
        np.savez(fh, manifest=np.array(json.dumps(manifest)), **arrays)  # type: ignore[arg-type]
    return path


def load_graph(path: str | Path) -> MotionGraph:
    """Read a graph written by ``save_graph``; ``GraphFileError`` if it is not one."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no graph file {path}")
    arrays = read_npz(path, ("manifest", *_ARRAYS), GraphFileError, "mimic graph")
    try:
        manifest: dict[str, Any] = json.loads(str(arrays.pop("manifest")))
    except ValueError as exc:
        raise GraphFileError(path, f"corrupt manifest ({exc})") from exc
    if not isinstance(manifest, dict) or manifest.get("format") != "mimic-graph":
        raise GraphFileError(path, "not a mimic graph file")
    if manifest.get("version") != GRAPH_VERSION:
        raise GraphFileError(
            path, f"graph version {manifest.get('version')}, this mimic reads {GRAPH_VERSION}"
        )
    verify_checksum(manifest, arrays, path, GraphFileError)
    try:
        return _graph_of(manifest, arrays, path)
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        if isinstance(exc, GraphFileError):
            raise
        raise GraphFileError(path, f"inconsistent graph file ({exc!r})") from None


def _graph_of(manifest: dict[str, Any], arrays: dict[str, np.ndarray], path: Path) -> MotionGraph:
    n_e = arrays["src"].shape[0]
    n = int(arrays["clip_start"][-1]) if arrays["clip_start"].size else -1
    shapes_ok = (
        arrays["dst"].shape == (n_e,)
        and arrays["dist"].shape == (n_e,)
        and arrays["align"].shape == (n_e, 4)
        and arrays["in_scc"].shape == (n,)
        and len(manifest["clip_names"]) == arrays["clip_start"].size - 1
    )
    if not shapes_ok:
        raise GraphFileError(path, "arrays of inconsistent shapes")
    if n_e and (
        arrays["src"].min() < 0
        or max(arrays["src"].max(), arrays["dst"].max()) >= n
        or arrays["dst"].min() < 1
    ):
        raise GraphFileError(path, "transition frame out of range")
    try:
        options = GraphOptions(**manifest["options"])
    except (TypeError, ValueError) as exc:
        raise GraphFileError(path, f"bad options ({exc})") from exc
    return MotionGraph(
        options=options,
        clip_names=tuple(manifest["clip_names"]),
        clip_start=arrays["clip_start"].astype(np.int64),
        fps=float(manifest["fps"]),
        sigma=float(manifest["sigma"]),
        src=arrays["src"].astype(np.int64),
        dst=arrays["dst"].astype(np.int64),
        dist=arrays["dist"].astype(np.float32),
        align=arrays["align"].astype(np.float32),
        in_scc=arrays["in_scc"].astype(bool),
        library_digest=str(manifest["library_digest"]),
        report=dict(manifest.get("report", {})),
    )


def _load_cached(path: Path, digest: str) -> MotionGraph | None:
    """The cached graph at ``path`` when it loads and is of the library ``digest``, else
    ``None`` (with a warning naming the file)."""
    try:
        graph = load_graph(path)
        if graph.library_digest == digest:
            touch(path)
            return graph
        log.warning("rebuilding the graph: %s was built from another library", path)
    except GraphFileError as exc:
        log.warning("rebuilding the graph: %s", exc)
    return None


def cached_graph(
    clips: Sequence[Clip],
    options: GraphOptions | None = None,
    cache_dir: str | Path | None = None,
    rebuild: bool = False,
    cluster: str | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[MotionGraph, Path, bool]:
    """The graph of ``clips`` from the cache, built and stored when missing or stale
    (built on ``cluster`` where one is named: ``build_graph``; ``progress(done,
    total)`` counts its search's jobs).

    Returns ``(graph, path, built)``. A cache file that cannot be used (unreadable,
    damaged, edited) is rebuilt, with a warning naming it. A build stopped midway keeps
    its finished jobs beside the graph's file (``graph-<key>.parts/``) and resumes from
    them; they are removed once the graph is stored.
    """
    options = options or GraphOptions()
    chosen, _ = select_clips(list(clips))
    digest = clips_digest(chosen)
    folder = Path(cache_dir) if cache_dir is not None else graph_cache_dir()
    path = folder / f"graph-{_key(options, digest)}.npz"

    graph, built = cached_in_parts(
        path,
        lambda: _load_cached(path, digest),
        lambda parts: build_graph(clips, options, cluster=cluster, work=parts, jobs=progress),
        lambda graph: save_graph(graph, path),
        rebuild,
    )
    if built and cache_dir is None:
        bound_cache(keep=[path])
    return graph, path, built
