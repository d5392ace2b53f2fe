"""The action classifier (issue 16): learned from the library's own windows, it settles
near ties between the best windows of two actions."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest
from sklearn.discriminant_analysis import LinearDiscriminantAnalysis

from control.motion import action_keys
from vision import ActionSettings, Matcher, MatchSettings
from vision._classify import (
    FLOOR,
    ActionClassifier,
    action_score,
    action_scores,
    cached_action_classifier,
    choose_action,
    voted_action,
    window_summary,
)
from vision._vote import FIT_POWER, fused


def _tables(actions: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Tables of 3 views whose windows differ by action: each action a block of frames
    with its own mean shape and its own sway of the centre."""
    rng = np.random.default_rng(seed)
    n = 120 * actions
    act = np.repeat(np.arange(actions), 120)
    shape = rng.normal(0, 1, (n, 3, 4)) + act[:, None, None] * 0.8
    t = np.arange(n)[:, None, None]
    centre = np.concatenate([np.sin(t * (0.2 + 0.1 * act[:, None, None])), 0 * t], axis=2)
    centre = centre + rng.normal(0, 0.05, (n, 3, 2))
    return shape.astype(np.float32), centre, np.arange(n - 9, dtype=np.int64), act


@pytest.mark.parametrize("n_actions", [2, 3])
def test_the_classifiers_probabilities_are_scikit_learns(n_actions: int) -> None:
    shape, centre, starts, act = _tables(n_actions)
    starts = starts[starts + 9 < shape.shape[0]]
    clf = ActionClassifier.learn(shape, centre, starts, 10, act)
    assert clf is not None and list(clf.classes) == list(range(n_actions))
    # the same windows, by hand, to scikit-learn
    rows = starts[:, None] + np.arange(10)
    x, y = [], []
    for v in range(3):
        seq = np.concatenate(
            [shape[rows, v].astype(np.float64), centre[rows, v] - centre[starts, v][:, None]], -1
        )
        x.append(window_summary(seq))
        y.append(act[starts + 9])
    order = np.argsort(np.concatenate([starts * 3 + v for v in range(3)]), kind="stable")
    lda = LinearDiscriminantAnalysis(solver="eigen", shrinkage=0.1)
    lda.fit(np.concatenate(x)[order], np.concatenate(y)[order])
    rng = np.random.default_rng(1)
    for _ in range(5):
        q = rng.normal(0, 1.5, (int(rng.integers(6, 14)), 6))
        want = lda.predict_log_proba(window_summary(q)[None])[0]
        np.testing.assert_allclose(clf.log_proba([q]), want, atol=1e-8)
    # two readings: each action's more probable one; by action number, unknown ones at FLOOR
    q2 = -q
    both = clf.log_proba([q, q2], n_actions + 2)
    np.testing.assert_allclose(
        both[:n_actions], np.maximum(clf.log_proba([q]), clf.log_proba([q2])), atol=1e-12
    )
    assert list(both[n_actions:]) == [FLOOR, FLOOR]


def test_one_action_teaches_nothing() -> None:
    shape, centre, starts, act = _tables(2)
    assert ActionClassifier.learn(shape, centre, starts, 10, np.zeros_like(act)) is None


