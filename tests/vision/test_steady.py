"""A steady avatar (issue 61): one avatar action while the performer keeps to one, and a
switch followed promptly, with the defaults. The performer is another take (13_29) of
the library's performer, as a pose tracker gives it (simulated landmarks on another
body, another camera, 3% noise); the library is 13_30 with a pose bank."""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from benchmarks._landmarks import LandmarkSource, landmark_points
from control.motion import load_library
from silhouette_bank import BankSettings, build_bank
from vision import PerformSettings, RecordSettings, avatar_labels, perform


@pytest.fixture(scope="module")
def pose_bank(setup: Any, tmp_path_factory: pytest.TempPathFactory) -> Any:
    lib, _, _ = setup
    folder = tmp_path_factory.mktemp("pose")
    return build_bank(lib.clips, BankSettings(descriptor="pose"), folder, workers=1)


def _decisions(setup: Any, bank: Any, mocap: Path, first: int, last: int) -> list[dict[str, Any]]:
    """The decisions made while the performer does 13_29's frames ``first`` to ``last``
    (at 120 frames/s, as its label file counts them)."""
    lib, layer, _ = setup
    clip = load_library(mocap, fps=30, clips=["13_29"]).clip("13_29")
    frames = np.arange(first // 4, last // 4)
    px = landmark_points(clip.motion, RecordSettings(), np.random.default_rng(5), frames=frames)
    r = perform(LandmarkSource(px, 30.0), layer, bank, lib.clips, PerformSettings(), seed=1)
    return [d for d in r.decisions if d["decision"] is not None]


def _follow(setup: Any, bank: Any, mocap: Path, first: int, last: int) -> list[tuple[float, str]]:
    """The avatar's action at each decision while the performer does 13_29's frames
    ``first`` to ``last``."""
    made = _decisions(setup, bank, mocap, first, last)
    labels = avatar_labels(made, setup[0].clips)
    return list(zip((float(d["t"]) for d in made), labels, strict=True))


def _runs(actions: list[tuple[float, str]]) -> list[tuple[str, float]]:
    """The avatar's actions in turn, each with the time it was first shown."""
    return [(a, next(g)[0]) for a, g in itertools.groupby(actions, key=lambda p: p[1])]


@pytest.mark.slow
def test_one_action_for_nine_seconds_is_one_avatar_action(
    setup: Any, pose_bank: Any, mocap: Path
) -> None:
    # 13_29's knee raises (its frames 2701-3804: 9.2 s, the longest stretch of one action
    # in its labels): once the avatar raises its knees, it does nothing else
    runs = _runs(_follow(setup, pose_bank, mocap, 2700, 3804))
    start = next(t for a, t in runs if a == "kneeraise")
    assert start <= 2.0, runs  # (a window and a few votes in)
    assert [a for a, t in runs if t >= start] == ["kneeraise"], runs


@pytest.mark.slow
def test_a_clean_switch_is_followed_once(setup: Any, pose_bank: Any, mocap: Path) -> None:
    # 13_29's jumping jacks, then its twists from 3.9 s (its frame 469): the avatar
    # jumps, then twists, once, at most 1.5 s after the performer does (a label's
    # boundary is not exact: the last jack already turns), and stays (the steadiness
    # issue's target is a lag under 0.5 s; here it is about 1.2 s). Without the strict
    # vote the avatar plays on from its jumping jacks into the library's next action,
    # and back.
    runs = _runs(_follow(setup, pose_bank, mocap, 0, 1100))
    switch = 468 / 120
    jacks = next(t for a, t in runs if a == "jumpjack")
    twist = next(t for a, t in runs if a == "twist" and t > jacks)
    assert jacks <= 2.0 and switch - 0.5 <= twist <= switch + 1.5, runs
    assert [a for a, t in runs if t >= jacks] == ["jumpjack", "twist"], runs


def test_the_lag_from_the_motion_reads_each_recorded_frame_at_its_source_frame(
    mocap: Path,
) -> None:
    """The lag counted from where the motion changes labels each frame of a recording by
    the take's cleaned labels at its source frame (a retimed take's frames fall between
    the take's), and leaves a pause unlabelled."""
    from vision._truth import labels_at_source_frames

    clean = load_library(mocap, fps=30, clips=["13_29"]).clip("13_29")
    src = clean.source_frames
    k = int(np.flatnonzero(clean.labels[1:] != clean.labels[:-1])[0]) + 1  # a cleaned boundary
    at = [src[k - 1] + 0.4 * (src[k] - src[k - 1]), src[k] - 0.4, src[k], src[k]]
    want = [clean.label_at(k - 1), clean.label_at(k), clean.label_at(k), None]
    assert labels_at_source_frames(clean, at, ["X", "X", "X", None]) == want
    assert want[0] != want[1]


@pytest.mark.slow
def test_a_performer_going_on_is_seen_to_repeat_and_one_who_changes_is_not(
    setup: Any, pose_bank: Any, mocap: Path
) -> None:
    # ``ActionSettings.repeat``: 13_29's jumping jacks, then its twists from 3.9 s. The
    # decisions from 3 s into the jacks on see the performer do again what they did
    # (all of them, here); in the second after the twists begin, most do not
    made = _decisions(setup, pose_bank, mocap, 0, 1100)
    switch = 468 / 120

    def share(lo: float, hi: float) -> float:
        got = [bool(d.get("repeats")) for d in made if lo <= float(d["t"]) < hi]
        return sum(got) / len(got)

    assert share(3.0, switch) >= 0.8
    assert share(switch + 0.3, switch + 1.3) <= 0.5
