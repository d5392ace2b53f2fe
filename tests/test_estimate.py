"""The cold build's estimate (``control.estimate``): bench_scale's figures where it
measured, a power of the frames between and beyond, scaled by this machine's rate."""

from __future__ import annotations

import itertools

import pytest

from control.estimate import (
    REFERENCE_BANK_RATE,
    REFERENCE_RENDER_RATE,
    REFERENCE_STEPS,
    cold_build_seconds,
    step_seconds,
)


def test_each_step_is_the_measured_time_where_it_was_measured_and_grows_between() -> None:
    for step, points in REFERENCE_STEPS.items():
        for frames, seconds in points:
            assert step_seconds(step, frames) == pytest.approx(seconds)
        sizes = [10_000, 50_000, 120_000, 200_000, 350_000, 500_000, 1_000_000]
        times = [step_seconds(step, n) for n in sizes]
        assert all(a < b for a, b in itertools.pairwise(times)), step
    assert step_seconds("graph", 0) == 0.0
    # beyond the last size, the last pair's power: 500k to 200k's ratio again at 1.25M
    ratio = step_seconds("graph", 500_000) / step_seconds("graph", 200_000)
    last = REFERENCE_STEPS["graph"][-1][1]
    assert step_seconds("graph", 1_250_000) == pytest.approx(last * ratio)


def test_a_machine_half_as_fast_takes_twice_as_long() -> None:
    here = cold_build_seconds(500_000, 18, REFERENCE_RENDER_RATE, workers=1)
    assert here["bank"] == pytest.approx(500_000 * 18 / REFERENCE_BANK_RATE + 18.4)
    assert here["total"] == pytest.approx(sum(v for k, v in here.items() if k != "total"))
    slow = cold_build_seconds(500_000, 18, REFERENCE_RENDER_RATE / 2, workers=1)
    for step in here:
        assert slow[step] == pytest.approx(2 * here[step])
    eight = cold_build_seconds(500_000, 18, REFERENCE_RENDER_RATE, workers=8)
    assert eight["bank"] == pytest.approx(500_000 * 18 / REFERENCE_BANK_RATE / 8 + 18.4)
    with pytest.raises(ValueError, match="render_rate must be positive"):
        cold_build_seconds(1000, 18, 0.0)
