"""The frame pairs under the likelihood threshold (``likely_pairs``): the lower bound's
candidates found a block of rows at a time and measured by the exact kernel a batch at a
time, in this process or as jobs on a cluster (``control.jobs``)."""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..jobs import cluster_address, run_jobs
from ._distance import close_pair_blocks, lower_bound_features, pair_distances
from ._features import FrameFeatures
from ._prune import contact_groups

if TYPE_CHECKING:
    from ._graph import GraphOptions

__all__ = ["likely_pairs"]

IntArray = NDArray[np.int64]


#: candidate pairs measured by the exact kernel at a time (``likely_pairs``)
_MEASURE = 1 << 21


#: lower-bound comparisons (rows x columns) of one job on a cluster (``_pairs_on_cluster``)
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


def _pairs_job(
    shared: tuple[FrameFeatures, np.ndarray, np.ndarray, GraphOptions, float, list[Any]],
    job: tuple[int, int, int],
) -> tuple[_Pairs, int]:
    """One cluster job: rows ``[r0, r1)`` of contact group ``g`` searched (the lower
    bound) and measured (exact distances, a batch at a time); its likely pairs and its
    number of candidates."""
    feat, x, norms, options, dmax, groups = shared
    g, r0, r1 = job
    rows, cols = groups[g]
    found = list(close_pair_blocks(feat, rows[r0:r1], cols, dmax, options.nu, x, norms))
    a = np.concatenate([f[0] for f in found]) if found else np.zeros(0, dtype=np.int64)
    b = np.concatenate([f[1] for f in found]) if found else np.zeros(0, dtype=np.int64)
    parts = [
        _measured(feat, options, dmax, a[k : k + _MEASURE], b[k : k + _MEASURE])
        for k in range(0, a.size, _MEASURE)
    ] or [_measured(feat, options, dmax, a, b)]
    joined = tuple(np.concatenate([p[i] for p in parts]) for i in range(4))
    return (joined[0], joined[1], joined[2], joined[3]), int(a.size)


def _pairs_on_cluster(
    feat: FrameFeatures,
    options: GraphOptions,
    dmax: float,
    groups: list[tuple[IntArray, IntArray]],
    x: np.ndarray,
    norms: np.ndarray,
    address: str,
) -> tuple[list[_Pairs], int]:
    """``likely_pairs``'s search and measure as jobs on the cluster ``address`` (blocks
    of rows of each contact group; the frame features sent to each worker once), their
    parts in the order the local build makes them; and the candidates counted."""
    jobs = []
    for g, (rows, cols) in enumerate(groups):
        step = max(1, _JOB_ELEMS // max(1, cols.size))
        jobs += [(g, r0, min(rows.size, r0 + step)) for r0 in range(0, rows.size, step)]
    got: dict[int, tuple[_Pairs, int]] = {}
    shared = (feat, x, norms, options, dmax, groups)
    run_jobs(_pairs_job, jobs, got.__setitem__, cluster=address, shared=shared)
    return [got[i][0] for i in range(len(jobs))], sum(got[i][1] for i in range(len(jobs)))


def likely_pairs(
    feat: FrameFeatures, options: GraphOptions, dmax: float, cluster: str | None = None
) -> tuple[_Pairs, dict[str, Any]]:
    """Frame pairs ``(a, b)`` that the contact rule allows and whose exact distance ``d``
    is within ``dmax`` (the likelihood rule), with the alignment ``align`` that takes
    ``b`` onto ``a``. Rows are searched (lower bound, then exact distances) a block at a
    time, so that no more than a batch of candidates is held beside the survivors; at
    500,000 frames nearly every candidate survives, so the alignments are held at
    float32, as the graph stores them (16 bytes a pair, not 32). On a ``cluster``
    (``control.jobs``) the blocks are jobs, and the same pairs come back in the same
    order. The counts: ``contact``, ``candidates``, and the seconds of the lower-bound
    ``search`` (on a cluster: of the jobs, search and measure together)."""
    groups = contact_groups(feat.states, feat.clip_start, options.contact)
    n_contact = 0
    for rows, cols in groups:
        n_contact += rows.size * cols.size - np.intersect1d(rows, cols, assume_unique=True).size
    x, norms = lower_bound_features(feat, options.nu)
    # the survivors' a, b, d and align, a part per measured batch
    out: tuple[list[Any], ...] = ([], [], [], [])
    n_candidates = 0
    t_search = 0.0
    held: list[tuple[IntArray, IntArray]] = []  # candidates not yet measured

    def measure() -> None:
        a = np.concatenate([h[0] for h in held])
        b = np.concatenate([h[1] for h in held])
        held.clear()
        for part, arr in zip(out, _measured(feat, options, dmax, a, b), strict=True):
            part.append(arr)

    address = cluster_address(cluster)
    if address is not None:
        t0 = time.perf_counter()
        parts, n_candidates = _pairs_on_cluster(feat, options, dmax, groups, x, norms, address)
        t_search = time.perf_counter() - t0
        for piece in parts:
            for part, arr in zip(out, piece, strict=True):
                part.append(arr)
        groups = []  # (searched)
    for rows, cols in groups:
        blocks = close_pair_blocks(feat, rows, cols, dmax, options.nu, x, norms)
        while True:
            t0 = time.perf_counter()
            got = next(blocks, None)
            t_search += time.perf_counter() - t0
            if got is not None:
                held.append(got)
                n_candidates += got[0].size
            # measured a few million at a time (one kernel call on every core)
            if held and (got is None or sum(h[0].size for h in held) >= _MEASURE):
                measure()
            if got is None:
                break
    if not out[0]:
        out[0].append(np.zeros(0, dtype=np.int64))
        out[1].append(np.zeros(0, dtype=np.int64))
        out[2].append(np.zeros(0))
        out[3].append(np.zeros((0, 4), dtype=np.float32))
    # joined one array at a time, its parts let go once copied: the peak is the
    # survivors and one more array, not the survivors twice
    joined = []
    for part in out:
        joined.append(np.concatenate(part))
        part.clear()
    pairs = (joined[0], joined[1], joined[2], joined[3])
    counts = {
        "contact": int(n_contact),
        "candidates": int(n_candidates),
        "search": t_search,
    }
    return pairs, counts