def test_a_near_tie_goes_to_the_more_probable_action_and_a_clear_win_stays() -> None:
    inf = np.inf
    assert choose_action(np.array([1.0, 1.02, inf]), np.array([-10.0, -0.1, FLOOR])) == 1
    assert choose_action(np.array([1.0, 1.5]), np.array([-3.0, 0.0])) == 0
    assert choose_action(np.array([2.0, 1.0]), None) == 1  # no classifier: the cheapest
    assert choose_action(np.array([inf, inf]), np.array([0.0, 0.0])) == -1
    # the search's short lists give each action's best window
    ranked = [
        (np.array([0, 50]), np.array([0, 1]), np.array([5.0, 4.0])),
        (np.array([100]), np.array([2]), np.array([4.1])),
    ]
    act = np.repeat(np.arange(3), 60)
    shape, centre, starts, _ = _tables(3)
    clf = ActionClassifier.learn(shape, centre, starts[starts < 170], 10, act)
    assert clf is not None
    q = shape[100:110, 2].astype(np.float64)
    q = np.concatenate([q, centre[100:110, 2] - centre[100, 2]], axis=1)
    got = voted_action(ranked, act, 10, clf, [q])
    logp = clf.log_proba([q], 3)
    cost = np.array([4.0, 4.1, np.inf])  # action 0 (frames 0 and 50 end in it), action 1
    assert got == choose_action(cost, logp)
    assert voted_action(ranked, act, 10, None, [q]) is None
    # for the filter, action 2 (no window listed) is scored at the lists' cutoff, the
    # least a window left off both lists can cost (4.1, the second list's last), not inf
    scores = action_scores(ranked, act, 10, clf, [q], 3)
    seen = action_scores(ranked, act, 10, clf, [q], 3, unseen=True)
    assert scores is not None and seen is not None and np.isinf(scores[2])
    np.testing.assert_allclose(seen[:2], scores[:2])
    np.testing.assert_allclose(seen[2], action_score(np.array([4.0, 4.1, 4.1]), logp)[2])


