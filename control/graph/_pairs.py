"""The frame pairs under the likelihood threshold (``likely_pairs``): the lower bound's
candidates found a block of rows at a time and measured by the exact kernel a batch at a
time, in jobs run in this process or on a cluster (``control.jobs``), each job's result
kept where a build may be stopped and resumed."""

from __future__ import annotations

import hashlib
import json
import logging
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..jobs import JobStore, run_jobs
from ._broad import BroadPhase, wants_broad
from ._distance import close_pair_blocks, lower_bound_features, pair_distances
from ._features import FrameFeatures
from ._prune import contact_groups

if TYPE_CHECKING:
    from ._graph import GraphOptions

__all__ = ["likely_pairs"]

log = logging.getLogger(__name__)

IntArray = NDArray[np.int64]


#: candidate pairs measured by the exact kernel at a time (``likely_pairs``)
_MEASURE = 1 << 21


#: lower-bound comparisons (rows x columns) of one job (``likely_pairs``): a few seconds
_JOB_ELEMS = 1 << 27

_Pairs = tuple[IntArray, IntArray, NDArray[np.float64], NDArray[np.float32]]


def _measured(
    feat: FrameFeatures, options: GraphOptions, dmax: float, a: IntArray, b: IntArray
) -> _Pairs:
    """The pairs ``(a, b)`` whose exact distance is within ``dmax``, with their distances
    and alignments (float32)."""
    d, align = pair_distances(feat, a, b, options.nu, **options.terrain_args())
    keep = d <= dmax
    return a[keep], b[keep], d[keep], align[keep].astype(np.float32)


def _search_rows(
    feat: FrameFeatures,
    options: GraphOptions,
    dmax: float,
    x: np.ndarray,
    norms: np.ndarray,
    rows: IntArray,
    cols: IntArray,
    broad: BroadPhase | None = None,
) -> tuple[list[_Pairs], int, float]:
    """``rows`` against ``cols``: the lower bound's candidates a block of rows at a time,
    measured (``_measured``) once about ``_MEASURE`` of them are held; the likely pairs
    a part per batch, the candidates counted and the seconds of the lower bound."""
    parts: list[_Pairs] = []
    held: list[tuple[IntArray, IntArray]] = []  # candidates not yet measured
    n_candidates = 0
    t_search = 0.0
    blocks = close_pair_blocks(feat, rows, cols, dmax, options.nu, x, norms, broad=broad)
    while True:
        t0 = time.perf_counter()
        got = next(blocks, None)
        t_search += time.perf_counter() - t0
        if got is not None:
            held.append(got)
            n_candidates += got[0].size
        # measured a few million at a time (one kernel call on every core)
        if held and (got is None or sum(h[0].size for h in held) >= _MEASURE):
            a = np.concatenate([h[0] for h in held])
            b = np.concatenate([h[1] for h in held])
            held.clear()
            parts.append(_measured(feat, options, dmax, a, b))
        if got is None:
            return parts, n_candidates, t_search


def _pairs_job(
    shared: tuple[FrameFeatures, np.ndarray, np.ndarray, GraphOptions, float, list[Any]],
    job: tuple[int, int, int],
) -> tuple[list[_Pairs], int]:
    """One job: rows ``[r0, r1)`` of contact group ``g`` (``_search_rows``); its likely
    pairs and its number of candidates."""
    feat, x, norms, options, dmax, groups = shared
    g, r0, r1 = job
    rows, cols, broad = groups[g]
    parts, n_candidates, _ = _search_rows(feat, options, dmax, x, norms, rows[r0:r1], cols, broad)
    return parts, n_candidates


