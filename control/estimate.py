"""How long a cold build of a library takes here, said before it starts (``mimic library
info``): each step's time grows with the library's frames as ``bench_scale`` measured it
on the development machine, scaled by how fast this machine renders silhouettes against
that one; the bank's step is this machine's own rate, on its workers.

The figures are ``benchmarks/results/scale.json``'s (a 2-core x86_64 machine; rerun with
``python -m benchmarks.bench_scale ../shared/mocap``), on its synthetic library of
retimed copies: a library of distinct takes has fewer transitions and builds its graph
faster. An estimate, said as such.
"""

from __future__ import annotations

import math

__all__ = [
    "REFERENCE_BANK_RATE",
    "REFERENCE_RENDER_RATE",
    "REFERENCE_STEPS",
    "cold_build_seconds",
    "step_seconds",
]

#: seconds of each step at 10,000 / 50,000 / 200,000 / 500,000 frames on the development
#: machine (the graph ``mimic perform`` builds: relative root coordinates)
REFERENCE_STEPS: dict[str, tuple[tuple[int, float], ...]] = {
    "graph": ((10_000, 0.56), (50_000, 6.51), (200_000, 62.02), (500_000, 322.09)),
    "higher layer": ((10_000, 12.78), (50_000, 36.46), (200_000, 70.46), (500_000, 74.72)),
    "search index": ((10_000, 2.0), (50_000, 12.4), (200_000, 42.6), (500_000, 108.2)),
}
#: silhouettes a second ``silhouette_bank.render_rate`` measures there (on the shared
#: library's longest clip; the runs are in ``benchmarks/HISTORY.md``)
REFERENCE_RENDER_RATE = 14_000.0
#: silhouettes a second one worker put into a bank there, shards written and merged (18
#: views, 320x240, the outline): half what the render alone does
REFERENCE_BANK_RATE = 7000.0
#: seconds the bank's learned metric adds there, whatever the library's size
REFERENCE_METRIC_SECONDS = 18.4


def step_seconds(step: str, frames: int) -> float:
    """A step's seconds on the development machine for ``frames`` frames: between its
    measured sizes as a power of the frames, beyond them as the nearest pair's power."""
    points = REFERENCE_STEPS[step]
    if frames <= 0:
        return 0.0
    i = 0
    while i < len(points) - 2 and frames > points[i + 1][0]:
        i += 1
    (n0, t0), (n1, t1) = points[i], points[i + 1]
    power = math.log(t1 / t0) / math.log(n1 / n0)
    return t0 * (frames / n0) ** power


def cold_build_seconds(
    frames: int, views: int, render_rate: float, workers: int = 1
) -> dict[str, float]:
    """Each step's seconds for a library of ``frames`` frames built from nothing here
    (``render_rate``: what ``silhouette_bank.render_rate`` measures on this machine; the
    bank's ``views`` rendered on ``workers``), and ``"total"``."""
    if not (render_rate > 0 and workers >= 1 and views >= 1):
        raise ValueError("render_rate must be positive, workers and views at least 1")
    slower = REFERENCE_RENDER_RATE / render_rate
    out = {step: step_seconds(step, frames) * slower for step in REFERENCE_STEPS}
    bank_rate = REFERENCE_BANK_RATE / slower
    out["bank"] = frames * views / (bank_rate * workers) + REFERENCE_METRIC_SECONDS * slower
    out["total"] = sum(out.values())
    return out
