"""The performer's query sequences and the library's window tables, as the matcher and
its global search compare them: the shape numbers mapped by the bank's metric (or the
descriptor's standardisation), the centre's displacement in body sizes, the per-frame
cost and the best window by exact DTW."""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from control.dtw import SHAPE_DTYPE, ShapeTable, dtw_best_window, dtw_windows
from silhouette_bank import DEFAULT_DESCRIPTOR, Bank, Descriptor, get_descriptor

__all__ = [
    "PHASE_FRAMES",
    "bank_sequences",
    "best_window",
    "per_frame_cost",
    "performer_queries",
    "performer_sequence",
    "phased_targets",
    "retimed",
    "shape_stats",
    "tempo_readings",
    "window_costs",
    "window_tables",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


def shape_stats(bank: Bank) -> tuple[FloatArray, FloatArray]:
    """``(mean (S,), proj (S, d))``: DTW compares shape numbers ``x`` as
    ``(x - mean) @ proj``. With the bank's learned metric: its projection, scaled so that
    the ``d`` numbers vary as much in all as 7 standardised numbers; otherwise the
    descriptor's standardiser (``proj`` diagonal, ``d = S``)."""
    desc = bank.settings.features
    x = desc.shape(bank.features).reshape(-1, desc.n_shape)
    x = x[:: max(1, x.shape[0] // 200_000)].astype(np.float64)  # a large bank: a sample
    x = x[np.isfinite(x).all(axis=1)]
    if bank.metric is not None:
        mean, proj = bank.metric
        z = (x - mean) @ proj
        spread = float(np.sqrt(z.var(axis=0).sum() / 7.0)) if z.size else 1.0
        return mean, proj / max(spread, 1e-9)
    mean, scale = desc.standardiser(x)
    return mean, np.diag(1.0 / scale)


def performer_sequence(
    features: FloatArray,
    mean: FloatArray,
    proj: FloatArray,
    centre_weight: float,
    descriptor: Descriptor | str = DEFAULT_DESCRIPTOR,
) -> FloatArray:
    """DTW features ``(n, d + 2)`` of a performer's raw features ``(n, F)`` of
    ``descriptor`` (shape numbers, then the centre in image coordinates / body size):
    the shape numbers mapped by ``shape_stats``'s ``(mean, proj)``, the centre's
    displacement since the first frame times ``centre_weight``."""
    desc = get_descriptor(descriptor)
    d = proj.shape[1]
    out = np.empty((features.shape[0], d + 2))
    out[:, :d] = (desc.shape(features) - mean) @ proj
    c = desc.centre(features)
    out[:, d:] = (c - c[0]) * centre_weight
    return out


def performer_queries(
    performer: FloatArray,
    desc: Descriptor,
    mean: FloatArray,
    proj: FloatArray,
    centre_weight: float,
    mirror: bool | None = None,
) -> list[FloatArray]:
    """DTW queries of a performer's features ``(n, F)`` without NaN rows: one per
    reading of ``desc.variants`` (as seen; with ``mirror``, by default the descriptor's
    ``reads_mirrored``, also mirrored, and for landmarks with the sides swapped)."""
    return [
        performer_sequence(np.asarray(v, dtype=np.float64), mean, proj, centre_weight, desc)
        for v in desc.variants(performer, mirror)
    ]


def bank_sequences(
    bank: Bank, rows: IntArray, mean: FloatArray, proj: FloatArray, centre_weight: float
) -> FloatArray:
    """DTW features ``(V, n, F)`` of the bank's frames ``rows`` in every view: as
    ``performer_sequence`` makes them, the centre from the root's image motion
    accumulated plus the centre relative to the root."""
    desc = bank.settings.features
    f = bank.features[rows].astype(np.float64)  # (n, V, F)
    move = bank.root_motion[rows].astype(np.float64)  # (n, V, 2)
    k = proj.shape[1]
    out = np.empty((*f.shape[:2], k + 2))
    out[..., :k] = (desc.shape(f) - mean) @ proj
    path = np.cumsum(move, axis=0) - move[0]
    centre = path + desc.centre(f)
    out[..., k:] = (centre - centre[0]) * centre_weight
    return np.nan_to_num(out.transpose(1, 0, 2), nan=0.0)


def window_tables(
    bank: Bank,
    frames: IntArray,
    clip_start: IntArray,
    mean: FloatArray,
    proj: FloatArray,
    centre_weight: float,
    out: tuple[ShapeTable, FloatArray] | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[ShapeTable, FloatArray]:
    """What the whole-library window search compares: for rows ``frames`` (bank frames;
    ``clip_start`` splits them into clips), the mapped shape numbers ``(N, V, d)``
    and the centre accumulated along each clip ``(N, V, 2)``, times ``centre_weight``
    (a window's centre is taken relative to its first frame by the DTW kernel); written
    into ``out`` (float32 and float64 arrays of those shapes: memory maps) when given.
    ``progress(done, total)`` counts the frames done."""
    desc = bank.settings.features
    n, v = frames.size, bank.features.shape[1]
    if out is None:
        out = (np.empty((n, v, proj.shape[1]), dtype=SHAPE_DTYPE), np.empty((n, v, 2)))
    shape, centre = out
    for a in range(0, n, 2048):  # in blocks: a bank of many views is large in float64
        f = bank.features[frames[a : a + 2048]].astype(np.float64)  # (b, V, F)
        b = a + f.shape[0]
        shape[a:b] = np.nan_to_num((desc.shape(f) - mean) @ proj, nan=0.0)
        centre[a:b] = desc.centre(f)
        if progress is not None and b < n:
            progress(b, n)
    move = bank.root_motion[frames].astype(np.float64)
    for a, b in itertools.pairwise(clip_start):
        centre[a:b] += np.cumsum(move[a:b], axis=0) - move[a]
    centre *= centre_weight
    np.nan_to_num(centre, copy=False, nan=0.0)
    if progress is not None:
        progress(n, n)
    return shape, centre


def window_costs(
    queries: list[FloatArray],
    shape: ShapeTable,
    centre: FloatArray,
    start: int,
    length: int,
    band: int,
    recency: float = 0.0,
) -> FloatArray:
    """DTW costs ``(len(queries), V)`` of the window of the tables at ``start`` against
    each of ``queries``, in every view (``recency``: ``control.dtw``'s)."""
    views = np.arange(shape.shape[1], dtype=np.int64)
    at = np.full(views.size, start, dtype=np.int64)
    return np.array(
        [dtw_windows(q, shape, centre, at, views, length, band, recency) for q in queries]
    )


def per_frame_cost(cost: float, length: int) -> float:
    """A DTW cost of a query of ``length`` frames as a per-frame cost (over the square
    root of the length): the scale of ``Descriptor.reject``."""
    return cost / float(np.sqrt(max(length, 1)))


def best_window(
    queries: list[FloatArray],
    shape: ShapeTable,
    centre: FloatArray,
    starts: IntArray,
    length: int,
    band: int,
    recency: float = 0.0,
) -> tuple[int, int, float]:
    """``(start, view, cost)`` of the window nearest any of ``queries`` by DTW
    (``control.dtw.dtw_best_window``), over ``starts``, every view."""
    best = (-1, -1, float("inf"))
    for q in queries:
        got = dtw_best_window(q, shape, centre, starts, length, band, recency)
        if got[2] < best[2]:
            best = got
    return best


#: frames of the performer's last (0.2 s at 15 frames/s) that place a window's end
PHASE_FRAMES = 3


def phased_targets(
    target: IntArray,
    views: IntArray,
    queries: list[FloatArray],
    shape: ShapeTable,
    runs: IntArray,
    shift: int,
) -> IntArray:
    """Each ``target`` (the frame after a window, where the performer is now, seen from
    table view ``views``), moved by up to ``shift`` frames within its clip's run
    (``runs``: a run id per table frame) to where the library's last ``PHASE_FRAMES``
    frames before it are nearest the performer's last (``queries``' shape numbers, the
    nearer reading, no time warping). DTW places a window's end loosely: its band lets
    the last frames slide, and the window costs about the same."""
    if shift <= 0 or target.size == 0:
        return target
    n, d = shape.shape[0], shape.shape[2]
    step = np.arange(-shift, shift + 1)
    end = target[:, None] - 1 + step[None, :]  # the window's last frame, moved
    m = min(PHASE_FRAMES, *(q.shape[0] for q in queries))
    lo = end - m + 1
    home = runs[np.clip(target - 1, 0, n - 1)][:, None]
    ok = (lo >= 0) & (end + 1 < n)
    ok &= (runs[np.clip(lo, 0, n - 1)] == home) & (runs[np.clip(end + 1, 0, n - 1)] == home)
    rows = np.clip(lo[..., None] + np.arange(m), 0, n - 1)  # (K, 2 shift + 1, m)
    tab = shape[rows, views[:, None, None]].astype(np.float64)  # (K, 2 shift + 1, m, d)
    cost = np.min(
        [np.sum((tab - q[None, None, -m:, :d]) ** 2, axis=(-1, -2)) for q in queries], axis=0
    )
    cost[~ok] = np.inf
    cost[:, shift] = np.where(ok[:, shift], cost[:, shift], -np.inf)  # (unmoved: never worse)
    best = np.argmin(cost, axis=1)
    return np.asarray(target + step[best], dtype=np.int64)


def retimed(performer: FloatArray, span: int, rows: int) -> FloatArray | None:
    """The performer's last ``span`` frames ``(span, F)`` resampled to ``rows`` frames
    (linearly, over the frames with features); ``None`` when fewer than ``span`` frames
    are there or fewer than half of them have features."""
    if span < 2 or performer.shape[0] < span or span == rows:
        return None
    seg = performer[-span:]
    ok = np.isfinite(seg).all(axis=1)
    if ok.sum() < max(2, span // 2):
        return None
    t = np.flatnonzero(ok).astype(np.float64)
    at = np.linspace(0.0, span - 1.0, rows)
    good = seg[ok]
    return np.stack([np.interp(at, t, good[:, j]) for j in range(seg.shape[1])], axis=1)


def tempo_readings(
    performer: FloatArray,
    n: int,
    tempos: Sequence[float],
    rows: int,
    desc: Descriptor,
    mean: FloatArray,
    proj: FloatArray,
    centre_weight: float,
) -> list[FloatArray]:
    """DTW queries of the performer's features ``(m, F)`` read at each of ``tempos``
    against the library's (0.6: the performer moves at 0.6 times its speed, so their
    last ``n / 0.6`` frames stand for a window of ``n``), ``retimed`` to ``rows`` frames
    and read as seen only; a tempo without enough frames gives none."""
    out: list[FloatArray] = []
    for tempo in tempos:
        got = retimed(performer, round(n / tempo), rows)
        if got is not None:
            out += performer_queries(got, desc, mean, proj, centre_weight, False)
    return out
