"""The windows' summaries (``WindowIndex``'s broad phase) and how its inverted lists are
filled with them.

A window's summary is the mean of each of a few stretches of its frames (PAA) of the
numbers DTW compares, reduced by PCA. Past ``flat_below`` windows the index is an inverted
file (``fill_lists``), made in two passes of jobs, here or on a cluster
(``control.jobs``). The first takes every window's summary, ``JOB_STARTS`` starts a job;
the lists are then trained here on a sample of them (kept in faiss's order: its
seeding). The second encodes each job's summaries for the trained lists (which list,
and the 8-bit code: the quantizer's search, most of filling's time), and the codes are
added here in the jobs' order. Each job's result is kept as a part in a folder
(``control.jobs.JobStore``), so that a stopped build resumes from the parts it finished
and every summary is never held at once (500k frames: 8.6 million windows, 1.1 GB as
float32). A job carries its data (a first-pass job its slice of the tables, a second-pass
job its summaries and, once for each worker, the trained lists), so a cluster's workers
need no copy of anything, and its results are the ones this machine would make, number
for number: the index is the local build's.
"""

from __future__ import annotations

import contextlib
import hashlib
import itertools
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from control.dtw import ShapeTable
from control.jobs import JobStore, run_jobs

if TYPE_CHECKING:
    from ._index import WindowIndex

