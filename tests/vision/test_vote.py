"""The action vote (issue 17): the best windows of the last decisions vote for the
performer's action, and the avatar keeps to it."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from control.avatar import JumpCosts
from control.motion import Library, action_keys, load_library
from mimic.cli import main
from tests.vision.conftest import RECORDING
from vision import (
    FILTER_SWITCH,
    ActionSettings,
    ActionVote,
    LandingSettings,
    Matcher,
    MatchSettings,
    per_frame_cost,
)


def _squats_and_jogs(lib: Library) -> tuple[list[str | None], list[int], list[int]]:
    """The first clip's label of each frame, and its frames 20 or more into a squat and
    into a jog (each of their last 21 frames so labelled)."""
    clip = lib.clips[0]
    labels = [clip.label_at(f) for f in range(clip.motion.n_frames)]
    squat = [f for f in range(40, len(labels)) if labels[f - 20 : f + 1] == ["Squat"] * 21]
    jog = [f for f in range(40, len(labels)) if labels[f - 20 : f + 1] == ["Jog"] * 21]
    return labels, squat, jog


def test_action_keys_share_labels_across_clips(mocap: Path) -> None:
    lib = load_library(mocap, clips=["13_29", "02_01", "13_30"])
    keys = action_keys(lib.clips)
    assert keys is not None and keys.size == lib.n_frames
    start = np.cumsum([0] + [c.motion.n_frames for c in lib.clips])
    by_label: dict[str, set[int]] = {}
    for i, c in enumerate(lib.clips):
        for f in range(c.motion.n_frames):
            name = c.label_at(f) or f"clip {c.name}"
            by_label.setdefault(name, set()).add(int(keys[start[i] + f]))
    # one number per action, the same in both takes; each clip's unlabelled frames their own
    assert all(len(v) == 1 for v in by_label.values())
    assert len({next(iter(v)) for v in by_label.values()}) == len(by_label)
    assert "Squat" in by_label and "clip 02_01" in by_label
    assert action_keys(load_library(mocap, clips=["02_01", "01_01"]).clips) is None


def test_the_vote_is_a_majority_and_a_tie_keeps_the_action(setup) -> None:
    lib, layer, bank = setup
    keys = action_keys(lib.clips)
    assert keys is not None
    m = Matcher(layer, bank, MatchSettings(action=ActionSettings(vote=3)), actions=keys)
    frame_of = {int(k): int(np.flatnonzero(keys == k)[0]) for k in np.unique(keys)}
    a, b = sorted(frame_of)[:2]
    fa, fb = frame_of[a], frame_of[b]
    targets = np.array([fb, fa, fb])
    got = [m.vote.cast(np.array([f, fa, fb])) for f in (fa, fb, fb)]
    assert m.vote.voted == b  # a, b, b
    # which of the last decision's windows show the voted action
    assert got[-1] is not None and list(got[-1]) == [True, False, True]
    for _ in range(2):
        m.vote.cast(np.array([fa]))
    assert m.vote.voted == a  # the last three: b, a, a
    tie = Matcher(layer, bank, MatchSettings(action=ActionSettings(vote=2)), actions=keys)
    tie.vote.cast(np.array([fa]))
    tie.vote.cast(np.array([fb]))
    assert tie.vote.voted == a  # a tie keeps the action voted for
    tie.vote.cast(np.array([fb]))
    assert tie.vote.voted == b
    # no labels, or no vote: nothing is voted
    assert (
        Matcher(layer, bank, MatchSettings(action=ActionSettings(vote=3))).vote.cast(targets)
        is None
    )
    off = Matcher(layer, bank, MatchSettings(action=ActionSettings(vote=0)), actions=keys)
    assert off.vote.cast(targets) is None


def test_windows_and_the_avatar_about_to_leave_the_action_do_not_count() -> None:
    """Ten frames of action 0, then ten of action 1; a window counts for its action when
    it still shows it 3 frames on, and an avatar about to play on out of the voted action
    leaves it now."""
    vote = ActionVote(5, 3)
    vote.actions = np.array([0] * 10 + [1] * 10, dtype=np.int64)
    assert list(vote.cast(np.array([2, 8, 5]))) == [True, False, True]  # type: ignore[arg-type]
    assert vote.voted == 0
    assert not vote.leaves(5, 8)
    assert vote.leaves(8, 11)  # about to play on into action 1
    assert vote.leaves(12, 15)
    # the windows of 4 frames that pass the gate: those followed by 3 more frames of 0
    assert list(np.flatnonzero(vote.starts(4))) == [0, 1, 2]
    assert ActionVote(0, 3).cast(np.array([2])) is None


def test_a_run_of_votes_takes_up_a_new_action_at_once() -> None:
    """Ten votes for action 0, then action 1 in a row: voted for at the fifth (a third of
    15), long before it has the most votes."""
    vote = ActionVote(15, 0)
    vote.actions = np.array([0] * 10 + [1] * 10, dtype=np.int64)
    assert vote.quick == 5
    for _ in range(10):
        vote.cast(np.array([2]))
    got = []
    for _ in range(5):
        vote.cast(np.array([12]))
        got.append(vote.voted)
    assert got == [0, 0, 0, 0, 1]
    # the older votes stay: one more for action 0, which still has the most, takes it back
    vote.cast(np.array([2]))
    assert vote.voted == 0


def test_a_decision_after_skipped_ones_votes_for_them_too() -> None:
    """A source slower than the decisions (a 5 frames/s video: every other decision point
    skipped): each vote stands for the points skipped before it, so the vote spans the
    same time at any frame rate."""
    vote = ActionVote(4, 0)
    vote.actions = np.array([0] * 10 + [1] * 10, dtype=np.int64)
    vote.cast(np.array([2]))
    vote.cast(np.array([2]))
    vote.missed = 2
    vote.cast(np.array([12]))  # the last four points: 0, 1, 1, 1
    assert vote.voted == 1 and vote.missed == 0


def test_the_avatar_leaves_an_action_the_performer_is_not_doing(setup) -> None:
    """The performer squats; the avatar jogs, and its jog window fits them nearly as well
    as the best (a ``jump_ratio`` so low that no jump would win): with the strict vote
    (``ActionSettings.margin`` infinite) it leaves for a squat all the same, once it has played
    ``min_play`` on."""
    lib, layer, bank = setup
    labels, squat, jog = _squats_and_jogs(lib)
    assert squat and jog
    costs = JumpCosts(layer.graph, lib.clips, anywhere=True)
    keys = action_keys(lib.clips)
    assert keys is not None

    def decide(vote: int) -> tuple[int, bool] | None:
        st = MatchSettings(
            action=ActionSettings(vote=vote, margin=math.inf),
            landing=LandingSettings(jump_ratio=0.01),
        )
        m = Matcher(layer, bank, st, actions=keys)
        s = squat[len(squat) // 2]
        performer = bank.features[m.windows.to_bank[np.arange(s - m.n + 1, s + 1)], 0]
        j = jog[len(jog) // 2]
        shown = np.arange(j - m.recent_frames + 1, j + 1)  # played on: settled
        d = m.decide(j, performer.astype(np.float64), shown, costs)
        if d is None or d.jump is None:
            return None
        return d.jump.target, d.jump.leaves

    assert decide(0) is None
    got = decide(1)
    assert got is not None and labels[got[0]] == "Squat"
    assert got[1]  # it leaves for the voted action (the decision log says `leaves`)


@pytest.mark.parametrize("margin", [math.inf, 0.2])
def test_the_avatar_jumps_into_the_voted_action_unless_another_fits_far_better(
    setup, margin: float
) -> None:
    """The performer jogs, but the vote is still for a squat (one jog window among many
    squat votes): none of the best windows is a squat, so the avatar, jogging, looks
    for the best squat windows. With the strict vote (``ActionSettings.margin`` infinite) it jumps
    into one of them, never into a jog (before the vote it stayed, or jumped to the best
    jog window); with a margin of 0.2 the best jog window, whose cost even 1.2 times is
    far below the best squat window's, wins, at 1.2 times its cost (the margin held
    whatever share of the votes agree: ``strict_share`` 0)."""
    lib, layer, bank = setup
    labels, squat, jog = _squats_and_jogs(lib)
    keys = action_keys(lib.clips)
    assert keys is not None and squat and jog
    costs = JumpCosts(layer.graph, lib.clips, anywhere=True)
    vote = ActionSettings(vote=15, margin=margin, strict_share=0.0)
    m = Matcher(layer, bank, MatchSettings(action=vote), actions=keys)
    for _ in range(10):
        m.vote.cast(np.array([squat[len(squat) // 2]]))
    j = jog[len(jog) // 3]
    performer = bank.features[m.windows.to_bank[np.arange(j - m.n + 1, j + 1)], 0].astype(
        np.float64
    )
    queries = m.queries(performer)
    assert queries is not None
    st = m.settings
    best = m.windows.index().search(queries, st.band, st.landing.top_windows, recency=st.recency)
    assert all(labels[s + m.n] != "Squat" for s, _, _ in best)  # the best windows jog
    a = jog[2 * len(jog) // 3]
    shown = np.arange(a - m.recent_frames + 1, a + 1)  # played on: settled
    d = m.decide(a, performer, shown, costs)
    assert d is not None and d.jump is not None
    assert m.vote.voted == keys[squat[0]]
    if math.isinf(margin):
        assert labels[d.jump.target] == "Squat"
        return
    squats = m.windows.index().search(
        queries, st.band, st.landing.top_windows, m.vote.starts(m.n), recency=st.recency
    )
    assert labels[d.jump.target] == "Jog" and not d.jump.leaves
    assert d.cost == pytest.approx(1.2 * best[0][2], rel=1e-6) and d.cost < squats[0][2]


def test_a_negative_or_infinite_recency_weighing_is_refused(mocap: Path, capsys) -> None:
    for bad in (-1.0, math.inf, math.nan):
        with pytest.raises(ValueError, match="recency must be a finite number >= 0"):
            MatchSettings(recency=bad)
    argv = ["perform", "--video", str(RECORDING), str(mocap), "--clips", "13_30", "--recency", "-2"]
    assert main(argv) != 0
    assert (
        "argument --recency: must be a number from 0 to 1000, not '-2'" in capsys.readouterr().err
    )


@pytest.mark.slow  # (mimic evaluate builds the library's graph, layer and bank first)
def test_the_hold_is_a_flag_and_a_bad_one_is_refused(mocap: Path, tmp_path: Path, capsys) -> None:
    for bad in (-0.1, math.inf, math.nan):
        with pytest.raises(ValueError, match="min_play must be a finite number of seconds >= 0"):
            MatchSettings(landing=LandingSettings(min_play=bad))
    argv = ["perform", "--video", str(RECORDING), str(mocap), "--clips", "13_30", "--hold", "-1"]
    assert main(argv) != 0
    assert "argument --hold: must be a number from 0 to 60, not '-1'" in capsys.readouterr().err
    out = tmp_path / "r.json"
    argv = ["evaluate", str(RECORDING), str(mocap), "--clips", "13_30", "--seconds", "2"]
    assert main([*argv, "--hold", "0.5", "--json", str(out)]) == 0
    match = json.loads(out.read_text())["match"]
    assert match["landing"]["min_play"] == 0.5
    # (a silhouette video: the landmarks read from it weigh in, and its vote is filtered)
    assert match["action"]["switch_chance"] == FILTER_SWITCH
    argv += ["--no-fuse"]  # the silhouette alone: the counted vote
    assert main([*argv, "--json", str(out)]) == 0
    assert json.loads(out.read_text())["match"]["action"]["switch_chance"] == 0.0


def test_a_negative_vote_is_refused(mocap: Path, capsys) -> None:
    with pytest.raises(ValueError, match="vote must be a number of decisions >= 0"):
        MatchSettings(action=ActionSettings(vote=-1))
    with pytest.raises(ValueError, match="margin must be >= 0"):
        MatchSettings(action=ActionSettings(margin=-0.1))
    argv = ["perform", "--video", str(RECORDING), str(mocap), "--clips", "13_30", "--vote", "-2"]
    assert main(argv) != 0
    assert (
        "argument --vote: must be a whole number from 0 to 1000, not '-2'"
        in capsys.readouterr().err
    )


@pytest.mark.parametrize("margin", [math.inf, 0.2])
def test_holding_still_in_another_action_costs_the_margin_too(setup, margin: float) -> None:
    """A performer standing still; the avatar holds a jog frame. Held, a frame of another
    action than the voted one costs 1 + ``ActionSettings.margin`` times as much, as it does played
    on (with the strict vote the hold is not weighed: the avatar leaves that action)."""
    lib, layer, bank = setup
    _, squat, jog = _squats_and_jogs(lib)
    keys = action_keys(lib.clips)
    assert keys is not None and squat and jog
    m = Matcher(
        layer, bank, MatchSettings(action=ActionSettings(vote=15, margin=margin)), actions=keys
    )
    j = jog[len(jog) // 2]
    still = bank.features[m.windows.to_bank[np.full(m.n, j + 3)], 0].astype(np.float64)
    queries = m.queries(still)
    assert queries is not None
    held = []
    for voted in (keys[j], keys[squat[0]]):
        m.vote.voted = int(voted)
        d = m.lander.held(j, queries, None, 1e9)  # (playing on, the rival, costs far more)
        assert d is not None and d.how == "held"
        held.append(d.cost)
    assert held[0] > 0
    assert held[1] == pytest.approx(held[0] * (1.0 if math.isinf(margin) else 1.2), rel=1e-9)


def test_the_filtered_vote_ignores_odd_decisions_and_follows_a_real_change() -> None:
    """The hidden Markov filter (``ActionSettings.switch_chance``): 10 s of one action
    whose decisions are won by another now and then (every 7th, two in a row at 4 s) keep the voted
    action; a clean change is taken up within half a second."""
    from vision._vote import ActionVote

    vote = ActionVote(15, 7, switch=0.02, temperature=0.1)
    vote.actions = np.array([0, 1, 2], dtype=np.int64)
    target = np.array([0], dtype=np.int64)
    voted = []
    for i in range(100):  # 10 s of action 0; action 1 wins every 7th, and at 4.0-4.1 s
        odd = i % 7 == 3 or i in (40, 41)
        scores = np.array([1.08, 1.0, 1.3]) if odd else np.array([1.0, 1.1, 1.3])
        vote.cast(target, None, scores)
        voted.append(vote.voted)
    assert voted[5:] == [0] * 95
    for _ in range(10):  # the performer changes to action 2
        vote.cast(target, None, np.array([1.2, 1.15, 1.0]))
        voted.append(vote.voted)
    assert voted[-5:] == [2] * 5
    taken = voted.index(2) - 100
    assert taken <= 5, taken  # within 0.5 s of decisions


def test_an_action_missing_from_the_short_lists_for_a_moment_is_kept() -> None:
    """An action none of whose windows made the search's short lists at a decision (its
    score infinite) is not ruled out: its evidence is the worst seen action's. Ruled
    out, the filter dropped the action it believed in for any other at once."""
    from vision._vote import ActionVote

    vote = ActionVote(15, 7, switch=0.02, temperature=0.3, confidence=0.9)
    vote.actions = np.array([0, 1, 2, 3], dtype=np.int64)
    target = np.array([0], dtype=np.int64)
    for _ in range(50):  # 5 s of action 0, sure
        vote.cast(target, None, np.array([1.0, 1.2, 1.3, 1.3]))
    assert vote.voted == 0 and vote.share() > 0.9  # (the strict vote reads the belief)
    voted = []
    for i in range(30):  # action 0 off the short lists at every third decision
        gone = i % 3 == 0
        scores = np.array([np.inf, 1.0, 1.2, np.inf]) if gone else np.array([1.0, 1.1, 1.1, 1.3])
        vote.cast(target, None, scores)
        voted.append(vote.voted)
    assert voted == [0] * 30
    for _ in range(20):  # then it is gone for good, and another action wins clearly
        vote.cast(target, None, np.array([np.inf, 1.0, 1.3, np.inf]))
    assert vote.voted == 1
    assert np.isfinite(vote._belief).all() and vote._belief.sum() == pytest.approx(1.0)


def test_a_confident_filter_keeps_its_action_while_two_are_about_as_likely() -> None:
    from vision._vote import ActionVote

    target = np.array([0], dtype=np.int64)
    steady = []
    for confidence in (0.0, 0.9):
        vote = ActionVote(15, 7, switch=0.02, temperature=0.1, confidence=confidence)
        vote.actions = np.array([0, 1, 2], dtype=np.int64)
        for _ in range(20):  # two actions alike from the start
            vote.cast(target, None, np.array([1.0, 1.0, 1.3]))
        changes, last = 0, vote.voted
        for i in range(60):  # actions 0 and 1 lead by turns, by a hair: neither is sure
            vote.cast(
                target, None, np.array([1.0, 1.01, 1.3]) if i % 2 else np.array([1.01, 1.0, 1.3])
            )
            changes += vote.voted != last
            last = vote.voted
        steady.append(changes)
    assert steady[1] == 0 and steady[0] > 10  # (the most believed flips at every point)


def test_a_vote_that_agrees_keeps_strictly_to_its_action() -> None:
    """``ActionSettings.strict_share``: where at least that share of the last votes went
    to the voted action, the decision's jumps go into it alone; where the vote is split,
    the settings' margin holds. The margin itself (the avatar's own motion, its holds)
    stays as set."""
    from vision._landing import Lander

    vote = ActionVote(10, 3)
    vote.actions = np.array([0] * 10 + [1] * 10, dtype=np.int64)
    settings = MatchSettings(action=ActionSettings(vote=10, margin=0.2, strict_share=0.9))
    lander = Lander.__new__(Lander)  # (strictness reads only the settings and the vote)
    lander.settings, lander.vote = settings, vote
    assert vote.share() == 0.0 and not lander.strict()  # no votes yet
    for _ in range(9):
        vote.cast(np.array([2]))  # action 0
    assert vote.share() == 1.0 and lander.strict() and lander.margin() == 0.2
    vote.cast(np.array([12]))  # one for action 1: 9 of 10 still agree
    assert vote.voted == 0 and vote.share() == 0.9 and lander.strict()
    vote.cast(np.array([12]))  # 8 of 10: split enough for the margin
    assert vote.share() == pytest.approx(0.8) and not lander.strict()
    lander.settings = MatchSettings(action=ActionSettings(margin=0.2))  # (off)
    vote.cast(np.array([2]))
    assert vote.share() == pytest.approx(0.8) and not lander.strict()
    lander.settings = MatchSettings(action=ActionSettings(margin=math.inf))
    assert lander.strict()  # an infinite margin: always
    with pytest.raises(ValueError, match="strict_share must lie in"):
        ActionSettings(strict_share=1.5)


def test_where_the_vote_agrees_the_avatar_leaves_its_action_before_playing_out_of_it() -> None:
    """With the vote strict, a jump goes into the voted action alone, and an avatar about
    to play on out of the voted action has no cost of its own (it jumps, as at a clip's
    end); an avatar in another action keeps the margin (it may still hold still there)."""
    from types import SimpleNamespace

    from vision._landing import Lander

    vote = ActionVote(10, 3)
    vote.actions = np.array([0] * 10 + [1] * 10, dtype=np.int64)
    for _ in range(10):
        vote.cast(np.array([2]))  # action 0, all agree
    lander = Lander.__new__(Lander)
    lander.settings = MatchSettings(action=ActionSettings(vote=10, margin=0.2, strict_share=0.9))
    lander.vote, lander.n = vote, 4
    lander.windows = SimpleNamespace(playback=lambda f: np.arange(f, f + 4))
    got = [(1, 0, 1.0), (13, 0, 0.5)]  # a window of action 0, a better one of action 1
    found = (got, np.array([5, 17]), np.array([True, True]), np.array([False, False]))
    voted = vote.gate(found[1])

    def own(frame: int) -> tuple[list[bool], float]:
        _, _, ok, weight, own_weight = lander.gated(frame, [], [], None, found, voted)
        assert np.all(weight == 1.0)
        return ok.tolist(), own_weight

    assert own(2) == ([True, False], 1.0)  # in the action, and still in it 2 frames on
    assert own(8) == ([True, False], math.inf)  # about to play on into action 1
    assert own(12) == ([True, False], 1.2)  # in action 1 already: the margin
    lander.settings = MatchSettings(action=ActionSettings(vote=10, margin=0.2, strict_share=0))
    _, _, ok, weight, own_weight = lander.gated(8, [], [], None, found, voted)
    assert ok.tolist() == [True, True] and weight.tolist() == [1.0, 1.2] and own_weight == 1.2


def test_with_ballot_jumps_the_filter_may_jump_into_the_ballots_action_alone() -> None:
    """``ActionSettings.ballot_jumps``: with the filter sure of its action (strict), a
    decision whose ballot names another action may jump into that one through the
    margin, before the filter believes it; a third action's window stays shut. Without
    it, or with the margin infinite, the decision stays strict."""
    from types import SimpleNamespace

    from vision._landing import Lander

    vote = ActionVote(10, 3, switch=0.02, temperature=0.2, confidence=0.9)
    vote.actions = np.array([0] * 10 + [1] * 10 + [2] * 10, dtype=np.int64)
    sure = np.array([0.0, 5.0, 5.0])  # the ballot's scores: action 0 far ahead
    for _ in range(10):
        vote.cast(np.array([2]), 0, sure)
    assert vote.voted == 0 and vote.share() > 0.99
    lander = Lander.__new__(Lander)
    action = ActionSettings(vote=10, margin=0.2, ballot_jumps=True, switch_chance=0.02)
    lander.settings, lander.vote, lander.n = MatchSettings(action=action), vote, 4
    lander.windows = SimpleNamespace(playback=lambda f: np.arange(f, f + 4))
    # windows of actions 0, 1 and 2, the other two far better than the voted one's
    got = [(1, 0, 1.0), (13, 0, 0.5), (23, 0, 0.4)]
    found = (got, np.array([5, 15, 25]), np.array([True, True, True]), np.zeros(3, bool))

    def gated() -> tuple[list[bool], list[float]]:
        voted = vote.gate(found[1])
        _, _, ok, weight, _ = lander.gated(2, [], [], None, found, voted)
        return ok.tolist(), weight.tolist()

    assert lander.named() is None and lander.strict()  # the ballot names the voted one
    assert gated()[0] == [True, False, False]
    vote.cast(np.array([2]), 1, np.array([1.02, 1.0, 5.0]))  # one ballot, for action 1
    assert vote.voted == 0 and vote.named == 1 and vote.share() > 0.9  # the filter: still 0
    assert lander.named() == 1 and not lander.strict()
    assert gated() == ([True, True, False], [1.0, 1.2, 1.2])  # action 1 at the margin
    lander.settings = MatchSettings(action=dataclasses.replace(action, ballot_jumps=False))
    assert lander.named() is None and lander.strict()
    lander.settings = MatchSettings(action=dataclasses.replace(action, margin=math.inf))
    assert lander.named() is None and lander.strict()


def test_an_action_a_ballot_named_lately_is_played_on_without_the_margin() -> None:
    """``ActionSettings.ballot_keep``: the avatar showing an action a ballot named within
    the last ``ballot_keep`` decision points (a skipped point counts) plays on in it at
    its own cost, so the next ballot for the voted action does not push it straight back
    out; later, or where it is about to play on out of that action, the margin holds."""
    from types import SimpleNamespace

    from vision._landing import Lander

    vote = ActionVote(10, 3, switch=0.02, temperature=0.2, confidence=0.9, keep=3)
    vote.actions = np.array([0] * 10 + [1] * 10 + [2] * 10, dtype=np.int64)
    sure = np.array([0.0, 5.0, 5.0])  # the ballot's scores: action 0 far ahead
    for _ in range(10):
        vote.cast(np.array([2]), 0, sure)
    lander = Lander.__new__(Lander)
    action = ActionSettings(vote=10, margin=0.2, switch_chance=0.02, ballot_keep=3)
    lander.settings, lander.vote, lander.n = MatchSettings(action=action), vote, 4
    lander.windows = SimpleNamespace(playback=lambda f: np.arange(f, f + 4))
    found = ([(1, 0, 1.0)], np.array([5]), np.array([True]), np.zeros(1, bool))

    def own(frame: int) -> float:
        return lander.gated(frame, [], [], None, found, vote.gate(found[1]))[4]

    assert own(12) == 1.2  # the avatar in action 1, which no ballot named: the margin
    vote.cast(np.array([2]), 1, np.array([1.02, 1.0, 5.0]))  # one ballot for action 1
    assert vote.voted == 0 and own(12) == 1.0
    assert own(18) == 1.2  # (it plays on into action 2 within half a window)
    vote.cast(np.array([2]), 0, sure)
    vote.cast(np.array([2]), 0, sure)
    assert own(12) == 1.0  # action 1 named 3 points ago
    vote.cast(np.array([2]), 0, sure)
    assert own(12) == 1.2
    vote.cast(np.array([2]), 1, np.array([1.02, 1.0, 5.0]))
    vote.skipped(2)  # the next ballot stands for 3 points: action 1 is out of the last 3
    vote.cast(np.array([2]), 0, sure)
    assert own(12) == 1.2
    lander.settings = MatchSettings(action=dataclasses.replace(action, ballot_jumps=False))
    vote.cast(np.array([2]), 1, np.array([1.02, 1.0, 5.0]))
    assert own(12) == 1.2  # (without ballot jumps, nothing is kept)
    with pytest.raises(ValueError, match="ballot_keep"):
        ActionSettings(ballot_keep=-1)


def test_where_the_best_window_fits_weakly_another_action_costs_more(setup) -> None:
    # the performer does the library's window ending at frame 200, seen from view 3: as
    # the library has it, and so blurred by noise that no window fits it well
    lib, layer, bank = setup
    m = Matcher(layer, bank, MatchSettings(landing=LandingSettings(phase_frames=0)))
    m.ready(lib.clips, 0.1)
    window = np.arange(200 - m.n + 1, 201)
    seen = bank.features[m.windows.to_bank[window], 3].astype(np.float64)
    noisy = seen + np.random.default_rng(3).normal(0.0, 3.0 * seen.std(), seen.shape)
    costs = JumpCosts(layer.graph, lib.clips, anywhere=True)
    st = m.settings
    weights = {}
    for name, performer in (("seen", seen), ("noisy", noisy)):
        queries = m.queries(performer)
        assert queries is not None
        ranked: list = []
        got = m.windows.index().search(queries, st.band, st.landing.top_windows, None, ranked)
        target, ok, there = m.lander.targets(40, got, costs, queries)
        voted = np.zeros(len(got), dtype=bool)
        voted[int(np.flatnonzero(ok)[0])] = True  # one window shows the voted action
        fit = per_frame_cost(min(g[2] for g in got), queries[0].shape[0]) / m.reject
        found = (got, target, ok, there)
        weights[name] = (
            fit,
            m.lander.weak(got, queries),
            m.lander.gated(40, queries, ranked, costs, found, voted),
        )
    fit, weak, (_, _, _, weight, own) = weights["seen"]
    assert fit < 0.35 and not weak and set(weight.round(6)) == {1.0, 1.2} and own == 1.2
    fit, weak, (_, _, _, weight, own) = weights["noisy"]
    # another action's windows at 1 + weak_margin, the avatar's own motion as before
    assert fit > 0.35 and weak and set(weight.round(6)) == {1.0, 2.0} and own == 1.2
    with pytest.raises(ValueError, match="weak_fit must be > 0"):
        ActionSettings(weak_fit=0.0)
