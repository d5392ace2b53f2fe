"""Following a performer from every side, through the real pose model: another take
(13_29) filmed in colour by ``mimic record --colour`` (the shaded body with a face) and
read by MediaPipe Pose, whose side views give the far limbs the low visibilities real
footage gives them; the library is 13_30 with a pose bank."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from control.motion import load_library
from tests.conftest import Prebuild
from vision import (
    ActionSettings,
    MatchSettings,
    PerformSettings,
    PersonSegmenter,
    RecordSettings,
    VideoSource,
    decision_points,
    evaluation,
    perform,
    record_clip,
    truth_for,
)
from vision._fallback import HIDDEN_FULL
from vision._frames import UNPOSED
from vision._perform import Performance

#: the takes the tests film, as ``(seconds, how)``: ``tests/prebuild.py`` films them in
#: the background (part ``films``) while the earlier tests run
FILMS: tuple[tuple[tuple[float, float], dict[str, float]], ...] = (
    ((0.0, 8.0), {"azimuth": 90.0}),
    ((0.0, 8.0), {"azimuth": 0.0, "turn": 90.0}),
    ((32.0, 38.0), {"azimuth": 20.0}),
    ((0.0, 9.0), {"azimuth": 20.0}),
    ((0.0, 6.0), {"azimuth": 0.0}),
    ((32.0, 38.0), {"azimuth": 0.0}),
)


def film(mocap: Path, folder: Path, seconds: tuple[float, float], **how: float) -> Path:
    """13_29 between ``seconds``, filmed in colour at 15 frames/s as ``how`` says, into
    ``folder`` (kept there: a film the session has made is not made again)."""
    name = "-".join([f"{s:g}" for s in seconds] + [f"{k}{v:g}" for k, v in sorted(how.items())])
    video = folder / f"13_29-{name}.mkv"
    if not video.with_name(video.name + ".json").exists():
        clip = load_library(mocap, fps=15, clips=["13_29"]).clip("13_29")
        settings = RecordSettings(colour=True, width=480, height=360, **how)
        record_clip(clip, video, settings, round(seconds[0] * 15), round(seconds[1] * 15))
    return video


def _film(mocap: Path, films: Path, seconds: tuple[float, float], **how: float) -> Path:
    assert (seconds, how) in FILMS, "a take the tests film is listed in FILMS"
    return film(mocap, films, seconds, **how)


@pytest.fixture(scope="module")
def films(prebuild: Prebuild, session_cache: Path) -> Path:
    """The folder of the session's films (``FILMS``), once the background has made them
    (or given up: a film not there is made by the test that needs it)."""
    prebuild.wait("films")
    return session_cache / "films"


def _frames(video: Path) -> list[np.ndarray]:
    cap = cv2.VideoCapture(str(video))
    frames = []
    while True:
        ok, img = cap.read()
        if not ok:
            break
        frames.append(img)
    cap.release()
    return frames


def _rewrite(video: Path, out: Path, change: Callable[[np.ndarray], np.ndarray]) -> Path:
    """``video`` with ``change`` made to every frame, as ``out``, with its sidecar."""
    frames = _frames(video)
    size = (frames[0].shape[1], frames[0].shape[0])
    writer = cv2.VideoWriter(str(out), cv2.VideoWriter.fourcc(*"FFV1"), 15.0, size)
    for img in frames:
        writer.write(np.ascontiguousarray(change(img)))
    writer.release()
    out.with_name(out.name + ".json").write_text(video.with_name(video.name + ".json").read_text())
    return out


def _follow(setup: Any, bank: Any, video: Path) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    lib, layer, _ = setup
    r = perform(VideoSource(video), layer, bank, lib.clips, PerformSettings(), seed=1)
    truth = truth_for(video)
    assert truth is not None
    return evaluation(r.decisions, lib.clips, truth, r.media_seconds), r.decisions


@pytest.mark.gl
def test_a_side_view_is_matched_and_its_action_found(
    setup: Any, pose_bank: Any, mocap: Path, films: Path
) -> None:
    # jumping jacks, then side twists, seen from the performer's left: the right arm and
    # leg are hidden much of the time, and every frame is matched all the same
    video = _film(mocap, films, (0.0, 8.0), azimuth=90.0)
    report, decisions = _follow(setup, pose_bank, video)
    hidden = [d for d in decisions if any(j.startswith("right") for j in d.get("hidden", []))]
    assert len(hidden) > len(decisions) // 3  # the test shows what a side view hides
    points = report["decision_points"]
    assert points["person_in_view_undecided_share"] <= 0.05, points
    assert report["best_at_lag_le_1s"] >= 0.6, report["per_action_at_best_lag"]
    # the timeline a viewer reads: the performer's action and the avatar's at each point
    line = report["timeline"]
    assert len(line["t"]) == len(line["performer"]) == len(line["avatar"]) == len(decisions)
    assert {"jumpjack", "twist"} <= set(line["performer"])  # (the truth: lower case)


@pytest.mark.gl
def test_a_performer_who_turns_is_followed_throughout(
    setup: Any, pose_bank: Any, mocap: Path, films: Path
) -> None:
    # from facing the camera to showing it their side over 8 s
    video = _film(mocap, films, (0.0, 8.0), azimuth=0.0, turn=90.0)
    report, decisions = _follow(setup, pose_bank, video)
    assert report["decision_points"]["person_in_view_undecided_share"] <= 0.05
    late = [d for d in decisions if d["t"] > 5.0]  # turned 60 degrees or more
    assert late and sum(d["decision"] is not None for d in late) >= 0.9 * len(late)
    assert report["best_at_lag_le_1s"] >= 0.6, report["per_action_at_best_lag"]


@pytest.mark.gl
def test_a_performer_cut_off_at_the_knees_is_matched(
    setup: Any, pose_bank: Any, mocap: Path, films: Path, tmp_path: Path
) -> None:
    # squats with the frame cut above the knees, as a camera on a desk sees a performer:
    # the legs' landmarks are of low confidence for the whole clip, and the model still
    # places them; every frame is matched, and the squats found
    video = _film(mocap, films, (32.0, 38.0), azimuth=20.0)

    def cut_off(img: np.ndarray) -> np.ndarray:
        img[int(img.shape[0] * 0.62) :] = (60, 60, 60)
        return img

    cut = _rewrite(video, tmp_path / "cut.mkv", cut_off)
    report, decisions = _follow(setup, pose_bank, cut)
    legs = [d for d in decisions if "left_ankle" in d.get("hidden", [])]
    assert len(legs) > len(decisions) // 2
    points = report["decision_points"]
    # (a library of one take, and half the body unknown: a few windows match nothing)
    assert points["person_in_view_undecided_share"] <= 0.1, points
    assert report["best_at_lag_le_1s"] >= 0.6, report["per_action_at_best_lag"]


class _Taped:
    """The pose model as a run's segmenter, each of its readings of a frame (the mask,
    the landmarks, ``others``, ``unposed``) kept on ``tape``: a second run of the same
    video replays them instead of reading every frame again (the runs test the loop
    around the model; a reading takes the model about 25 ms)."""

    learning = False

    def __init__(self, tape: list[tuple[Any, ...]]) -> None:
        self.model = None if tape else PersonSegmenter("pose")
        self.tape, self.i, self.others, self.unposed = tape, 0, 0, False
        self.landmarks: np.ndarray | None = None

    def apply(self, image: np.ndarray) -> np.ndarray | None:
        if self.model is not None:
            mask = self.model.apply(image)
            model = self.model
            self.tape.append((mask, model.landmarks, model.others, model.unposed))
        mask, self.landmarks, self.others, self.unposed = self.tape[self.i]
        self.i += 1
        return mask


def _run(
    video: Path,
    setup: Any,
    bank: Any,
    segmenter: _Taped,
    settings: PerformSettings | None = None,
    **kw: Any,
) -> Performance:
    """A run of ``video`` as ``perform`` makes it, the frames read by ``segmenter``."""
    lib, layer, _ = setup
    st = settings or PerformSettings()
    run = Performance(VideoSource(video), layer, bank, lib.clips, st, seed=1, **kw)
    run.reader.segmenter = segmenter
    return run


@pytest.mark.gl
def test_the_silhouette_weighs_in_each_landmark_decision_where_limbs_are_hidden(
    setup: Any, pose_bank: Any, mocap: Path, films: Path
) -> None:
    # the side view (jumping jacks, then twists): with ``fuse`` (``--fuse``) the
    # silhouette's action scores are weighed into each landmark decision's ballot where
    # the pose model's limbs are of low confidence (from the side, most windows), and
    # the action is found
    lib, _, silhouettes = setup
    video = _film(mocap, films, (0.0, 8.0), azimuth=90.0)
    fused = PerformSettings(match=MatchSettings(action=ActionSettings(fuse=True)))
    run = _run(video, setup, pose_bank, _Taped([]), fused, fallback=silhouettes)
    assert run.fallback is not None and run.matcher.ballot.partner is not None
    asked: list[Any] = []
    own = run.fallback.evidence
    run.fallback.evidence = lambda vote: asked.append(got := own(vote)) or got  # type: ignore[method-assign]
    run.matcher.ballot.partner = run.fallback.evidence
    r = run.run()
    by_landmarks = [d for d in r.decisions if d.get("by") == "landmarks"]
    assert len(by_landmarks) > 50 and len(asked) >= len(by_landmarks) - 10
    assert sum(a is not None for a in asked) >= 0.8 * len(asked)  # (limbs hidden: it speaks)
    # the log says where it weighed in, and how much
    weighed = [d["silhouette_weight"] for d in by_landmarks if "silhouette_weight" in d]
    assert len(weighed) >= 0.8 * len(by_landmarks) - 10 and all(0 < w <= 1 for w in weighed)
    truth = truth_for(video)
    assert truth is not None
    report = evaluation(r.decisions, lib.clips, truth, r.media_seconds)
    assert report["best_at_lag_le_1s"] >= 0.6, report["per_action_at_best_lag"]
    # its weight follows the window's share of limbs of low confidence: none with every
    # limb seen (a performer facing the camera, whom the landmarks read well), in full
    # from HIDDEN_FULL on
    fallback, vote = run.fallback, run.matcher.vote
    for seen in fallback.history:
        seen.hidden = 0.0
    assert fallback.evidence(vote) is None
    for seen in fallback.history:
        seen.hidden = HIDDEN_FULL / 2
    half = fallback.evidence(vote)
    assert half is not None and half[2] == pytest.approx(0.5)
    for seen in fallback.history:
        seen.hidden = 1.0
    whole = fallback.evidence(vote)
    assert whole is not None and whole[2] == 1.0
    # without the silhouette beside them there is nothing to weigh; and with ``fuse``
    # off (``--no-fuse``), the silhouette decides only where the landmarks fail
    alone = _run(video, setup, pose_bank, _Taped([]), fused)
    assert alone.fallback is None and alone.matcher.ballot.partner is None
    off = PerformSettings(match=MatchSettings(action=ActionSettings(fuse=False)))
    plain = _run(video, setup, pose_bank, _Taped([]), off, fallback=silhouettes)
    assert plain.fallback is not None and plain.matcher.ballot.partner is None


class _Misread(_Taped):
    """The pose model, whose landmarks fail between ``hide`` seconds, its mask as it is:
    ``torso``, the torso's landmarks of low confidence (as when the torso is cut by the
    frame or hidden); ``limbs``, the limbs' read all at the nose, the torso upright (a
    reading no pose of the library's is near)."""

    def __init__(self, hide: tuple[float, float], fails: str, tape: list[Any]) -> None:
        super().__init__(tape)
        self.hide, self.fails, self.t = hide, fails, 0.0

    def apply(self, image: np.ndarray) -> np.ndarray | None:
        mask = super().apply(image)
        if self.landmarks is not None and self.hide[0] <= self.t < self.hide[1]:
            self.landmarks = self.landmarks.copy()
            if self.fails == "torso":
                self.landmarks[[11, 12, 23, 24], 2] = 0.1  # shoulders and hips
            else:
                self.landmarks[[13, 14, 15, 16, 25, 26, 27, 28], :2] = self.landmarks[0, :2]
        self.t += 1 / 15
        return mask