__all__ = ["JOB_STARTS", "fill_lists", "projected"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: starts a job of ``fill_lists`` summarises (in every view: 590,000 windows, 75 MB of
#: summaries, with the 18-view bank)
JOB_STARTS = 8 * 4096


def _bounds(length: int, segments: int) -> IntArray:
    p = max(1, min(segments, length))
    return np.round(np.linspace(0, length, p + 1)).astype(np.int64)


def _summaries(
    shape: ShapeTable,
    centre: FloatArray,
    starts: IntArray,
    length: int,
    bounds: IntArray,
    views: IntArray | None = None,
) -> NDArray[np.float32]:
    """PAA summaries ``(len(starts), V, P * D)`` of the windows at ``starts`` (with
    ``views``, ``(len(starts), P * D)``: each start's window in its view only)."""
    parts = []
    for a, b in itertools.pairwise(bounds):
        frames = [  # a segment's frames, summed
            np.concatenate((shape[f], centre[f]), axis=-1)
            if views is None
            else np.concatenate((shape[f, views], centre[f, views]), axis=-1)
            for f in (starts + k for k in range(int(a), int(b)))
        ]
        mean = np.sum(frames, axis=0) / float(b - a)
        base = centre[starts] if views is None else centre[starts, views]
        mean[..., shape.shape[2] :] -= base  # the centre relative to the window's start
        parts.append(mean)
    return np.concatenate(parts, axis=-1).astype(np.float32)


def _run_summaries(
    shape: ShapeTable, centre: FloatArray, starts: IntArray, length: int, bounds: IntArray
) -> NDArray[np.float32]:
    """``_summaries`` of the windows at ``starts`` in every view, each run of
    consecutive starts from prefix sums over its frames (a slice of the tables, not a
    gather a frame: about four times faster, the same numbers)."""
    d = shape.shape[2]
    out = np.empty((starts.size, shape.shape[1], (bounds.size - 1) * (d + 2)), np.float32)
    for run in np.split(np.arange(starts.size), np.flatnonzero(np.diff(starts) != 1) + 1):
        if not run.size:
            continue
        a, b = int(starts[run[0]]), int(starts[run[-1]]) + length
        x = np.concatenate((shape[a:b], centre[a:b]), axis=-1, dtype=np.float64)
        c = np.concatenate((np.zeros((1, *x.shape[1:])), np.cumsum(x, axis=0)))
        rel = starts[run] - a
        parts = []
        for lo, hi in itertools.pairwise(bounds):
            mean = (c[rel + hi] - c[rel + lo]) / float(hi - lo)
            mean[..., d:] -= x[rel, :, d:]  # the centre relative to the window's start
            parts.append(mean)
        out[run] = np.concatenate(parts, axis=-1)
    return out


def projected(
    shape: ShapeTable,
    centre: FloatArray,
    starts: IntArray,
    length: int,
    bounds: IntArray,
    mean: NDArray[np.float32],
    basis: NDArray[np.float32],
    chunk: int,
) -> Iterator[NDArray[np.float32]]:
    """The PCA'd summaries ``(rows, k)`` of the windows at ``starts`` in every view (row
    ``r``: start ``r // V``, view ``r % V``), ``chunk`` starts at a time."""
    for a in range(0, starts.size, chunk):
        x = _summaries(shape, centre, starts[a : a + chunk], length, bounds)
        z = (x.reshape(-1, x.shape[2]) - mean) @ basis
        yield np.ascontiguousarray(z, dtype=np.float32)


def _summary_job(shared: tuple[Any, ...], job: tuple[Any, ...]) -> NDArray[np.float32]:
    """One job of ``fill_lists``: the summaries of its starts, from its slice of the
    tables (``job``: the slices and the starts within them)."""
    length, bounds, mean, basis, chunk = shared
    shape, centre, starts = job
    return np.concatenate(
        list(projected(shape, centre, starts, length, bounds, mean, basis, chunk))
    )


def fill_lists(
    win: WindowIndex,
    train: IntArray,
    count: Callable[[int, int], None],
    work: Path | None,
    cluster: str | None,
    chunk: int,
) -> None:
    """Train ``win``'s empty inverted-file index on its rows ``train`` and fill it with
    every window's summary (the module says how), ``chunk`` starts at a time within a
    job. ``work``: the folder of the jobs' parts, kept until it is removed (``None``: a
    temporary one); ``cluster``: where the jobs run (``control.jobs.run_jobs``);
    ``count(rows, 2)`` as rows are summarised, and again as they are added. The
    seconds of each pass go into ``win.seconds`` (``jobs``, ``train``, ``encode``: the
    encoding jobs, ``fill``: adding their codes), with the summary jobs ``resumed`` from
    parts."""
    starts, v = win.starts, win.n_views
    spans = [(a, min(a + JOB_STARTS, starts.size)) for a in range(0, starts.size, JOB_STARTS)]
    order = np.argsort(train)
    first = train[order]
    picked = np.empty((train.size, win.basis.shape[1]), dtype=np.float32)

    def take(i: int, z: NDArray[np.float32]) -> None:  # job i's rows that train the lists
        a = spans[i][0] * v
        lo, hi = np.searchsorted(first, [a, a + z.shape[0]])
        picked[order[lo:hi]] = z[first[lo:hi] - a]
        count(z.shape[0], 2)

    with contextlib.ExitStack() as stack:
        folder = work or Path(stack.enter_context(tempfile.TemporaryDirectory()))
        store = JobStore(folder, _key(win, chunk))
        todo, finished = _resumed(store, len(spans), "z", take)
        jobs = [_slice(win, *spans[i]) for i in todo]
        shared = (win.length, win.bounds, win.mean, win.basis, chunk)
        t0 = time.perf_counter()
        run_jobs(_summary_job, jobs, finished, 1, cluster, shared)
        t1 = time.perf_counter()
        win.index.train(picked)
        t2 = time.perf_counter()
        adding = _encode(win, store, len(spans), count, cluster)
        win.seconds.update(
            jobs=t1 - t0,
            train=t2 - t1,
            encode=time.perf_counter() - t2 - adding,
            fill=adding,
            resumed=len(spans) - len(todo),
        )


def _encode(
    win: WindowIndex,
    store: JobStore,
    n_parts: int,
    count: Callable[[int, int], None],
    cluster: str | None,
) -> float:
    """The second pass of ``fill_lists``: each of the ``n_parts`` parts of ``store``
    encoded for ``win``'s trained lists in a job (its codes kept as a part beside them,
    under the trained lists' name), and the codes added to the lists in the parts'
    order (which fixes each window's number: row ``r`` is start ``r // V``, view ``r %
    V``), as they come in order. Returns the seconds spent adding."""
    import faiss

    trained = np.frombuffer(faiss.serialize_index(win.index), dtype=np.uint8)
    name = hashlib.sha256(trained.tobytes()).hexdigest()[:24]
    codes = JobStore(store.folder / "codes", f"{store.key}-{name}")
    waiting: dict[int, NDArray[np.uint8]] = {}
    added, adding = [0], [0.0]

    def add(i: int, got: NDArray[np.uint8]) -> None:
        waiting[i] = got
        while added[0] in waiting:  # (a cluster's results come in any order)
            z = waiting.pop(added[0])
            t0 = time.perf_counter()
            win.index.add_sa_codes(z)
            adding[0] += time.perf_counter() - t0
            count(z.shape[0], 2)
            added[0] += 1

    todo, finished = _resumed(codes, n_parts, "codes", add)
    run_jobs(_code_job, _Parts(store, todo), finished, 1, cluster, (name, trained))
    if added[0] != n_parts:  # (cannot happen: every part was added or encoded)
        raise RuntimeError(f"{store.folder}: {n_parts - added[0]} parts were not added")
    return adding[0]


def _resumed(
    store: JobStore, n_jobs: int, key: str, use: Callable[[int, Any], None]
) -> tuple[list[int], Callable[[int, Any], None]]:
    """The jobs of ``n_jobs`` that ``store`` holds no part of (``use(i, array)`` for
    each that it holds, in order), and what to call with the ``j``-th of them's result:
    it is kept as job ``todo[j]``'s part (array ``key``) and used."""
    todo = []
    for i in range(n_jobs):
        if (got := store.read(i, (key,))) is None:
            todo.append(i)
        else:
            use(i, got[key])

    def finished(j: int, out: Any) -> None:
        store.save(todo[j], {key: out})
        use(todo[j], out)

    return todo, finished


class _Parts(Sequence[NDArray[np.float32]]):
    """The summaries of the parts ``todo`` of ``store``, each read as its job is handed
    out (``control.jobs.run_jobs`` hands a cluster a few at a time), not all at once."""

    def __init__(self, store: JobStore, todo: list[int]) -> None:
        self.store, self.todo = store, todo

    def __len__(self) -> int:
        return len(self.todo)

    def __getitem__(self, j: int) -> NDArray[np.float32]:  # type: ignore[override]
        got = self.store.read(self.todo[j], ("z",))
        if got is None:  # (removed or damaged since it was written)
            raise RuntimeError(
                f"{self.store.folder}: the part of job {self.todo[j]} is gone; build again"
            )
        return got["z"]


#: the trained lists a worker process has read, by name (one a build)
_TRAINED: dict[str, Any] = {}


def _code_job(shared: tuple[str, NDArray[np.uint8]], z: NDArray[np.float32]) -> NDArray[np.uint8]:
    """One job of ``_encode``: the codes (``sa_encode``: the list, then the 8-bit code)
    of summaries ``z`` for the trained lists ``shared`` (their name and faiss's bytes)."""
    import faiss

    name, trained = shared
    if name not in _TRAINED:
        _TRAINED.clear()
        faiss.omp_set_num_threads(1)  # (one job a thread of the worker)
        _TRAINED[name] = faiss.deserialize_index(np.ascontiguousarray(trained))
    out: NDArray[np.uint8] = _TRAINED[name].sa_encode(np.ascontiguousarray(z, dtype=np.float32))
    return out


def _slice(win: WindowIndex, a: int, b: int) -> tuple[Any, Any, IntArray]:
    """The job of starts ``a:b``: the rows of the tables its windows cover, and its
    starts within them."""
    lo, hi = int(win.starts[a]), int(win.starts[b - 1]) + win.length
    return win.shape[lo:hi], win.centre[lo:hi], win.starts[a:b] - lo


def _key(win: WindowIndex, chunk: int) -> str:
    """What names a build's parts: the windows, the summaries' sizes and their PCA (the
    tables themselves are named by the folder, ``cached_window_index``'s)."""
    text = f"{win.shape.shape}|{win.length}|{win.bounds.tolist()}|{JOB_STARTS}|{chunk}"
    h = hashlib.sha256(text.encode())
    for a in (win.starts, win.mean, win.basis):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()[:24]
