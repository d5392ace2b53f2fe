"""A performer at another tempo, or one who stops: the matcher's readings of the
performer at other tempos (``ActionSettings.tempos``) and the benchmark's takes that keep
another tempo, pause, or move with another reach (``benchmarks._takes``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from benchmarks._takes import held_since, paused_clip, retimed_clip, styled_clip
from control.graph import joint_jumps
from control.motion import foot_points, load_library, qconj, qlog, qmul
from silhouette_bank import get_descriptor
from vision import ActionSettings, MatchSettings
from vision._windows import retimed, tempo_readings


def test_the_performers_last_frames_are_resampled_to_a_window() -> None:
    """``retimed``: the last ``span`` frames of a steady ramp, resampled to ``rows``, are
    the ramp at evenly spaced times; frames without features are bridged; too few frames,
    or too few with features, give nothing."""
    t = np.arange(40, dtype=np.float64)
    performer = np.stack((t, 2.0 * t, np.full(40, 7.0)), axis=1)
    got = retimed(performer, 25, 15)
    assert got is not None and got.shape == (15, 3)
    np.testing.assert_allclose(got[:, 0], np.linspace(15.0, 39.0, 15))
    np.testing.assert_allclose(got[:, 1], 2.0 * got[:, 0])
    np.testing.assert_allclose(got[:, 2], 7.0)
    holes = performer.copy()
    holes[[20, 21, 30]] = np.nan  # frames without a pose: bridged linearly
    np.testing.assert_allclose(retimed(holes, 25, 15), got)
    assert retimed(performer, 41, 15) is None  # not that many frames yet
    assert retimed(performer, 15, 15) is None  # a window already
    blank = performer.copy()
    blank[-20:] = np.nan
    assert retimed(blank, 25, 15) is None  # fewer than half with features


def test_tempo_readings_are_one_per_tempo_as_seen_only() -> None:
    """A silhouette is read mirrored too, but a tempo reading is read as seen only: one
    query per tempo with enough frames, each as long as the window's query."""
    desc = get_descriptor("outline")
    rng = np.random.default_rng(0)
    performer = rng.normal(size=(30, desc.size))
    k = desc.shape(performer).shape[1]
    mean, proj = np.zeros(k), np.eye(k)
    got = tempo_readings(performer, 15, (0.6, 1.5, 0.4), 15, desc, mean, proj, 3.0)
    assert len(got) == 2  # 0.4 needs 38 frames
    assert all(q.shape == (15, k + 2) for q in got)
    assert tempo_readings(performer, 15, (), 15, desc, mean, proj, 3.0) == []
    # the fast reading is the last 10 frames stretched: its first row is frame 20's
    fast = tempo_readings(performer, 15, (1.5,), 15, desc, mean, proj, 3.0)[0]
    np.testing.assert_allclose(fast[0, :k], desc.shape(performer[20:21])[0])
    assert MatchSettings().action.tempos == ()  # measured, not on by default (README)


def test_a_paused_take_holds_still_where_it_moves_least(mocap: Path) -> None:
    """``paused_clip``: holds of 2 s every 6 s, each at the frame of the next second that
    moves least, unlabelled; the frames between are the take's own, in order."""
    clip = load_library(mocap, fps=30, clips=["13_30"]).clip("13_30")
    held, holds = paused_clip(clip)
    n = clip.motion.n_frames
    k = len(np.arange(3.0, n / 30.0 - 1.0, 6.0))
    assert holds.sum() == 60 * k and held.motion.n_frames == n + 60 * k
    assert np.all(held.labels[holds] == -1)
    assert np.all(held.labels[~holds] == clip.labels)
    np.testing.assert_array_equal(held.motion.quats[~holds], clip.motion.quats)
    starts = np.flatnonzero(np.diff(holds.astype(int)) == 1) + 1
    move = joint_jumps(clip.motion)
    for s, t in zip(starts, np.arange(3.0, n / 30.0 - 1.0, 6.0), strict=True):
        q = held.motion.quats
        np.testing.assert_array_equal(q[s : s + 60], np.broadcast_to(q[s - 1], (60, *q.shape[1:])))
        rest = int(np.flatnonzero(clip.source_frames == held.source_frames[s - 1])[0])
        a = round(t * 30)
        assert rest == a + int(np.argmin(move[a : a + 30]))  # where it moves least
    assert held_since(holds, 30.0, 0.5).sum() == (60 - 15) * k


@pytest.mark.parametrize("bad", [(0.0,), (0.1,), (float("nan"),), ("slow",), (9.0,)])
def test_bad_tempos_are_refused(bad) -> None:
    with pytest.raises(ValueError, match="tempos must be numbers"):
        MatchSettings(action=ActionSettings(tempos=bad))


@pytest.mark.parametrize("tempo", [0.5, 1.3])
def test_a_retimed_take_keeps_its_labels(mocap: Path, tempo: float) -> None:
    clip = load_library(mocap, fps=30, clips=["13_30"]).clip("13_30")
    other = retimed_clip(clip, tempo)
    n = clip.motion.n_frames
    assert abs(other.motion.n_frames - n / tempo) <= 2 and other.motion.fps == 30.0
    src = np.clip(np.round(np.arange(other.motion.n_frames) * tempo).astype(int), 0, n - 1)
    np.testing.assert_array_equal(other.labels, clip.labels[src])


def test_a_take_with_another_reach_turns_its_joints_that_much_further(mocap: Path) -> None:
    """``styled_clip``: every joint but the root turns ``reach`` times as far from its mean
    over the take; the root's orientation and path across the floor are the take's, its
    height moved so that the lowest foot is where the take's was; the labels are kept;
    reach 1 is the take itself."""
    clip = load_library(mocap, fps=30, clips=["13_30"]).clip("13_30")
    q = clip.motion.quats
    same = styled_clip(clip, 1.0)
    np.testing.assert_allclose(np.abs((same.motion.quats * q).sum(axis=-1)), 1.0, atol=1e-9)
    np.testing.assert_allclose(same.motion.root_pos, clip.motion.root_pos, atol=1e-9)
    for reach in (0.7, 1.25):
        other = styled_clip(clip, reach)
        assert np.array_equal(other.labels, clip.labels)
        np.testing.assert_allclose(other.motion.quats[:, 0], q[:, 0])
        np.testing.assert_allclose(
            other.motion.root_pos[:, [0, 2]], clip.motion.root_pos[:, [0, 2]]
        )
        # each joint's turn from the first frame to every other: about reach times the take's
        # (exactly so about the mean; the knees' and elbows' turns keep their axis)
        turn = [qlog(qmul(qconj(x[:1, 1:]), x[:, 1:])) for x in (q, other.motion.quats)]
        big = np.linalg.norm(turn[0], axis=-1) > 0.3
        ratio = np.linalg.norm(turn[1], axis=-1)[big] / np.linalg.norm(turn[0], axis=-1)[big]
        assert abs(np.median(ratio) - reach) < 0.05
        lowest = []
        for m in (clip.motion, other.motion):
            ankle, toe = foot_points(m)
            lowest.append(np.minimum(ankle[..., 1], toe[..., 1]).min(axis=1))
        np.testing.assert_allclose(lowest[1], lowest[0], atol=1e-9)