@pytest.mark.gl
@pytest.mark.parametrize(
    ("fails", "why"),
    [("torso", "torso landmarks of low confidence"), ("limbs", "no match")],
)
def test_where_the_landmarks_fail_the_silhouette_decides(
    setup: Any, pose_bank: Any, mocap: Path, films: Path, tmp_path: Path, fails: str, why: str
) -> None:
    # 13_29's jumping jacks and twists; from 2 to 7 s the landmarks fail (no torso; or
    # limbs where no body has them, read all the same) while the person mask is good:
    # half a window on, the silhouette bank decides (the log's ``by``), and the avatar
    # keeps doing the performer's action
    lib, _, silhouettes = setup
    video = _film(mocap, films, (0.0, 9.0), azimuth=20.0)
    truth = truth_for(video)
    assert truth is not None
    runs, tape = {}, []  # (the second run replays the first's readings of the model)
    for fallback in (silhouettes, None):
        misread = _Misread((2.0, 7.0), fails, tape)
        r = _run(video, setup, pose_bank, misread, fallback=fallback).run()
        runs[fallback is not None] = (r, evaluation(r.decisions, lib.clips, truth, r.media_seconds))
    r, report = runs[True]
    lost = [d for d in r.decisions if 2.6 <= d["t"] < 7.0]
    assert all(d.get("by") == "silhouette" for d in lost), [d.get("reason") for d in lost]
    # (misread limbs stay in the window a whole window on, a missing torso half of one)
    kept = [d for d in r.decisions if d["t"] >= 8.1 or 1.0 <= d["t"] < 2.0]
    assert kept and all(d.get("by") == "landmarks" for d in kept)
    assert report["decision_points"]["person_in_view_undecided"] == 0, report["decision_points"]
    assert report["best_at_lag_le_1s"] >= 0.6, report["per_action_at_best_lag"]
    # without the silhouette those points get no decision, and say why
    r, report = runs[False]
    lost = [d for d in r.decisions if 2.6 <= d["t"] < 7.0]
    assert all(d["decision"] is None for d in lost)
    assert {d["reason"].split(" (")[0] for d in lost} == {why}
    assert report["decision_points"]["person_in_view_undecided"] >= len(lost)


