"""Which way the performer faces, for silhouettes (``vision._facing``)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from control.clusters import orientation_distance
from control.graph import weighted_joints
from control.motion import load_library, mirrored_rotations, qmul
from vision import MatchSettings, PerformSettings, RecordSettings, VideoSource, record_clip
from vision._facing import STEP, Facing, clip_headings, clip_sides
from vision._perform import Performance


def test_headings_are_where_the_hips_face(mocap: Path) -> None:
    """13_30's subject faces +Z (as the ring's view 0 sees it, from the front); turned a
    quarter round +Y, every heading moves by a quarter."""
    clip = load_library(mocap, fps=30, clips=["13_30"]).clip("13_30")
    h = clip_headings([clip])
    assert h.shape == (clip.motion.n_frames,)
    assert abs(math.degrees(np.angle(np.exp(1j * h).mean()))) < 15.0
    turn = np.array([math.cos(math.pi / 4), 0.0, math.sin(math.pi / 4), 0.0])  # 90 degrees
    q = clip.motion.quats.copy()
    q[:, 0] = qmul(np.broadcast_to(turn, q[:, 0].shape), q[:, 0])
    turned = dataclasses.replace(clip, motion=dataclasses.replace(clip.motion, quats=q))
    moved = np.angle(np.exp(1j * (clip_headings([turned]) - h)))
    np.testing.assert_allclose(moved, math.pi / 2, atol=1e-6)


def test_only_windows_that_show_a_side_are_weighed(mocap: Path) -> None:
    """13_30's knee raises show a side (a pose unlike its mirror image), its squats and
    jumping jacks do not; a window that shows none is seen from neither front nor back."""
    clip = load_library(mocap, fps=30, clips=["13_30"]).clip("13_30")
    sided = clip_sides([clip], 30)
    labels = np.array([clip.label_at(f) for f in range(clip.motion.n_frames)])
    assert sided[labels == "KneeRaise"].mean() > 0.9
    assert sided[labels == "Squat"].mean() < 0.2 and sided[labels == "JumpJack"].mean() < 0.2
    f = Facing(np.zeros(4), np.radians([0.0, 180.0]), 0, 0.3, sided=np.array([1, 0, 1, 0], bool))
    np.testing.assert_array_equal(f.zone, [[1, -1], [0, 0], [1, -1], [0, 0]])


def _facing() -> Facing:
    az = np.radians(np.arange(18) * 20.0)  # view 0 in front of the avatar, 9 behind
    return Facing(np.zeros(50), az, half=0, penalty=0.3, memory=0.5)


def _lists(front: float, back: float, side: float = 99.0) -> list:
    """One window seen from the front (view 0), from behind (view 9) and from the side
    (view 4, 80 degrees) per reading: as seen costs ``front``, ``back``, ``side``;
    mirrored 1 more."""
    s, v = np.array([10, 20, 30]), np.array([0, 9, 4])
    return [(s, v, np.array([front, back, side])), (s, v, np.array([front, back, side]) + 1)]


def test_the_facing_weighs_what_it_does_not_explain_and_learns_from_the_costs() -> None:
    f = _facing()
    assert f.toward  # before any evidence: the performer faces the camera
    np.testing.assert_array_equal(f.zone[0, [0, 9, 4, 5, 3]], [1, -1, 0, 0, 1])
    # facing the camera: as seen from behind and mirrored from the front cost 1.3 times
    got = f.weigh(_lists(10.0, 9.8))
    np.testing.assert_allclose(got[0][2], [10.0, 9.8 * 1.3, 99.0])
    np.testing.assert_allclose(got[1][2], [11.0 * 1.3, 10.8, 100.0])
    # the windows it did not explain were the cheaper (9.8 against 10): facing away now
    assert f.evidence == pytest.approx(math.log(9.8 / 10.0))
    assert not f.toward
    got = f.weigh(_lists(10.0, 9.8), observe=False)
    np.testing.assert_allclose(got[0][2], [13.0, 9.8, 99.0])  # (the side: never)
    assert f.evidence == pytest.approx(math.log(9.8 / 10.0))  # (not observed)
    # one view at a time, as ``weigh``: the views that are not explained cost more
    costs = np.ones((2, 18))
    w = f.weigh_views(costs, 0)
    np.testing.assert_allclose(w[0, [0, 9, 4]], [1.3, 1.0, 1.0])
    np.testing.assert_allclose(w[1, [0, 9, 4]], [1.0, 1.3, 1.0])
    # the evidence fades with ``memory``, and one decision adds at most ``STEP``: a
    # cheaper front (by 10%) turns it round
    f.weigh(_lists(9.0, 10.0))
    assert f.evidence == pytest.approx(0.5 * math.log(9.8 / 10.0) + STEP)
    assert f.toward


def _own_side(decisions: list[dict], lib_motion, perf_motion, first: int) -> float:
    """Of the decisions where the avatar's pose is clearly nearer the performer's or its
    mirror image, the share nearer the performer's own side."""
    joints = weighted_joints(lib_motion.skeleton)
    own, other = lib_motion.quats[:, joints], mirrored_rotations(lib_motion, joints)
    truth = perf_motion.quats[:, joints]

    def dist(a: np.ndarray, b: np.ndarray) -> float:
        return float(np.sum(orientation_distance(b, a) ** 2))

    hits = []
    for d in decisions:
        if d["decision"] is None:
            continue
        k = first + round(d["t"] * perf_motion.fps)
        a, b = dist(own[d["clip_frame"]], truth[k]), dist(other[d["clip_frame"]], truth[k])
        if abs(a - b) > 0.1:
            hits.append(a < b)
    assert len(hits) >= 50
    return float(np.mean(hits))


@pytest.mark.parametrize(
    "azimuth, toward, recency", [(10.0, True, 0.0), (190.0, False, 0.0), (190.0, False, 2.0)]
)
def test_the_avatar_raises_the_knee_the_performer_raises(
    setup, mocap: Path, tmp_path: Path, azimuth: float, toward: bool, recency: float
) -> None:
    """13_29's knee raises (another take) filmed from the front and from behind, the
    library 13_30: the avatar raises the performer's knee, not the other, at most
    decisions where the two differ, and learns that the performer faces the camera or
    away; without weighing the facing it does so about half the time. With DTW weighing
    the last frames more (``recency``) the evidence is still read over the whole window
    (from behind it settled on the camera side without that)."""
    lib, layer, bank = setup
    perf = load_library(mocap, fps=30, clips=["13_29"]).clip("13_29")
    first = 675  # 22.5 s: knee raises for 9 s
    video = tmp_path / "knees.mkv"
    rs = dataclasses.replace(RecordSettings(), width=160, height=120, azimuth=azimuth)
    record_clip(perf, video, rs, first, first + 285)
    shares = []
    for facing in (0.3, 0.0):
        settings = PerformSettings(match=MatchSettings(facing=facing, recency=recency))
        run = Performance(VideoSource(video, silhouette=True), layer, bank, lib.clips, settings)
        r = run.run()
        shares.append(_own_side(r.decisions, lib.clips[0].motion, perf.motion, first))
        if facing:
            assert (
                run.matcher.windows.facing is not None
                and run.matcher.windows.facing.toward == toward
            )
            said = {d["facing"] for d in r.decisions[-5:] if d["decision"] is not None}
            assert said == {"camera" if toward else "away"}  # (the decision log says so)
        else:
            assert run.matcher.windows.facing is None
    assert shares[0] >= 0.7 and shares[0] > shares[1] + 0.1, shares
