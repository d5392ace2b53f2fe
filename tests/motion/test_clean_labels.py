"""Cleaned labels: each boundary between two labelled actions where the motion changes."""

from __future__ import annotations

import csv
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from control.motion import clean_labels, load_library, source_label_rows

FPS = 15.0


@pytest.fixture(scope="module")
def cycles(mocap: Path) -> tuple[np.ndarray, np.ndarray]:
    """8 s of 13_29's jumping jacks and 8 s of its squats, at 15 frames/s."""
    clip = load_library(mocap, fps=FPS, clips=["13_29"], clean_labels=False).clip("13_29")
    q = clip.motion.quats
    return q[0:56], q[round(32 * FPS) : round(32 * FPS) + 120]


def _take(cycles: tuple[np.ndarray, np.ndarray], blend: int) -> np.ndarray:
    """Jumping jacks, then ``blend`` frames from their last pose to the squats' first (a
    transition, each joint's rotation blended and normalised), then the squats."""
    a, b = cycles
    w = np.linspace(0.0, 1.0, blend + 2)[1:-1, None, None]
    start, end = a[-1], np.where((a[-1] * b[0]).sum(-1, keepdims=True) < 0, -b[0], b[0])
    mid = (1 - w) * start + w * end
    mid /= np.linalg.norm(mid, axis=-1, keepdims=True)
    return np.concatenate([a, mid, b])


@pytest.mark.parametrize("off", [-0.8, 0.8])
@pytest.mark.parametrize("blend", [0, 8])
def test_a_boundary_moves_to_the_known_transition(
    cycles: tuple[np.ndarray, np.ndarray], off: float, blend: int
) -> None:
    # the label file's boundary 0.8 s early or late; the cleaned one lies in the
    # transition (or at the junction when there is none) to within 0.2 s
    q = _take(cycles, blend)
    first, last = cycles[0].shape[0], cycles[0].shape[0] + blend  # the transition
    labels = np.zeros(q.shape[0], dtype=np.int64)
    labels[first + round(off * FPS) :] = 1
    cleaned, moves = clean_labels(q, labels, FPS)
    assert len(moves) == 1
    b = moves[0].cleaned
    assert first - 0.2 * FPS <= b <= last + 0.2 * FPS, (b, first, last)
    assert (cleaned[:b] == 0).all() and (cleaned[b:] == 1).all()
    # the transition found lies within the true one, give or take 0.2 s
    assert moves[0].transition_start >= first - 0.2 * FPS


def test_unlabelled_stretches_and_short_ones_are_left_alone(
    cycles: tuple[np.ndarray, np.ndarray],
) -> None:
    q = _take(cycles, 0)
    labels = np.full(q.shape[0], -1, dtype=np.int64)
    labels[60:] = 1  # unlabelled, then an action: nothing to move
    assert (clean_labels(q, labels, FPS)[0] == labels).all()
    labels[:3] = 0  # an action too short to have a cycle
    assert (clean_labels(q, labels, FPS)[0] == labels).all()
    with pytest.raises(ValueError, match="one label per frame"):
        clean_labels(q, labels[:-1], FPS)


def test_rows_at_the_source_rate_round_trip() -> None:
    # library frames k show source frames 8k (a 120 frames/s file at 15)
    labels = np.array([0, 0, 0, 1, 1, -1, -1, 1])
    rows = source_label_rows(labels, ("A", "B"), np.arange(8) * 8.0, 60)
    # (a source frame halfway between two library frames takes the earlier's label)
    assert rows == [(1, 21, "A"), (22, 37, "B"), (54, 60, "B")]


def _mimic(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "mimic", *args], capture_output=True, text=True, check=False
    )


@pytest.mark.slow
def test_the_library_loads_cleaned_labels_and_the_command_writes_them(
    mocap: Path, tmp_path: Path
) -> None:
    kept = load_library(mocap, clips=["13_30"], clean_labels=False).clip("13_30")
    clean = load_library(mocap, clips=["13_30"]).clip("13_30")
    assert (clean.labels != kept.labels).any()  # some boundary moved...
    # ...by at most the reach either side of a source boundary, never elsewhere
    edges = np.flatnonzero(np.diff(kept.labels)) + 1
    moved = np.flatnonzero(clean.labels != kept.labels)
    assert np.min(np.abs(moved[:, None] - edges[None, :]), axis=1).max() <= 1.5 * FPS
    # the command, on a copy of the take (it must never write into a library)
    lib = tmp_path / "lib"
    for rel in ("cmu/subjects/13/13.asf", "cmu/subjects/13/13_30.amc", "cmu/labels/13_30.csv"):
        (lib / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(mocap / rel, lib / rel)
    source = (lib / "cmu/labels/13_30.csv").read_bytes()
    out = tmp_path / "cleaned"
    run = _mimic("library", "labels", str(lib), "--out", str(out))
    assert run.returncode == 0, run.stderr
    assert "13_30: KneeRaise -> Squat at 11.80 s, moved" in run.stdout
    with open(out / "13_30.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["action"] for r in rows] == ["JumpJack", "Twist", "KneeRaise", "Squat", "Jog"]
    assert int(rows[0]["first_frame"]) == 1
    assert [int(r["first_frame"]) for r in rows] != [1, 217, 805, 1417, 1933]  # moved
    # the library's own label files cannot be the output, nor anywhere in the library
    for inside in (lib / "cmu/labels", lib / "cleaned"):
        bad = _mimic("library", "labels", str(lib), "--out", str(inside))
        assert bad.returncode != 0 and "the source labels stay" in bad.stderr, bad.stderr
    assert (lib / "cmu/labels/13_30.csv").read_bytes() == source
    assert not (lib / "cleaned").exists()