@pytest.mark.gl
@pytest.mark.parametrize("garbage", ["upside down", "noise"])
def test_garbage_is_still_rejected(
    setup: Any, pose_bank: Any, mocap: Path, films: Path, tmp_path: Path, garbage: str
) -> None:
    # the image upside down (the pose model may still find a body, whose torso is then
    # upside down), or noise for every frame: no decision follows it
    video = _film(mocap, films, (0.0, 6.0), azimuth=0.0)
    rng = np.random.default_rng(0)

    def change(img: np.ndarray) -> np.ndarray:
        if garbage == "upside down":
            return img[::-1]
        return rng.integers(0, 256, img.shape, dtype=np.uint8)

    bad = _rewrite(video, tmp_path / "garbage.mkv", change)
    silhouettes, tape = setup[2], []  # (the second run replays the first's readings)
    for fallback in (None, silhouettes):  # nor does the silhouette follow it
        r = _run(bad, setup, pose_bank, _Taped(tape), fallback=fallback).run()
        points = decision_points(r.decisions)
        assert points["decided"] <= 0.1 * points["points"], points


@pytest.mark.gl
def test_a_performer_who_walks_out_and_back_is_followed_again(
    setup: Any, pose_bank: Any, mocap: Path, films: Path, tmp_path: Path
) -> None:
    # the room empty from 3 to 5 s: the frames seen last decide while they fill half the
    # window, then nobody is there; back, half a window fills, and the performer is
    # followed again
    video = _film(mocap, films, (0.0, 9.0), azimuth=20.0)
    seen = iter(range(10**6))

    def away(img: np.ndarray) -> np.ndarray:
        if 3.0 <= next(seen) / 15 < 5.0:
            img[:] = RecordSettings().background
        return img

    report, decisions = _follow(setup, pose_bank, _rewrite(video, tmp_path / "away.mkv", away))
    gone = [d for d in decisions if 3.6 <= d["t"] < 5.0]
    assert gone and {d.get("reason") for d in gone} == {"nobody in view"}
    back = [d for d in decisions if 5.0 <= d["t"] < 5.4]
    assert back and {d.get("reason") for d in back} == {"filling buffer (back in view)"}
    later = [d for d in decisions if d["t"] >= 6.0]
    assert sum(d["decision"] is not None for d in later) >= 0.9 * len(later)
    assert report["decision_points"]["person_in_view_undecided"] == 0
    assert report["best_at_lag_le_1s"] >= 0.6, report["per_action_at_best_lag"]


