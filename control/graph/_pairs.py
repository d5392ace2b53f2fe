"""The frame pairs under the likelihood threshold (``likely_pairs``): the lower bound's
candidates found a block of rows at a time and measured by the exact kernel a batch at a
time, in this process or as jobs on a cluster (``control.jobs``)."""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..jobs import cluster_address, map_jobs
from ._broad import BroadPhase, wants_broad
from ._distance import close_pair_blocks, lower_bound_features, pair_distances
from ._features import FrameFeatures
from ._prune import contact_groups

if TYPE_CHECKING:
    from ._graph import GraphOptions

__all__ = ["likely_pairs"]

IntArray = NDArray[np.int64]


#: candidate pairs measured by the exact kernel at a time (``likely_pairs``)
_MEASURE = 1 << 21


#: lower-bound comparisons (rows x columns) of one job on a cluster (``likely_pairs``)
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
    """One cluster job: rows ``[r0, r1)`` of contact group ``g`` (``_search_rows``); its
    likely pairs and its number of candidates."""
    feat, x, norms, options, dmax, groups = shared
    g, r0, r1 = job
    rows, cols, broad = groups[g]
    parts, n_candidates, _ = _search_rows(feat, options, dmax, x, norms, rows[r0:r1], cols, broad)
    return parts, n_candidates


def likely_pairs(
    feat: FrameFeatures, options: GraphOptions, dmax: float, cluster: str | None = None
) -> tuple[_Pairs, dict[str, Any]]:
    """Frame pairs ``(a, b)`` that the contact rule allows and whose exact distance ``d``
    is within ``dmax`` (the likelihood rule), with the alignment ``align`` that takes
    ``b`` onto ``a``. Rows are searched (lower bound, then exact distances) a block at a
    time, so that no more than a batch of candidates is held beside the survivors; at
    500,000 frames nearly every candidate survives, so the alignments are held at
    float32, as the graph stores them (16 bytes a pair, not 32). On a ``cluster``
    (``control.jobs``) blocks of rows of each contact group are jobs (the frame features
    sent to each worker once), and the same pairs come back in the same order. The
    counts: ``contact``, ``candidates``, and the seconds of the lower-bound ``search``
    (on a cluster: of the jobs, search and measure together)."""
    groups = contact_groups(feat.states, feat.clip_start, options.contact)
    n_contact = 0
    for rows, cols in groups:
        n_contact += rows.size * cols.size - np.intersect1d(rows, cols, assume_unique=True).size
    x, norms = lower_bound_features(feat, options.nu)
    parts: list[_Pairs] = []  # the survivors, a part per measured batch
    n_candidates = 0
    t_search = 0.0
    address = cluster_address(cluster)
    if address is not None:
        jobs = []
        for g, (rows, cols) in enumerate(groups):
            step = max(1, _JOB_ELEMS // max(1, cols.size))
            jobs += [(g, r0, min(rows.size, r0 + step)) for r0 in range(0, rows.size, step)]
        t0 = time.perf_counter()
        # a large group's KD-tree made once here, and sent with the features
        with_broad = [
            (
                rows,
                cols,
                BroadPhase.of(x, cols) if wants_broad(rows.size, cols.size) else None,
            )
            for rows, cols in groups
        ]
        shared = (feat, x, norms, options, dmax, with_broad)
        for got, n in map_jobs(_pairs_job, jobs, cluster=address, shared=shared):
            parts += got
            n_candidates += n
        t_search = time.perf_counter() - t0
    else:
        for rows, cols in groups:
            got, n, t = _search_rows(feat, options, dmax, x, norms, rows, cols)
            parts += got
            n_candidates += n
            t_search += t
    empty = (
        np.zeros(0, dtype=np.int64),
        np.zeros(0, dtype=np.int64),
        np.zeros(0),
        np.zeros((0, 4), dtype=np.float32),
    )
    columns: list[list[Any]] = [[part[i] for part in parts] or [empty[i]] for i in range(4)]
    del parts
    # joined one array at a time, its parts let go once copied: the peak is the
    # survivors and one more array, not the survivors twice
    joined = []
    for column in columns:
        joined.append(np.concatenate(column))
        column.clear()
    pairs = (joined[0], joined[1], joined[2], joined[3])
    counts = {
        "contact": int(n_contact),
        "candidates": int(n_candidates),
        "search": t_search,
    }
    return pairs, counts
