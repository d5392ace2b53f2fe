"""``vision._repeat``: a performer going on with what they did opens no new action."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from vision import ActionSettings, MatchSettings
from vision._landing import Lander
from vision._repeat import REPEAT_GAP, REPEAT_REACH, REPEAT_SPAN, repeat_frames, repeated
from vision._vote import ActionVote

FPS = 15.0


def cycles(seconds: float, period: float, phase: float = 0.0, dims: int = 6) -> np.ndarray:
    """Features of a performer doing one cyclic action: each dimension a sine of
    ``period`` s at its own phase."""
    t = np.arange(round(seconds * FPS)) / FPS
    shifts = np.linspace(0.0, np.pi, dims) + phase
    return np.sin(2 * np.pi * t[:, None] / period + shifts[None])


def repeats(history: np.ndarray, fps: float, ratio: float) -> bool:
    return repeated(history, fps, ratio) is not None


def test_a_performer_going_on_with_a_cycle_repeats_and_a_new_motion_does_not() -> None:
    rng = np.random.default_rng(0)
    noise = 0.05
    same = cycles(4.0, 0.9) + noise * rng.standard_normal((60, 6))
    back = repeated(same, FPS, 0.5)
    # the nearest stretch is a whole number of cycles back (0.9 or 1.8 s, on 15 frames/s)
    assert back is not None and REPEAT_GAP <= back <= REPEAT_REACH
    assert min(abs(back - 0.9), abs(back - 1.8), abs(back - 2.7)) <= 1.5 / FPS
    # 3 s of one cycle, then 0.7 s of another motion (another period and sides)
    new = np.concatenate((cycles(3.0, 0.9), 0.6 + 1.5 * cycles(0.7, 0.4, phase=2.0)))
    new = new + noise * rng.standard_normal(new.shape)
    assert not repeats(new, FPS, 0.5)
    # a new motion far from the old one (every feature moved), however alike its cycles
    jump = np.concatenate((cycles(3.3, 0.9), 2.0 + cycles(0.4, 0.5)))
    assert not repeats(jump, FPS, 0.5)
    # held still: the same pose again and again
    still = np.full((60, 6), 0.3)
    assert repeated(still, FPS, 0.5) == REPEAT_GAP  # (every stretch alike: the nearest)
    assert not repeats(still, FPS, 0.0)  # (0: off)


def test_the_test_reads_enough_history_and_skips_frames_without_a_reading() -> None:
    assert repeat_frames(FPS) == round((REPEAT_REACH + REPEAT_SPAN) * FPS)
    same = cycles(4.0, 0.9)
    assert not repeats(same[-15:], FPS, 0.5)  # 1 s: too little to compare with
    gaps = same.copy()
    gaps[::4] = np.nan  # a frame in four without a pose
    assert repeats(gaps, FPS, 0.5)
    blank = np.full_like(same, np.nan)
    assert not repeats(blank, FPS, 0.5)
    with pytest.raises(ValueError, match="repeat"):
        ActionSettings(repeat=1.5)


def test_while_the_performer_repeats_the_ballot_opens_no_new_action() -> None:
    """With the filter sure of action 0, a ballot naming action 1 opens action 1's
    windows through the margin; while the performer repeats, it does not, and the
    action the avatar shows stays open, and so does the one voted when the performer
    last did what they do now (a second squat after a pause voted as standing)."""
    vote = ActionVote(10, 3, switch=0.02, temperature=0.2, confidence=0.9)
    vote.actions = np.array([0] * 10 + [1] * 10 + [2] * 10, dtype=np.int64)
    for _ in range(10):
        vote.cast(np.array([2]), 0, np.array([0.0, 5.0, 5.0]))
    lander = Lander.__new__(Lander)
    action = ActionSettings(vote=10, margin=0.2, switch_chance=0.02, repeat=0.5)
    lander.settings, lander.vote, lander.n = MatchSettings(action=action), vote, 4
    lander.windows = SimpleNamespace(playback=lambda f: np.arange(f, f + 4))
    lander.repeated = None
    lander.plays = np.ones(30, dtype=bool)
    got = [(1, 0, 1.0), (13, 0, 0.5), (23, 0, 0.4)]  # windows of actions 0, 1 and 2
    found = (got, np.array([5, 15, 25]), np.array([True, True, True]), np.zeros(3, bool))

    def ok(frame: int) -> list[bool]:
        return lander.gated(frame, [], [], None, found, vote.gate(found[1]))[2].tolist()

    vote.cast(np.array([2]), 1, np.array([1.02, 1.0, 5.0]))  # one ballot, for action 1
    assert vote.voted == 0 and vote.named == 1
    assert ok(2) == [True, True, False]  # the ballot's action at the margin
    lander.repeated = 0  # the performer goes on with what was voted action 0 then
    assert ok(2) == [True, False, False]  # no new action
    assert ok(22) == [True, False, True]  # the avatar in action 2: it stays open
    lander.repeated = 1  # what the performer does again was voted action 1 then
    assert ok(2) == [True, True, False]
    lander.repeated = -1  # (no vote kept from then)
    assert ok(2) == [True, False, False]
    # the voted action's window not open (the avatar is on it): at its clip's end the
    # avatar must jump, so the ballot's action stays open there, and only there
    found = (got, found[1], np.array([False, True, True]), np.zeros(3, bool))
    none: tuple = ([], np.zeros(0, np.int64), np.zeros(0, bool), np.zeros(0, bool))
    lander.voted_windows = lambda *args: none  # (the voted action has no other window)
    assert ok(2) == [False, False, False]
    lander.plays[2] = False
    assert ok(2) == [False, True, False]


def test_the_vote_remembers_what_it_voted_a_few_decision_points_ago() -> None:
    vote = ActionVote(10, 3, switch=0.02, temperature=0.2, confidence=0.9)
    vote.actions = np.array([0] * 10 + [1] * 10, dtype=np.int64)
    assert vote.voted_back(1) == -1
    for _ in range(10):
        vote.cast(np.array([2]), 0, np.array([0.0, 5.0]))
    for _ in range(10):
        vote.cast(np.array([12]), 1, np.array([5.0, 0.0]))
    assert vote.voted == 1 and vote.voted_back(1) == 1 and vote.voted_back(20) == 0
    vote.skipped(3)  # (the next decision stands for 4 points)
    vote.cast(np.array([12]), 1, np.array([5.0, 0.0]))
    assert vote.voted_back(4) == 1 and vote.voted_back(24) == 0 and vote.voted_back(0) == -1
    # a loop deciding 20 times a second keeps twice the points for the same 3 s
    vote.keep_voted(61)
    for _ in range(40):
        vote.cast(np.array([12]), 1, np.array([5.0, 0.0]))
    assert vote.voted_back(61) == 0 and vote.voted_back(62) == -1
