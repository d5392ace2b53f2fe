"""The window index stored beside its bank (``cached_window_index``): read back next
time, checked, built again where damaged, and built once when two processes need it."""

from __future__ import annotations

import contextlib
import logging
import os
from pathlib import Path
from typing import Any

import numpy as np

from control.artifacts import array_digest, cached_in_parts, read_checked_npz, write_checked_npz
from control.dtw import ShapeTable

from ._index import FloatArray, IntArray, Progress, WindowIndex
from ._tables import prune_indexes

log = logging.getLogger(__name__)

__all__ = ["INDEX_VERSION", "IndexFileError", "cached_window_index"]


#: the stored index's format (``cached_window_index``)
INDEX_VERSION = 4  # 4: at most 64 lists scanned; 3: inverted files from 20,000 windows


def cached_window_index(
    shape: ShapeTable,
    centre: FloatArray,
    starts: IntArray,
    length: int,
    folder: str | Path | None,
    key: str = "",
    progress: Progress | None = None,
    cluster: str | None = None,
    **options: Any,
) -> WindowIndex:
    """``WindowIndex(shape, centre, starts, length, **options)``, stored in ``folder`` (a bank's
    folder: the index is made from its features) as ``index-<tables>-<hash>.npz`` and
    loaded from there next time, checked (``control.artifacts``). ``<tables>`` begins the
    tables' ``key`` (``cached_window_tables``), so that the index goes when they do
    (``prune_indexes``); the hash is of the key and ``starts`` (without a key: of the
    tables, read in full; no ``<tables>``). A damaged file is built again with a
    warning naming it; a folder that cannot be written is only read. ``progress`` and
    ``cluster``: ``WindowIndex``'s, as one is made (not when it is read). A build stopped
    midway keeps its finished jobs beside the file (``index-<tables>-<hash>.parts/``) and
    resumes from them; they are removed once the index is stored. Of two processes that
    need it at once, one builds it and the other waits and reads it
    (``control.artifacts.cached_in_parts``, under the folder's build lock)."""
    import faiss

    if folder is None:
        return WindowIndex(
            shape, centre, starts, length, progress=progress, cluster=cluster, **options
        )
    text = f"{INDEX_VERSION}|{length}|{sorted(options.items())}|{key}"
    digest = array_digest(text, (starts,) if key else (shape, centre, starts))
    path = Path(folder) / f"index-{f'{key[:24]}-' if key else ''}{digest[:24]}.npz"

    def load() -> WindowIndex | None:
        built = _read_index(path)
        if built is None:
            return None
        return WindowIndex(shape, centre, starts, length, **options, built=built)

    def build(parts: Path) -> WindowIndex:
        try:
            parts.mkdir(exist_ok=True)
            work: Path | None = parts
        except OSError:  # a bank folder that is only ours to read: the parts go elsewhere
            work = None
        return WindowIndex(
            shape, centre, starts, length, progress=progress, work=work, cluster=cluster, **options
        )

    def save(out: WindowIndex) -> None:
        arrays: dict[str, np.ndarray] = {
            "mean": np.asarray(out.mean, dtype=np.float32),
            "basis": out.basis,
            "index": np.asarray(faiss.serialize_index(out.index), dtype=np.uint8),
            "nprobe": np.array(out.nprobe),
        }
        try:
            write_checked_npz(path, arrays)
        except OSError as exc:  # a bank folder that is only ours to read
            log.info("the window index is not stored: %s", exc)
        prune_indexes(path.parent)

    # (a second builder beside the first would find the first one's parts gone)
    return cached_in_parts(path, load, build, save)[0]


def _read_index(path: Path) -> tuple[Any, Any, Any, int] | None:
    """The parts of the window index stored at ``path`` (its mean, basis, faiss index and
    lists searched), or ``None`` where there is none, or one that cannot be used (with a
    warning naming the file: it is built again)."""
    import faiss

    if not path.is_file():
        return None
    try:
        keys = ("mean", "basis", "index", "nprobe")
        d = read_checked_npz(path, keys, IndexFileError, "window index")
        with contextlib.suppress(OSError):
            os.utime(path)  # (used: the last of its tables' to be pruned)
        index: Any = faiss.deserialize_index(np.ascontiguousarray(d["index"], dtype=np.uint8))
    except IndexFileError as exc:  # (its message names the file)
        log.warning("building the window index again: %s", exc)
        return None
    except RuntimeError as exc:  # faiss could not read the index it wrote
        log.warning("building the window index again: %s: %s", path, exc)
        return None
    if int(d["nprobe"]):  # (an inverted-file index: its lists searched)
        index.nprobe = int(d["nprobe"])
    return d["mean"], d["basis"], index, int(d["nprobe"])


class IndexFileError(ValueError):
    """A stored window index that cannot be used (names the file)."""

    def __init__(self, path: str | Path, problem: str) -> None:
        self.path = Path(path)
        self.problem = problem
        super().__init__(f"{path}: {problem}")