def test_the_stored_classifier_is_read_back_and_a_damaged_one_learned_again(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    shape, centre, starts, act = _tables(3)
    a = cached_action_classifier(shape, centre, starts, 10, act, tmp_path, key="k")
    (path,) = tmp_path.glob("actions-*.npz")
    b = cached_action_classifier(shape, centre, starts, 10, act, tmp_path, key="k")
    assert a is not None and b is not None
    np.testing.assert_array_equal(a.coef, b.coef)
    path.write_bytes(path.read_bytes()[:100])
    with caplog.at_level(logging.WARNING):
        c = cached_action_classifier(shape, centre, starts, 10, act, tmp_path, key="k")
    assert c is not None and str(path) in caplog.text
    np.testing.assert_allclose(c.coef, a.coef)
    # fewer than two actions: stored as such, and read back as no classifier
    one = np.zeros_like(act)
    assert cached_action_classifier(shape, centre, starts, 10, one, tmp_path, key="k") is None
    assert cached_action_classifier(shape, centre, starts, 10, one, tmp_path, key="k") is None


def test_the_matchers_vote_goes_to_the_classifiers_choice(setup) -> None:
    lib, layer, bank = setup
    keys = action_keys(lib.clips)
    assert keys is not None
    m = Matcher(layer, bank, MatchSettings(action=ActionSettings(vote=3)), actions=keys)
    fa = int(np.flatnonzero(keys == keys[0])[0])
    other = int(keys[np.flatnonzero(keys != keys[0])[0]])
    for _ in range(3):
        m.vote.cast(np.array([fa]), other)  # the best window is of keys[0]; the choice other
    assert m.vote.voted == other
    # a whole decision: the classifier is learned from the bank's windows and stored beside it
    x = np.asarray(bank.features[100 : 100 + m.n, 3], dtype=np.float64)
    queries = m.queries(x)
    assert queries is not None
    ranked: list = []
    m.windows.index().search(
        queries,
        m.settings.band,
        m.settings.landing.top_windows,
        ranked=ranked,
        recency=m.settings.recency,
    )
    choice, scores = m.ballot.choose(m.vote, queries, ranked, x)
    assert choice is not None and choice == int(keys[100 + m.n - 1])
    assert scores is not None and int(np.argmin(scores)) == choice  # (the filter's evidence)
    assert list(Path(bank.path).glob("actions-*.npz"))
    off = Matcher(
        layer, bank, MatchSettings(action=ActionSettings(vote=3, classify=False)), actions=keys
    )
    assert off.ballot.choose(off.vote, queries, ranked, x) == (None, None)


def test_perform_says_whether_the_classifier_settles_the_vote(
    setup, mocap: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from mimic.cli import main
    from tests.vision.conftest import RECORDING

    base = ["perform", "--video", str(RECORDING), str(mocap), "--clips", "13_30"]
    for extra, said in (([], True), (["--no-classify"], False)):
        out = tmp_path / f"a{len(extra)}.bvh"
        more = [*extra, "--no-fuse"]  # (the landmarks' voice is said of below)
        assert main([*base, *more, "--seconds", "1.5", "--out", str(out)]) == 0
        err = capsys.readouterr().err
        assert "actions: " in err
        assert ("settled by an action classifier" in err) is said
    # a silhouette video: with ``--fuse`` (the default) the silhouette's vote also weighs
    # the landmarks the pose model reads from each silhouette, and the run says so; with
    # ``--no-fuse`` it says nothing of it
    for flag, said in (("--fuse", True), ("--no-fuse", False)):
        out = tmp_path / f"fuse{flag}.bvh"
        assert main([*base, flag, "--seconds", "1.5", "--out", str(out)]) == 0
        err = capsys.readouterr().err
        assert ("also weighs the landmarks the pose model reads" in err) is said, err
        assert "weighs it too" not in err  # (the landmarks' fallback: colour frames only)


def test_fused_scores_weigh_the_descriptor_that_fits_better() -> None:
    a, b = np.array([1.0, 1.5, 2.0]), np.array([2.0, 1.0, 1.2])
    np.testing.assert_allclose(fused([a, b], [0.4, 0.4]), (a + b) / 2)  # alike: the mean
    # half the per-frame cost: 2**FIT_POWER times the weight
    w = 2.0**FIT_POWER
    np.testing.assert_allclose(fused([a, b], [0.5, 0.25]), (a + w * b) / (1 + w))
    assert int(np.argmin(fused([a, b], [0.5, 0.25]))) == 1
    assert int(np.argmin(fused([a, b], [0.25, 0.5]))) == 0
    # a weight multiplies the fit's (the silhouette's: how many limbs are hidden)
    np.testing.assert_allclose(fused([a, b], [0.4, 0.4], [1.0, 0.5]), (a + 0.5 * b) / 1.5)
    np.testing.assert_allclose(fused([a, b], [0.5, 0.25], [1.0, 0.0]), a)


def test_a_ballot_with_a_partner_takes_the_better_fitting_descriptors_action(setup) -> None:
    """``ActionChoice.partner`` (the silhouette beside the landmarks): its scores are
    weighed with the ballot's own by each one's fit and its weight, so a partner that fits
    far better carries the vote, one that fits far worse or weighs nothing does not, and
    none leaves the ballot's own."""
    lib, layer, bank = setup
    keys = action_keys(lib.clips)
    assert keys is not None
    m = Matcher(layer, bank, MatchSettings(action=ActionSettings(vote=3)), actions=keys)
    x = np.asarray(bank.features[100 : 100 + m.n, 3], dtype=np.float64)
    queries = m.queries(x)
    assert queries is not None
    ranked: list = []
    m.windows.ranked(queries, ranked)
    own, _ = m.ballot.choose(m.vote, queries, ranked, x)
    assert own is not None
    fit = m.ballot.fit(ranked, queries[0])
    got = m.ballot.scores(m.vote, queries, ranked)
    assert got is not None and got[1] == fit and np.isfinite(got[0]).all()
    other = (own + 1) % got[0].size
    theirs = np.full(got[0].size, 3.0)
    theirs[other] = 1.0
    for their_fit, weight, want in (
        (fit / 10, 1.0, other),
        (fit * 10, 1.0, own),
        (fit / 10, 0.0, own),
    ):
        m.ballot.partner = lambda vote, f=their_fit, w=weight: (theirs, f, w)
        choice, scores = m.ballot.choose(m.vote, queries, ranked, x)
        assert choice == want and scores is not None and int(np.argmin(scores)) == want
    m.ballot.partner = lambda vote: None
    assert m.ballot.choose(m.vote, queries, ranked, x)[0] == own
