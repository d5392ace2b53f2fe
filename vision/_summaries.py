"""The windows' summaries (``WindowIndex``'s broad phase) and how its inverted lists are
filled with them.

A window's summary is the mean of each of a few stretches of its frames (PAA) of the
numbers DTW compares, reduced by PCA. Past ``flat_below`` windows the index is an inverted
file (``fill_lists``): every window's summary is taken in jobs of ``JOB_STARTS`` starts,
here or on a cluster (``control.jobs``), each job's summaries kept as a part in a folder
(``control.jobs.JobStore``), so that a stopped build resumes from the parts it finished
and every summary is never held at once (500k frames: 8.6 million windows, 1.1 GB as
float32); the lists are trained on a sample of them (kept in faiss's order: its
seeding), then filled from the parts one at a time. A job carries its slice of the
tables, so a cluster's workers need no copy of them, and its summaries are the ones this
machine would take, number for number: the index is the local build's.
"""

from __future__ import annotations

import contextlib
import hashlib
import itertools
import tempfile
import time
from collections.abc import Callable, Iterator
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
    seconds of each pass go into ``win.seconds`` (``jobs``, ``train``, ``fill``), with
    the jobs ``resumed`` from parts."""
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
        todo = []
        for i in range(len(spans)):
            if (got := store.read(i, ("z",))) is None:
                todo.append(i)
            else:
                take(i, got["z"])

        def finished(j: int, z: NDArray[np.float32]) -> None:
            store.save(todo[j], {"z": z})
            take(todo[j], z)

        jobs = [_slice(win, *spans[i]) for i in todo]
        shared = (win.length, win.bounds, win.mean, win.basis, chunk)
        t0 = time.perf_counter()
        run_jobs(_summary_job, jobs, finished, 1, cluster, shared)
        t1 = time.perf_counter()
        win.index.train(picked)
        t2 = time.perf_counter()
        for i in range(len(spans)):
            got = store.read(i, ("z",))
            if got is None:  # (removed or damaged since it was written)
                raise RuntimeError(f"{folder}: the part of job {i} is gone; build again")
            win.index.add(got["z"])
            count(got["z"].shape[0], 2)
        win.seconds.update(
            jobs=t1 - t0,
            train=t2 - t1,
            fill=time.perf_counter() - t2,
            resumed=len(spans) - len(todo),
        )


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
