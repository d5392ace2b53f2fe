"""A metric learned from the bank itself: which differences between silhouettes are pose,
and which are only body, shadow or camera?

The bank can render any library frame as other performers would look: other body widths,
a shadow at the feet, cameras higher and lower and between the ring's views. Each
(frame, view) is then a class whose members differ in everything but the pose; linear
discriminant analysis (scikit-learn's ``LinearDiscriminantAnalysis``, eigen solver with
a little shrinkage) finds the few directions of the shape numbers along which classes
differ most relative to how much each class varies (``lda_directions``: the same
solution computed in one pass over the data, where scikit-learn's loops over classes
took 7 of a bank's first 35 s; tested against it). The matcher compares silhouettes
along those directions only (``Bank.metric``), which both carries over to performers the
library has not seen (``benchmarks/bench_recognition.py``) and makes DTW cheaper (24
numbers a frame instead of 168).

Each chosen frame is seen 24 ways; the silhouettes with a shadow are those without plus
the blob (``motion_features_both``), so each camera rasterizes a frame once for both.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from control.motion import Clip, Motion

from ._body import BodyShape, capsule_body
from ._camera import CameraRing
from ._descriptor import get_descriptor
from ._render import motion_features_both

__all__ = [
    "METRIC_FRAMES",
    "MetricJob",
    "fit_metric",
    "lda_directions",
    "learn_metric",
    "metric_jobs",
    "metric_rings",
    "metric_samples",
]

FloatArray = NDArray[np.float64]

#: at most this many library frames (spread evenly) teach the metric
METRIC_FRAMES = 400
_WIDTHS = (1.0, 0.9, 1.1, 1.25)


def metric_rings(ring: CameraRing) -> list[CameraRing]:
    """The cameras of the learning set: the ring itself, and rings 0.3 m lower and 0.4 m
    higher, turned 7 degrees either way (between the ring's views)."""
    return [
        ring,
        dataclasses.replace(ring, height=ring.height - 0.3, azimuth_offset=ring.azimuth_offset + 7),
        dataclasses.replace(ring, height=ring.height + 0.4, azimuth_offset=ring.azimuth_offset - 7),
    ]


@dataclass(frozen=True)
class MetricJob:
    """One clip's chosen frames seen with one body width: every view of the learning
    rings, each with and without a shadow (``metric_samples``)."""

    clip: int  # the clip's place in the library: its frames make its own classes
    motion: Motion
    frames: NDArray[np.int64]
    body: BodyShape
    rings: tuple[CameraRing, ...]
    descriptor: str


def metric_jobs(
    clips: Sequence[Clip],
    descriptor: str,
    ring: CameraRing,
    body: BodyShape,
    max_frames: int = METRIC_FRAMES,
) -> list[MetricJob]:
    """The renders that teach the metric (``learn_metric``): up to ``max_frames`` frames
    of ``clips`` (evenly spread), one job per clip and body width, in order."""
    desc = get_descriptor(descriptor)
    if desc.kind != "silhouette":
        raise ValueError(f"a learned metric is for silhouette descriptors, not {descriptor!r}")
    total = sum(c.motion.n_frames for c in clips)
    if total == 0:
        raise ValueError("no frames to learn a metric from")
    every = max(1, math.ceil(total / max_frames))
    rings = tuple(metric_rings(ring))
    jobs = []
    for i, clip in enumerate(clips):
        frames = np.arange(0, clip.motion.n_frames, every)
        if frames.size:
            for w in _WIDTHS:
                shape = BodyShape(body.width * w, body.height, body.legs, body.arms)
                jobs.append(MetricJob(i, clip.motion, frames, shape, rings, desc.name))
    return jobs


def metric_samples(job: MetricJob) -> NDArray[np.float32]:
    """The shape numbers ``(n, V, 2 * rings, S)`` of a job's frames: without a shadow
    then with one, each ring in turn."""
    desc = get_descriptor(job.descriptor)
    cap = capsule_body(job.motion.skeleton, job.body)
    seen = [
        motion_features_both(job.motion, cap, r, job.frames, descriptor=desc.name)
        for r in job.rings
    ]
    return np.stack([desc.shape(both[sh][0]) for sh in (0, 1) for both in seen], axis=2)


def fit_metric(
    jobs: Sequence[MetricJob], samples: Sequence[NDArray[np.float32]], dims: int
) -> tuple[FloatArray, FloatArray]:
    """``(mean (S,), projection (S, dims))`` of the ``samples`` of ``jobs``: each (frame,
    view) of a clip a class, its members every width, shadow and ring."""
    xs, ys = [], []
    label = 0
    for c in sorted({j.clip for j in jobs}):
        x = np.concatenate([s for j, s in zip(jobs, samples, strict=True) if j.clip == c], axis=2)
        n, v, k, s = x.shape  # (n, V, widths x shadows x rings, S)
        xs.append(x.reshape(n * v * k, s).astype(np.float64))
        ys.append(label + np.repeat(np.arange(n * v), k))
        label += n * v
    x = np.concatenate(xs)
    y = np.concatenate(ys)
    ok = np.isfinite(x).all(axis=1)
    x, y = x[ok], y[ok]
    dims = min(dims, x.shape[1], np.unique(y).size - 1)
    mean = x.mean(axis=0)  # (the eigen solver does not centre; distances do not care)
    return mean, lda_directions(x, y, dims, shrinkage=1e-3)


def learn_metric(
    clips: Sequence[Clip],
    descriptor: str,
    ring: CameraRing,
    body: BodyShape,
    dims: int,
    max_frames: int = METRIC_FRAMES,
) -> tuple[FloatArray, FloatArray]:
    """``(mean (S,), projection (S, dims))``: shape numbers ``x`` are compared as
    ``(x - mean) @ projection``. Learned from up to ``max_frames`` frames of ``clips``
    (evenly spread), each seen by every view of ``metric_rings(ring)`` with bodies of
    widths 1, 0.9, 1.1, 1.25 (times ``body``), each with and without a shadow. (A bank's
    build runs ``metric_jobs`` in its worker processes beside its shards.)"""
    jobs = metric_jobs(clips, descriptor, ring, body, max_frames)
    return fit_metric(jobs, [metric_samples(j) for j in jobs], dims)


def _shrunk(cov: FloatArray, shrinkage: float) -> FloatArray:
    out = (1.0 - shrinkage) * cov
    out.flat[:: cov.shape[0] + 1] += shrinkage * np.trace(cov) / cov.shape[0]
    return out


def lda_directions(
    x: FloatArray, y: NDArray[np.integer], dims: int, shrinkage: float = 1e-3
) -> FloatArray:
    """The ``dims`` leading discriminant directions ``(S, dims)`` of samples ``x``
    ``(N, S)`` in classes ``y`` ``(N,)``: scikit-learn's
    ``LinearDiscriminantAnalysis(solver="eigen", shrinkage=shrinkage).scalings_``.

    Its within-class scatter is the class-prior-weighted sum of each class's shrunk
    covariance; with priors ``n_c / N`` that sum is the shrunk covariance of all the
    samples less their class means, which one matrix product gives. The directions
    solve ``Sb v = lambda Sw v`` (``Sb = St - Sw``, ``St`` the shrunk total covariance),
    largest ``lambda`` first, normalised so that ``v' Sw v = 1``."""
    from scipy.linalg import eigh

    x = np.asarray(x, dtype=np.float64)
    _, inv, counts = np.unique(np.asarray(y), return_inverse=True, return_counts=True)
    if not 0 < dims <= min(x.shape[1], counts.size - 1):
        raise ValueError(
            f"dims must be in 1..{min(x.shape[1], counts.size - 1)} "
            f"({counts.size} classes of {x.shape[1]} numbers), not {dims}"
        )
    means = np.stack([np.bincount(inv, weights=col) for col in x.T], axis=1) / counts[:, None]
    within = x - means[inv]
    sw = _shrunk(within.T @ within / x.shape[0], shrinkage)
    centred = x - x.mean(axis=0)
    st = _shrunk(centred.T @ centred / x.shape[0], shrinkage)
    evals, evecs = eigh(st - sw, sw)
    return np.asarray(evecs[:, np.argsort(evals)[::-1][:dims]], dtype=np.float64)