@pytest.mark.gl
def test_a_performer_cut_at_the_waist_is_not_taken_for_nobody(
    setup: Any, pose_bank: Any, mocap: Path, films: Path, tmp_path: Path
) -> None:
    # the frame's top 45% hidden: the pose model's detector looks for a face and
    # shoulders and finds nobody; the selfie model still finds the person, so the log
    # says that someone it cannot read is there (a point that counts against the run),
    # not that nobody is; their half silhouette matches nothing whole either
    video = _film(mocap, films, (0.0, 9.0), azimuth=20.0)

    def cut(img: np.ndarray) -> np.ndarray:
        img[: int(img.shape[0] * 0.45)] = (60, 60, 60)
        return img

    report, decisions = _follow(setup, pose_bank, _rewrite(video, tmp_path / "cut.mkv", cut))
    unread = [d for d in decisions if d.get("reason") == UNPOSED]
    assert len(unread) >= len(decisions) // 3, report["decision_points"]
    points = report["decision_points"]
    assert points["person_in_view_undecided"] >= len(unread)


@pytest.mark.gl
def test_of_two_people_in_view_one_is_followed(
    setup: Any, pose_bank: Any, mocap: Path, films: Path, tmp_path: Path
) -> None:
    # 13_29's jumping jacks on the left and its squats on the right, side by side: the
    # pose model follows one person, and the avatar does that person's action
    takes = [_film(mocap, films, seconds, azimuth=0.0) for seconds in ((0.0, 6.0), (32.0, 38.0))]
    left, right = (_frames(f) for f in takes)
    both = tmp_path / "both.mkv"
    writer = cv2.VideoWriter(str(both), cv2.VideoWriter.fourcc(*"FFV1"), 15.0, (480, 360))
    for a, b in zip(left, right, strict=False):
        writer.write(np.ascontiguousarray(np.concatenate([a[:, 120:360], b[:, 120:360]], 1)))
    writer.release()
    lib, layer, _ = setup
    r = perform(VideoSource(both), layer, pose_bank, lib.clips, PerformSettings(), seed=1)
    points = decision_points(r.decisions)
    assert points["decided"] >= 0.5 * points["points"], points
    agree = []
    for take in takes:
        truth = truth_for(take)
        assert truth is not None
        agree.append(evaluation(r.decisions, lib.clips, truth, r.media_seconds))
    best = max(a["best_at_lag_le_1s"] for a in agree)
    assert best >= 0.8, [a["per_action_at_best_lag"] for a in agree]


def test_decision_points_count_each_reason_once_and_blame_only_a_person_in_view() -> None:
    log = [
        {"t": 0.1, "decision": None, "reason": "filling buffer"},
        {"t": 0.2, "decision": None, "reason": "no match (cost 5.10 per frame > 4.5)"},
        {"t": 0.3, "decision": None, "reason": "no match (cost 6.00 per frame > 4.5)"},
        {"t": 0.4, "decision": None, "reason": "nobody in view"},
        {"t": 0.5, "decision": [1], "cost": 1.0, "by": "landmarks"},
        {"t": 0.6, "decision": None, "reason": "filling buffer (back in view)"},
        {"t": 0.7, "decision": [2], "cost": 1.0, "by": "silhouette"},
        {"t": 0.8, "decision": [3], "cost": 1.0, "by": "landmarks"},
    ]
    got = decision_points(log)
    assert got["points"] == 8 and got["decided"] == 3
    assert got["decided_by"] == {"landmarks": 2, "silhouette": 1}
    assert got["undecided_by_reason"] == {"no match": 2, "filling buffer": 2, "nobody in view": 1}
    assert got["person_in_view_undecided"] == 2
    assert got["person_in_view_undecided_share"] == pytest.approx(0.25)
