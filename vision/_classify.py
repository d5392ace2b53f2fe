"""Which action a window shows, learned from the library's own labelled windows (issue 16).

The window search names the library window nearest the performer's, and its action is
the decision's vote. Where two actions' best windows cost nearly the same, the nearest
is often the wrong one: an action rich in shapes (side twists, seen from 18 views) has a
window near almost anything. A classifier that has seen every window of every action in
every view settles those near ties: linear discriminant analysis (scikit-learn's
``LinearDiscriminantAnalysis``, eigen solver, shrinkage 0.1) of a window's summary (the
numbers DTW compares at ``TIMES`` evenly spread frames, and their mean and spread over
the window), fitted to the bank's windows with the action of their last frame.

The decision's action is then the one with the least ``cost / best cost - WEIGHT * log p``
(``choose_action``): its best window's DTW cost, relative to the best of all, less the
classifier's log-probability of it (for the performer as seen or mirrored, whichever is
more probable). On ``bench_recognition``'s leave-one-take-out folds the two together
recognise more windows than either alone, with either descriptor, and any ``WEIGHT``
from 0.01 to 0.07 does about as well; 0.02 holds up best with noisier landmarks
(``benchmarks/HISTORY.md``).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from control.artifacts import array_digest, read_checked_npz, write_checked_npz
from control.dtw import ShapeTable

__all__ = [
    "CLASSIFIER_VERSION",
    "TIMES",
    "WEIGHT",
    "ActionClassifier",
    "ClassifierFileError",
    "action_scores",
    "cached_action_classifier",
    "choose_action",
    "voted_action",
    "window_summary",
]

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: frames of a window the summary keeps (evenly spread, first and last included)
TIMES = 5
#: the classifier's log-probability against the cost ratio (``choose_action``)
WEIGHT = 0.02
#: at most this many (window, view) pairs teach the classifier (evenly spread)
LEARN_ROWS = 60_000
SHRINKAGE = 0.1
#: the stored classifier's format (``cached_action_classifier``)
CLASSIFIER_VERSION = 1
#: the least log-probability counted (an action the classifier never saw)
FLOOR = -50.0


def window_summary(seq: NDArray[np.floating]) -> FloatArray:
    """The summary ``(..., (TIMES + 2) * k)`` of windows ``(..., m, k)`` of the numbers DTW
    compares: the frames at ``TIMES`` evenly spread times, then the mean and standard
    deviation over the window."""
    seq = np.asarray(seq, dtype=np.float64)
    m = seq.shape[-2]
    at = np.linspace(0, m - 1, TIMES).round().astype(np.int64)
    lead = seq.shape[:-2]
    return np.concatenate(
        [seq[..., at, :].reshape(*lead, -1), seq.mean(axis=-2), seq.std(axis=-2)], axis=-1
    )


class ActionClassifier:
    """Log-probabilities of each action for a performer's window: a linear model
    ``coef (C, D)``, ``intercept (C,)`` over ``window_summary``, ``classes`` the actions'
    numbers (``control.motion.action_keys``)."""

    def __init__(self, classes: IntArray, coef: FloatArray, intercept: FloatArray) -> None:
        self.classes = np.asarray(classes, dtype=np.int64)
        self.coef = np.asarray(coef, dtype=np.float64)
        self.intercept = np.asarray(intercept, dtype=np.float64)
        if self.coef.ndim != 2 or self.coef.shape[0] != self.classes.size:
            raise ValueError("coef must have one row per class")
        if self.intercept.shape != (self.classes.size,):
            raise ValueError("intercept must have one number per class")

    @classmethod
    def learn(
        cls,
        shape: ShapeTable,
        centre: FloatArray,
        starts: IntArray,
        length: int,
        actions: IntArray,
    ) -> ActionClassifier | None:
        """Fitted to the windows of ``length`` frames at ``starts`` of the search's
        tables (``shape (N, V, d)``, ``centre (N, V, 2)``: ``vision.window_tables``), in
        every view, each of the action of its last frame (``actions (N,)``); ``None``
        when the windows show fewer than two actions."""
        from sklearn.discriminant_analysis import LinearDiscriminantAnalysis

        views = shape.shape[1]
        label = actions[starts + length - 1]
        if starts.size == 0 or np.unique(label).size < 2:
            return None
        # (window, view) pairs evenly spread, at most LEARN_ROWS of them
        pick = np.linspace(0, starts.size * views - 1, min(LEARN_ROWS, starts.size * views))
        pick = np.unique(pick.round().astype(np.int64))
        x = np.empty((pick.size, (TIMES + 2) * (shape.shape[2] + 2)))
        for a in range(0, pick.size, 4096):  # in blocks: windows of every view are large
            s, v = starts[pick[a : a + 4096] // views], pick[a : a + 4096] % views
            rows = s[:, None] + np.arange(length)
            seq = np.concatenate(
                [
                    shape[rows, v[:, None]].astype(np.float64),
                    centre[rows, v[:, None]] - centre[s, v][:, None],
                ],
                axis=-1,
            )
            x[a : a + s.size] = window_summary(seq)
        y = label[pick // views]
        if np.unique(y).size < 2:
            return None
        lda = LinearDiscriminantAnalysis(solver="eigen", shrinkage=SHRINKAGE)
        lda.fit(x, y)
        coef, intercept = lda.coef_, lda.intercept_
        if lda.classes_.size == 2:  # scikit-learn keeps one row for two classes
            coef = np.vstack([-coef[0] / 2, coef[0] / 2])
            intercept = np.array([-intercept[0] / 2, intercept[0] / 2])
        return cls(lda.classes_, coef, intercept)

    def log_proba(self, queries: list[FloatArray], n_actions: int = 0) -> FloatArray:
        """Each class's log-probability ``(C,)`` for a performer's window, read as each
        of ``queries`` (``vision.performer_queries``: as seen, mirrored, ...): the most
        probable reading for each class. With ``n_actions``, by action number instead
        ``(n_actions,)``, ``FLOOR`` for an action that is no class."""
        x = window_summary(np.stack([np.asarray(q, dtype=np.float64) for q in queries]))
        z = x @ self.coef.T + self.intercept
        z -= z.max(axis=1, keepdims=True)
        logp = (z - np.log(np.exp(z).sum(axis=1, keepdims=True))).max(axis=0)
        if not n_actions:
            return np.asarray(logp, dtype=np.float64)
        out = np.full(n_actions, FLOOR)
        known = self.classes < n_actions
        out[self.classes[known]] = np.maximum(logp[known], FLOOR)
        return out


def voted_action(
    ranked: list[tuple[IntArray, IntArray, FloatArray]],
    actions: IntArray,
    length: int,
    classifier: ActionClassifier | None,
    queries: list[FloatArray],
    n_actions: int = 0,
) -> int | None:
    """The action a decision votes for (``choose_action``), from the search's ranked
    short lists (``WindowIndex.search``'s ``ranked``: each action's best window among
    them) and ``classifier``; ``None`` without a classifier (the best window's action
    then) or without a window. ``n_actions``: ``actions.max() + 1``, if the caller
    has it."""
    scores = action_scores(ranked, actions, length, classifier, queries, n_actions)
    if scores is None or not np.isfinite(scores).any():
        return None
    return int(np.argmin(scores))


def action_scores(
    ranked: list[tuple[IntArray, IntArray, FloatArray]],
    actions: IntArray,
    length: int,
    classifier: ActionClassifier | None,
    queries: list[FloatArray],
    n_actions: int = 0,
    unseen: bool = False,
) -> FloatArray | None:
    """Each action's score at this decision (``choose_action``'s, lower is better; inf:
    no window of it among the ranked short lists); ``None`` without a classifier or a
    window. ``unseen``: an action with no window among the lists is scored at their
    cutoff instead (the least cost a window left off every list can have), not ruled
    out, for a filter that weighs every action at every decision."""
    if classifier is None or not ranked:
        return None
    cost = np.full(n_actions or int(actions.max()) + 1, np.inf)
    for s, _, c in ranked:
        np.minimum.at(cost, actions[np.minimum(s + length - 1, actions.size - 1)], c)
    cutoffs = [float(np.max(c)) for _, _, c in ranked if len(c)] if unseen else []
    if cutoffs:
        cost[~np.isfinite(cost)] = min(cutoffs)
    return action_score(cost, classifier.log_proba(queries, cost.size))


def action_score(
    costs: FloatArray, log_proba: FloatArray | None, weight: float = WEIGHT
) -> FloatArray:
    """``costs[a] / min(costs) - weight * log_proba[a]`` (inf where ``costs`` is)."""
    ok = np.isfinite(costs)
    if not ok.any():
        return np.full(costs.shape, np.inf)
    best = max(float(costs[ok].min()), 1e-12)
    if log_proba is None or weight <= 0:
        return np.where(ok, costs / best, np.inf)
    return np.where(ok, costs / best - weight * log_proba, np.inf)


def choose_action(costs: FloatArray, log_proba: FloatArray | None, weight: float = WEIGHT) -> int:
    """The action (an index of ``costs``) a decision votes for: the least ``costs[a] /
    min(costs) - weight * log_proba[a]`` over actions with a window (finite cost), or the
    cheapest without ``log_proba``; -1 when none has a window."""
    ok = np.isfinite(costs)
    if not ok.any():
        return -1
    if log_proba is None or weight <= 0:
        return int(np.flatnonzero(ok)[np.argmin(costs[ok])])
    return int(np.argmin(action_score(costs, log_proba, weight)))


class ClassifierFileError(ValueError):
    """A stored action classifier that cannot be used (names the file)."""

    def __init__(self, path: str | Path, problem: str) -> None:
        self.path = Path(path)
        self.problem = problem
        super().__init__(f"{path}: {problem}")


def cached_action_classifier(
    shape: ShapeTable,
    centre: FloatArray,
    starts: IntArray,
    length: int,
    actions: IntArray,
    folder: str | Path | None,
    key: str = "",
) -> ActionClassifier | None:
    """``ActionClassifier.learn(shape, centre, starts, length, actions)``, stored in
    ``folder`` (a bank's folder) as ``actions-<hash>.npz`` and loaded from there next
    time, checked (``control.artifacts``). The hash is of the tables' ``key``
    (``cached_window_tables``), ``starts`` and ``actions``, or without a key of the
    tables themselves. A damaged file is learned again with a warning naming it; a
    folder that cannot be written is only read."""
    if folder is None:
        return ActionClassifier.learn(shape, centre, starts, length, actions)
    text = f"{CLASSIFIER_VERSION}|{length}|{TIMES}|{LEARN_ROWS}|{SHRINKAGE}|{key}"
    digest = array_digest(text, (starts, actions) if key else (shape, centre, starts, actions))
    path = Path(folder) / f"actions-{digest[:24]}.npz"
    if path.is_file():
        try:
            keys = ("classes", "coef", "intercept")
            d = read_checked_npz(path, keys, ClassifierFileError, "action classifier")
            if d["classes"].size == 0:
                return None  # (stored: the windows show fewer than two actions)
            return ActionClassifier(d["classes"], d["coef"], d["intercept"])
        except ClassifierFileError as exc:  # (its message names the file)
            log.warning("learning the action classifier again: %s", exc)
        except ValueError as exc:  # arrays of the wrong shapes
            log.warning("learning the action classifier again: %s: %s", path, exc)
    out = ActionClassifier.learn(shape, centre, starts, length, actions)
    arrays = {
        "classes": np.zeros(0, dtype=np.int64) if out is None else out.classes,
        "coef": np.zeros((0, 0)) if out is None else out.coef,
        "intercept": np.zeros(0) if out is None else out.intercept,
    }
    try:
        write_checked_npz(path, arrays)
    except OSError as exc:  # a bank folder that is only ours to read
        log.info("the action classifier is not stored: %s", exc)
    return out
