"""A fast whole-library window search: a nearest-neighbour broad phase (faiss), exact DTW
on its short list.

Every window of ``length`` frames in every bank view is summarised by its piecewise
aggregate (the mean of each of ``segments`` stretches of frames: Keogh's PAA, which DTW's
band barely changes) of the same numbers DTW compares (mapped shape numbers, the centre
relative to the window's first frame), reduced by PCA to ``dims`` numbers. A query (a
performer's window, of any length: it is resampled to ``length`` frames) is summarised
the same way; faiss returns the ``shortlist`` nearest summaries (an inverted-file index
for large banks, exact for small ones), and exact DTW ranks them, with each window's two
neighbours in time (the band lets DTW shift). ``tests/vision/test_index.py`` checks that
the best window found is the brute-force best in >= 99% of queries.
"""

from __future__ import annotations

import hashlib
import itertools
import logging
import math
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from control.dtw import SHAPE_DTYPE, ShapeTable, dtw_windows

from ._summaries import _bounds, _run_summaries, _summaries, fill_lists, projected

log = logging.getLogger(__name__)

__all__ = ["WindowIndex", "best_of"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
#: ``progress(done, total)``, as a build goes
Progress = Callable[[int, int], None]


#: a search among flagged windows (``WindowIndex.search``'s ``only``: the voted action's)
#: scans their own summaries exactly when an inverted-file index holds at most this many
#: (rows: starts x views); in ``bench_accuracy``'s silhouette runs a decision that searched
#: again among the voted action's windows took 1.5-2 ms more through the lists, at four
#: times their usual number, than the first search
SUBSET_FLAT = 20_000
#: the flat indexes of flagged windows hold at most this many rows in all (26 MB of
#: summaries at 32 numbers; bench_accuracy's folds hold 50,000-60,000 windows in all)
FLAT_ROWS = 200_000
#: starts summarised at a time while the index is filled (bounds the build's memory)
_CHUNK = 4096
#: windows up to which the short list is ``shortlist`` long; past it, it grows with the
#: square root of the windows: a large library holds more near twins of each window,
#: which crowd the exact best off a list of fixed length (``benchmarks/HISTORY.md``,
#: "the exact best window at 500k")
LIST_ROWS = 2_000_000


def _resample(query: FloatArray, length: int) -> FloatArray:
    m = query.shape[0]
    if m == length:
        return query
    t = np.linspace(0.0, m - 1.0, length)
    lo = np.floor(t).astype(np.int64)
    hi = np.minimum(lo + 1, m - 1)
    w = (t - lo)[:, None]
    return query[lo] * (1.0 - w) + query[hi] * w


def _principal_axes(centred: NDArray[np.floating], k: int) -> NDArray[np.float32]:
    """The ``k`` principal axes ``(d, k)`` of ``centred (n, d)`` rows, largest variance
    first: the eigenvectors of the ``d x d`` scatter matrix (the right singular vectors
    an SVD of the rows gives, in a twentieth of its time at 50,000 x 250), each signed
    so that its largest entry is positive (one basis on every run)."""
    _, vecs = np.linalg.eigh(centred.T @ centred)
    axes = vecs[:, ::-1][:, :k]
    top = np.argmax(np.abs(axes), axis=0)
    axes = axes * np.where(axes[top, np.arange(axes.shape[1])] < 0, -1.0, 1.0)
    return np.ascontiguousarray(axes, dtype=np.float32)


class WindowIndex:
    """Nearest windows of a multi-view feature table to a query, by DTW.

    Parameters
    ----------
    shape, centre : ``(N, V, S)`` and ``(N, V, 2)``, as ``vision._matcher.window_tables``
        makes them (a window's centre is taken relative to its first frame).
    starts : the frames a window may start at (each with ``length`` frames ahead).
    length : window length in frames.
    dims, segments : PCA dimensions and PAA segments of the summaries.
    shortlist : summaries taken from the broad phase per query, up to ``LIST_ROWS``
        windows (more: this times the square root of their ratio).
    flat_below : fewer windows than this are scanned exactly (faiss ``IndexFlatL2``);
        more go into an inverted-file index of 8-bit summaries (``IndexIVFScalarQuantizer``,
        ``nprobe`` lists searched); either way exact DTW ranks the short list.
    progress : ``progress(done, total)`` as the index is made, in windows: those put in
        a flat index; for the lists, half a window each as its summary is taken and as
        it is added (the lists are trained between, uncounted).
    work, cluster : for the lists, where their jobs keep their parts (a folder of these
        tables: a stopped build resumes from it; ``None``: a temporary one), and where
        they run (``vision._summaries.fill_lists``).
    """

    def __init__(
        self,
        shape: ShapeTable,
        centre: FloatArray,
        starts: IntArray,
        length: int,
        dims: int = 32,
        segments: int = 5,
        shortlist: int = 96,
        seed: int = 0,
        flat_below: int = 20_000,
        built: tuple[NDArray[np.float32], NDArray[np.float32], Any, int] | None = None,
        progress: Progress | None = None,
        work: Path | None = None,
        cluster: str | None = None,
    ) -> None:
        import faiss

        if shape.ndim != 3 or centre.shape != (*shape.shape[:2], 2):
            raise ValueError("shape must be (N, V, S) and centre (N, V, 2)")
        starts = np.ascontiguousarray(starts, dtype=np.int64)
        if starts.size and (starts.min() < 0 or starts.max() + length > shape.shape[0]):
            raise ValueError("every window must lie inside the table")
        self.shape = np.ascontiguousarray(shape, dtype=SHAPE_DTYPE)
        self.centre = np.ascontiguousarray(centre, dtype=np.float64)
        self.starts = starts
        self.length = int(length)
        self.n_views = shape.shape[1]
        rows = starts.size * self.n_views
        self.shortlist = max(int(shortlist), round(int(shortlist) * math.sqrt(rows / LIST_ROWS)))
        self.bounds = _bounds(self.length, segments)
        self._ok = np.zeros(shape.shape[0], dtype=bool)
        self._ok[starts] = True
        faiss.omp_set_num_threads(1)  # one core, and the same index on every run
        self._selected: dict[bytes, tuple[Any, Any, NDArray[np.uint8]]] = {}
        self._flat: dict[bytes, tuple[Any, IntArray]] = {}  # (``_among``)
        self._flat_rows = 0
        self.index: Any
        #: how long an inverted file's passes took as it was made (``fill_lists``)
        self.seconds: dict[str, float] = {}
        if built is not None:  # (mean, basis, faiss index, nprobe) of the same build
            self.mean, self.basis, self.index, self.nprobe = built
        else:
            self._build(dims, seed, flat_below, progress, work, cluster)

    def _build(
        self,
        dims: int,
        seed: int,
        flat_below: int,
        progress: Progress | None,
        work: Path | None,
        cluster: str | None,
    ) -> None:
        """Make the index (``dims``, ``seed``, ``flat_below``, ``progress``, ``work``,
        ``cluster``: the class's)."""
        import faiss

        starts = self.starts
        v = self.n_views  # row r of the index: start r // V, view r % V
        rows = starts.size * v
        rng = np.random.default_rng(seed)
        pick = rng.choice(rows, min(rows, 50_000), replace=False)
        sample = _summaries(
            self.shape, self.centre, starts[pick // v], self.length, self.bounds, pick % v
        )
        self.mean = sample.mean(axis=0)
        k = max(1, min(dims, sample.shape[1], sample.shape[0]))
        self.basis = _principal_axes(sample - self.mean, k)
        halves = [0]  # windows done, in halves (a pass of two counts a half each)

        def count(done: int, passes: int) -> None:
            halves[0] += done * (2 // passes)
            if progress is not None:
                progress(halves[0] // 2, rows)

        # an exact broad phase where a flat scan is fast enough (a 48,000-window fold of
        # bench_accuracy: 0.8 ms a query flat, against about 0.1 ms through the lists,
        # with every decision of its 12 runs the same)
        if rows < flat_below:
            self.index = faiss.IndexFlatL2(k)
            self.nprobe = 0
            for z in self._projected_chunks():
                self.index.add(z)
                count(z.shape[0], 1)
        else:
            self._lists(rows, k, seed)
            train = rng.choice(rows, min(rows, 64 * int(self.index.nlist)), replace=False)
            fill_lists(self, train, count, work, cluster, _CHUNK)

    def _lists(self, rows: int, k: int, seed: int) -> None:
        """An empty inverted-file index for ``rows`` summaries of ``k`` numbers (its
        k-means seeded by ``seed``)."""
        import faiss

        nlist = int(min(4096, max(16, 2 * math.sqrt(rows))))
        quantizer = faiss.IndexFlatL2(k)
        # each summary stored as 8-bit numbers: a quarter of the float32 lists to scan
        # and to store (500k frames: 7.5 ms p99 a decision against 14 ms, 0.35 GB
        # against 1.18 GB, the same best window in all 340 decisions of bench_scale's)
        self.index = faiss.IndexIVFScalarQuantizer(
            quantizer, k, nlist, faiss.ScalarQuantizer.QT_8bit
        )
        # 1/32 of the lists, at least 32 and at most 64, are scanned: the exact best
        # window is found as often at 64 of 4,096 lists as at 128 (the short list decides
        # that), in half the time
        self.nprobe = max(32, min(64, nlist // 32))
        self.index.nprobe = self.nprobe
        self.index.cp.seed = seed

    def _projected_chunks(self) -> Iterator[NDArray[np.float32]]:
        """The PCA'd summaries of every index row (start ``r // V``, view ``r % V``), a
        chunk of ``_CHUNK`` starts at a time."""
        yield from projected(
            self.shape,
            self.centre,
            self.starts,
            self.length,
            self.bounds,
            self.mean,
            self.basis,
            _CHUNK,
        )

    @property
    def size(self) -> int:
        """Windows indexed (starts x views)."""
        return int(self.index.ntotal)

    def summary(self, query: FloatArray) -> NDArray[np.float32]:
        """The PCA'd PAA summary of a query ``(m, S + 2)``."""
        q = _resample(np.asarray(query, dtype=np.float64), self.length)
        s = q.shape[1] - 2
        csum = np.concatenate((np.zeros((1, q.shape[1])), np.cumsum(q, axis=0)))
        parts = []
        for a, b in itertools.pairwise(self.bounds):
            mean = (csum[b] - csum[a]) / float(b - a)
            mean[s:] -= q[0, s:]
            parts.append(mean)
        x = np.concatenate(parts).astype(np.float32)
        return np.ascontiguousarray(((x - self.mean) @ self.basis)[None], dtype=np.float32)

    def prepare(self, keys: IntArray) -> None:
        """Make the searches among the windows of each value of ``keys`` (one a table
        frame, -1 for none: ``search``'s ``only`` is ``keys == k``) ready now, not at the
        decision that first asks for one: those that get a flat index of their own
        (``_among``), while ``FLAT_ROWS`` allows (``vision.Performance`` does this for
        the library's actions at its start)."""
        if not self.nprobe:
            return  # (a flat index: searched through a bitmap, made in no time)
        k = keys[self.starts]
        rows = np.bincount(k[k >= 0]) * self.n_views
        for key in np.flatnonzero(rows):
            if self._fits_flat(int(rows[key])):
                self._among(keys == key)

    def _fits_flat(self, rows: int) -> bool:
        """Whether a search among ``rows`` flagged windows gets a flat index of its own
        (``_among``)."""
        return bool(self.nprobe) and rows <= SUBSET_FLAT and self._flat_rows + rows <= FLAT_ROWS

    def _among(self, only: NDArray[np.bool_]) -> tuple[Any, Any, IntArray | None]:
        """How to search only the windows starting where ``only`` (one flag a table
        frame) is set: ``(index, params, rows)``. At most ``SUBSET_FLAT`` of them, in an
        inverted-file index: a flat index of their own summaries, scanned exactly
        (``rows``: its rows' rows in the whole index), kept while such indexes hold at
        most ``FLAT_ROWS`` rows in all. Else the whole index with faiss's search
        parameters: a bitmap of its rows, and four times the inverted lists scanned (the
        nearest lists may hold few such windows), kept for the last few masks."""
        import faiss

        key = hashlib.blake2b(np.packbits(only).tobytes(), digest_size=16).digest()
        if key in self._flat:
            sub, ids = self._flat[key]
            return sub, None, ids
        if key not in self._selected:
            rows = np.repeat(only[self.starts], self.n_views)
            n = int(rows.sum())
            if self._fits_flat(n):
                ids = np.flatnonzero(rows).astype(np.int64)  # (every view of each start)
                v = self.n_views
                x = _run_summaries(
                    self.shape,
                    self.centre,
                    self.starts[ids[::v] // v],
                    self.length,
                    self.bounds,
                ).reshape(n, -1)
                sub = faiss.IndexFlatL2(self.basis.shape[1])
                if ids.size:
                    sub.add(np.ascontiguousarray((x - self.mean) @ self.basis, dtype=np.float32))
                self._flat[key] = (sub, ids)
                self._flat_rows += n
                return sub, None, ids
            bitmap = np.packbits(rows, bitorder="little")
            sel = faiss.IDSelectorBitmap(rows.size, faiss.swig_ptr(bitmap))
            params: Any = faiss.SearchParametersIVF() if self.nprobe else faiss.SearchParameters()
            params.sel = sel
            if self.nprobe:
                params.nprobe = min(int(self.index.nlist), 4 * self.nprobe)
            if len(self._selected) >= 8:
                self._selected.pop(next(iter(self._selected)))
            self._selected[key] = (params, sel, bitmap)  # (faiss keeps no reference)
        return self.index, self._selected[key][0], None

    def shortlisted(
        self, query: FloatArray, only: NDArray[np.bool_] | None = None, readings: int = 2
    ) -> tuple[IntArray, IntArray]:
        """``(starts, views)`` of the broad phase's windows for ``query``, one of
        ``readings`` of the performer searched together, each with its neighbours one
        frame earlier and later (where those may start a window; with ``only``, only
        where it is set)."""
        index, params, rows = (self.index, None, None) if only is None else self._among(only)
        # flagged windows are fewer: half the short list (the same label agreement in all
        # 12 runs of bench_accuracy; a decision's p99 at worst 6.5 -> 6.0 ms)
        k = self.shortlist if only is None else max(1, self.shortlist // 2)
        # the list is per pair of readings (a silhouette as seen and mirrored): the pose
        # descriptor's four (left and right swapped too) share two lists' worth (in
        # bench_accuracy's 12 runs the same label agreement, the pose score within 0.004,
        # a decision's p99 4.5-8.2 -> 2.6-5.4 ms)
        k = max(1, k * 2 // max(2, readings))
        _, ids = index.search(self.summary(query), k, params=params)
        ids = ids[0][ids[0] >= 0]
        if rows is not None:
            ids = rows[ids]
        s = self.starts[ids // self.n_views]
        v = ids % self.n_views
        s = np.concatenate((s, s - 1, s + 1))
        v = np.concatenate((v, v, v))
        keep = (s >= 0) & (s < self._ok.size)
        s, v = s[keep], v[keep]
        keep = self._ok[s] if only is None else self._ok[s] & only[s]
        key = np.unique(s[keep] * self.n_views + v[keep])
        return (key // self.n_views).astype(np.int64), (key % self.n_views).astype(np.int64)

    def search(
        self,
        queries: list[FloatArray],
        band: int,
        top: int = 1,
        only: NDArray[np.bool_] | None = None,
        ranked: list[tuple[IntArray, IntArray, FloatArray]] | None = None,
        recency: float = 0.0,
    ) -> list[tuple[int, int, float]]:
        """The ``top`` windows ``(start, view, cost)`` nearest any of ``queries`` by
        exact DTW (band ``band``) among the broad phase's short lists, cheapest first,
        at most one per start; with ``only`` (a flag for each table frame), only windows
        that start where it is set. ``ranked`` (a list) gets each query's short list and
        its costs, ``(starts, views, costs)``, for ``best_of``: one a query, in order.
        ``recency``: the queries' last frames weigh more in DTW (``control.dtw``; the
        broad phase's summaries weigh every frame alike)."""
        if only is not None and only.shape != self._ok.shape:
            raise ValueError(f"only must flag each of the {self._ok.size} table frames")
        lists = []
        for q in queries:
            q = np.ascontiguousarray(q, dtype=np.float64)
            s, v = self.shortlisted(q, only, len(queries))
            cost = (  # (one list a query, empty or not: ``ranked`` keeps the readings' order)
                dtw_windows(q, self.shape, self.centre, s, v, self.length, band, recency)
                if s.size
                else np.zeros(0)
            )
            lists.append((s, v, cost))
        if ranked is not None:
            ranked.extend(lists)
        return best_of(lists, top)


def best_of(
    lists: list[tuple[IntArray, IntArray, FloatArray]],
    top: int,
    only: NDArray[np.bool_] | None = None,
) -> list[tuple[int, int, float]]:
    """The ``top`` cheapest windows ``(start, view, cost)`` of ranked short lists
    (``WindowIndex.search``'s ``ranked``), at most one per start; with ``only``, only
    those whose start it flags."""
    best: dict[int, tuple[int, int, float]] = {}
    for s, v, cost in lists:
        pick = np.argsort(cost, kind="stable")
        if only is not None:
            pick = pick[only[s[pick]]]
        for i in pick[: max(top * 4, top)]:
            si = int(s[i])
            if si not in best or cost[i] < best[si][2]:
                best[si] = (si, int(v[i]), float(cost[i]))
    return sorted(best.values(), key=lambda r: (r[2], r[0]))[:top]