def _jobs(groups: list[tuple[IntArray, IntArray]]) -> list[tuple[int, int, int]]:
    """``(group, first row, end row)``: each contact group's rows in blocks of about
    ``_JOB_ELEMS`` comparisons."""
    jobs = []
    for g, (rows, cols) in enumerate(groups):
        step = max(1, _JOB_ELEMS // max(1, cols.size))
        jobs += [(g, r0, min(rows.size, r0 + step)) for r0 in range(0, rows.size, step)]
    return jobs


def _joined(parts: list[_Pairs]) -> _Pairs:
    """``parts`` as one ``_Pairs``, joined one array at a time, each array's parts let go
    once copied: the peak is the survivors and one more array, not the survivors twice."""
    empty = (
        np.zeros(0, dtype=np.int64),
        np.zeros(0, dtype=np.int64),
        np.zeros(0),
        np.zeros((0, 4), dtype=np.float32),
    )
    columns: list[list[Any]] = [[part[i] for part in parts] or [empty[i]] for i in range(4)]
    parts.clear()
    joined = []
    for column in columns:
        joined.append(np.concatenate(column))
        column.clear()
    return joined[0], joined[1], joined[2], joined[3]


_PART_KEYS = ("a", "b", "d", "align", "candidates")


def _to_part(pairs: _Pairs, n_candidates: int, n_frames: int) -> dict[str, np.ndarray]:
    """A job's pairs (joined) as the arrays a ``JobStore`` keeps (frame numbers at 32
    bits where they fit: read back, the same numbers)."""
    a, b, d, align = pairs
    index = np.int32 if n_frames < np.iinfo(np.int32).max else np.int64
    return {
        "a": a.astype(index),
        "b": b.astype(index),
        "d": d,
        "align": align,
        "candidates": np.array(n_candidates, dtype=np.int64),
    }


def _from_part(part: dict[str, np.ndarray]) -> tuple[list[_Pairs], int]:
    a, b = part["a"].astype(np.int64), part["b"].astype(np.int64)
    return [(a, b, part["d"], part["align"])], int(part["candidates"])


def _kept_jobs(
    work: Path | None, dmax: float, n: int, jobs: list[tuple[int, int, int]]
) -> tuple[JobStore | None, dict[int, tuple[list[_Pairs], int]]]:
    """The store of a build's finished jobs in ``work`` (``None`` without), named by
    what the jobs are, and the jobs it already holds (a stopped build's)."""
    if work is None:
        return None, {}
    table = json.dumps({"dmax": repr(dmax), "n": n, "jobs": jobs})
    store = JobStore(work, hashlib.sha256(table.encode()).hexdigest()[:24])
    results = {i: _from_part(p) for i, p in store.done(len(jobs), _PART_KEYS).items()}
    if results:
        kept = len(results)
        log.info("resuming the frame pairs: %d of %d jobs kept in %s", kept, len(jobs), work)
    return store, results


def _pair_count(groups: Sequence[tuple[IntArray, IntArray]]) -> int:
    """How many frame pairs the contact rule allows: each group's rows by its columns,
    less a frame with itself."""
    n = 0
    for rows, cols in groups:
        n += rows.size * cols.size - np.intersect1d(rows, cols, assume_unique=True).size
    return int(n)


def likely_pairs(
    feat: FrameFeatures,
    options: GraphOptions,
    dmax: float,
    cluster: str | None = None,
    work: Path | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[_Pairs, dict[str, Any]]:
    """Frame pairs ``(a, b)`` that the contact rule allows and whose exact distance ``d``
    is within ``dmax`` (the likelihood rule), with the alignment ``align`` that takes
    ``b`` onto ``a``.

    The rows of each contact group are searched (lower bound, then exact distances) in
    jobs of about ``_JOB_ELEMS`` comparisons, so that no more than a batch of candidates
    is held beside the survivors; at 500,000 frames nearly every candidate survives, so
    the alignments are held at float32, as the graph stores them (16 bytes a pair, not
    32). The jobs run in this process, or on a ``cluster`` (``control.jobs``; the frame
    features and each large group's KD-tree sent to each worker once); the same pairs
    come back in the same order either way. With ``work`` (a folder) each finished job's
    pairs are kept there (``JobStore``), so that a stopped build runs only the jobs it
    had not finished; ``progress(done, total)`` counts the jobs. The counts:
    ``contact``, ``candidates``, ``jobs``, ``resumed`` (jobs kept from before) and the
    seconds of the ``search`` (the lower bound and the exact distances)."""
    groups = contact_groups(feat.states, feat.clip_start, options.contact)
    x, norms = lower_bound_features(feat, options.nu)
    jobs = _jobs(groups)
    store, results = _kept_jobs(work, dmax, feat.n, jobs)
    resumed = len(results)
    todo = [i for i in range(len(jobs)) if i not in results]
    if progress:
        progress(len(results), len(jobs))

    def finished(k: int, got: tuple[list[_Pairs], int]) -> None:
        if store is not None:
            pairs = _joined(list(got[0]))  # (one array a column, as a kept job's)
            store.save(todo[k], _to_part(pairs, got[1], feat.n))
            got = ([pairs], got[1])
        results[todo[k]] = got
        if progress:
            progress(len(results), len(jobs))

    t0 = time.perf_counter()
    if todo:
        # a large group's KD-tree made once here, and sent with the features
        with_broad = [
            (rows, cols, BroadPhase.of(x, cols) if wants_broad(rows.size, cols.size) else None)
            for rows, cols in groups
        ]
        shared = (feat, x, norms, options, dmax, with_broad)
        # in this process the kernels use every core already: no worker processes
        run_jobs(_pairs_job, [jobs[i] for i in todo], finished, 1, cluster, shared)
    t_search = time.perf_counter() - t0
    # (in the jobs' order, whichever finished first)
    pairs = _joined([part for i in range(len(jobs)) for part in results[i][0]])
    counts = {
        "contact": _pair_count(groups),
        "candidates": int(sum(results[i][1] for i in range(len(jobs)))),
        "jobs": len(jobs),
        "resumed": resumed,
        "search": t_search,
    }
    return pairs, counts
