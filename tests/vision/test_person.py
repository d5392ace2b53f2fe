"""Person segmentation (MediaPipe) for footage without a background plate."""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from silhouette_bank import POSE_JOINTS
from vision import (
    MEDIAPIPE_INDEX,
    PersonSegmenter,
    PoseReader,
    Segmenter,
    person_segmentation_available,
)
from vision._person import make_segmenter, resolve_segmentation


def _frames(path: Path, every: int = 10) -> list[np.ndarray]:
    cap = cv2.VideoCapture(str(path))
    out = []
    i = 0
    while True:
        ok, img = cap.read()
        if not ok:
            break
        if i % every == 0:
            out.append(img)
        i += 1
    cap.release()
    assert out, f"cannot read {path}"
    return out


@pytest.fixture(scope="module")
def squats(mocap: Path) -> list[np.ndarray]:
    return _frames(mocap.parent / "video" / "pose_squats.mp4", every=10)


@pytest.fixture(autouse=True)
def _needs_mediapipe() -> None:
    """MediaPipe is optional: without it these tests skip, except in CI (``CI`` set, as
    ``.ci/run`` does after installing it), where a skip would hide a broken install."""
    if not person_segmentation_available():
        if os.environ.get("CI"):
            pytest.fail("MediaPipe is not installed in CI (see .ci/run)")
        pytest.skip("MediaPipe (optional) is not installed")


def test_selfie_and_pose_find_one_whole_person(squats: list[np.ndarray]) -> None:
    selfie, pose = PersonSegmenter("selfie"), PersonSegmenter("pose")
    ious = []
    for img in squats:
        a, b = selfie.apply(img), pose.apply(img)
        assert a is not None and b is not None and a.shape == img.shape[:2]
        # a standing or squatting woman in a portrait frame: a tenth to a third of it
        assert 0.05 < a.mean() < 0.35
        n, _ = cv2.connectedComponents(a.astype(np.uint8))
        assert n == 2  # one blob (and the background)
        ious.append((a & b).sum() / (a | b).sum())
    assert np.median(ious) > 0.7  # the two models agree on the silhouette
    # nobody in view: no silhouette
    assert selfie.apply(np.full((480, 640, 3), 128, dtype=np.uint8)) is None
    selfie.close()
    pose.close()


def test_a_large_frame_is_scaled_down_for_the_model_and_its_mask_back_up(
    squats: list[np.ndarray],
) -> None:
    """The squats are 720x1280: the model sees them at 360x640 (``MAX_SIDE``), yet the
    mask has the frame's size and covers what the model finds at full size, and the
    landmarks (image fractions) are where they were."""
    assert max(squats[0].shape[:2]) > 640
    scaled, full = PersonSegmenter("pose"), PersonSegmenter("pose", max_side=None)
    ious, moved = [], []
    for img in squats:
        a, b = scaled.apply(img), full.apply(img)
        assert a is not None and b is not None and a.shape == b.shape == img.shape[:2]
        ious.append((a & b).sum() / (a | b).sum())
        assert scaled.landmarks is not None and full.landmarks is not None
        body = list(MEDIAPIPE_INDEX)  # the 12 the pose descriptor reads
        moved.append(np.abs(scaled.landmarks[body, :2] - full.landmarks[body, :2]).max())
        prob = scaled.probability(img)
        assert prob is not None and prob.shape == img.shape[:2] and prob.dtype == np.float32
    # (the masks' IoU is about 0.9, and the landmarks move by a percent or two of the
    # frame: MediaPipe tracks its crop from frame to frame)
    assert np.median(ious) > 0.9 and min(ious) > 0.85, ious
    assert np.median(moved) < 0.02, moved  # of the image's width or height
    small = squats[0][::4, ::4].copy()  # 180x320: given to the model as it is
    fresh = PersonSegmenter("pose")
    got = fresh.apply(small)
    assert got is not None and got.shape == small.shape[:2]
    fresh.close()
    with pytest.raises(ValueError, match="max_side must be at least 64"):
        PersonSegmenter("selfie", max_side=32)
    scaled.close()
    full.close()


def test_frames_that_change_size_start_the_pose_model_again(
    squats: list[np.ndarray], caplog: pytest.LogCaptureFixture
) -> None:
    """MediaPipe's pose model smooths its mask from frame to frame and fails for good
    (RuntimeError on every later frame) when a stream's frame size changes (a camera
    reconfigured, videos played one after another). The segmenter starts it again, with
    a warning naming the sizes, and the masks and landmarks carry on."""
    seg = PersonSegmenter("pose")
    small = [cv2.resize(img, (270, 480), interpolation=cv2.INTER_AREA) for img in squats[:3]]
    with caplog.at_level("WARNING", logger="vision._person"):
        for img in [*squats[:3], *small, squats[3]]:  # 360x640 (scaled), 270x480, back
            mask = seg.apply(img)
            assert mask is not None and mask.shape == img.shape[:2]
            assert seg.landmarks is not None
    assert seg.restarts == 2
    said = [r.getMessage() for r in caplog.records if "changed size" in r.getMessage()]
    assert said == [
        "the frames changed size (360x640 to 270x480): the pose model starts again",
        "the frames changed size (270x480 to 360x640): the pose model starts again",
    ]
    seg.close()
    selfie = PersonSegmenter("selfie")  # no smoothing across frames: nothing to restart
    for img in (squats[0], small[0]):
        assert selfie.apply(img) is not None
    assert selfie.restarts == 0
    selfie.close()


def test_a_pose_model_without_masks_reads_the_same_landmarks(squats: list[np.ndarray]) -> None:
    """The landmarks' voice (``vision._voice``) has its silhouette already: its pose model
    makes no masks, and reads the very landmarks one that makes them does."""
    with_masks, without = PersonSegmenter("pose"), PersonSegmenter("pose", masks=False)
    for img in squats[:4]:
        seen = with_masks.landmarks_of(img)
        assert seen is not None
        assert np.array_equal(without.landmarks_of(img), seen)
    for makes_a_mask in (without.apply, without.probability):
        with pytest.raises(ValueError, match="without masks"):
            makes_a_mask(squats[0])
    with pytest.raises(ValueError, match="only the pose model"):
        PersonSegmenter("selfie", masks=False)
    with_masks.close()
    without.close()


@pytest.mark.slow
def test_a_plate_subtractor_loses_a_person_who_is_there_from_the_start(mocap: Path) -> None:
    """The measured fact behind the person segmenter: with no empty frames to learn from,
    MOG2 (learning over the first 30 frames, as by default) learns the person into the
    background; its masks hardly overlap the person segmenter's."""
    frames = _frames(mocap.parent / "video" / "pose_1.mp4", every=1)
    mog = Segmenter("mog2", learn_frames=30)
    person = PersonSegmenter("selfie")
    ious = []
    for img in frames:
        m, p = mog.apply(img), person.apply(img)
        if mog.learning or p is None:
            continue
        m = np.zeros_like(p) if m is None else m
        ious.append((m & p).sum() / (m | p).sum())
    assert len(ious) > 60 and np.median(ious) < 0.4


def test_choosing_a_segmenter() -> None:
    assert resolve_segmentation("auto", live=True) == "mog2"  # a camera learns its plate
    assert resolve_segmentation("auto", live=False) == "pose"  # footage has none
    # the pose descriptor needs the pose model's landmarks, camera or file
    assert resolve_segmentation("auto", live=True, landmarks=True) == "pose"
    with pytest.raises(ValueError, match="needs the pose model's landmarks"):
        resolve_segmentation("mog2", live=True, landmarks=True)
    assert resolve_segmentation("knn", live=False) == "knn"
    assert isinstance(make_segmenter("pose"), PersonSegmenter)
    assert isinstance(make_segmenter("mog2", 5), Segmenter)
    with pytest.raises(ValueError, match="method must be one of selfie, pose"):
        PersonSegmenter("body")
    with pytest.raises(ValueError, match=r"expected a BGR image \(H, W, 3\)"):
        PersonSegmenter().apply(np.zeros((10, 10), dtype=np.uint8))


def test_pose_landmarks_become_pose_vectors(squats: list[np.ndarray]) -> None:
    model = PersonSegmenter("pose")
    reader = PoseReader()
    vecs = []
    for img in squats:
        model.apply(img)
        assert model.landmarks is not None and model.landmarks.shape == (33, 3)
        v = reader.read(model.landmarks, (img.shape[1], img.shape[0]))
        assert reader.why == "" and np.isfinite(v).all()
        vecs.append(v)
    x = np.array(vecs)
    # the hips are 0 and the torso at most 1 long (1 unless the legs say the torso is
    # foreshortened); the shoulders above the hips, the ankles below
    mid_shoulder = 0.5 * (x[:, 0:2] + x[:, 2:4])
    torso = np.linalg.norm(mid_shoulder, axis=1)
    assert (torso <= 1 + 1e-9).all() and np.median(torso) > 0.8
    assert (mid_shoulder[:, 1] > 0.8).all() and (x[:, 21] < -0.5).all()
    # squats: the knees rise towards the hips and fall back
    assert np.ptp(x[:, 17]) > 0.3
    # nobody in view, and a person upside down (the detector finds no torso it trusts,
    # or a pose of low confidence): no vector, and why
    assert np.isnan(reader.read(None, (640, 480))).all() and reader.why == "nobody in view"
    model.apply(np.full((480, 640, 3), 128, dtype=np.uint8))
    blank = reader.read(model.landmarks, (640, 480))
    assert np.isnan(blank).all() and reader.why
    # a limb of low confidence is matched all the same, at the place the model gives it,
    # for as long as it stays hidden (a side view hides the far limbs for a whole take);
    # ``hidden`` names it for the log and ``visibility`` keeps each landmark's
    model.apply(squats[0])
    assert model.landmarks is not None
    lm, good_lm = model.landmarks.copy(), model.landmarks.copy()
    good = reader.read(lm, (720, 1280))
    assert reader.hidden == () and reader.upright
    flipped = lm.copy()  # the same landmarks upside down: read, and not upright
    flipped[:, 1] = 1.0 - flipped[:, 1]
    assert np.isfinite(reader.read(flipped, (720, 1280))).all() and not reader.upright
    lm[27, 2] = 0.0  # the left ankle unseen
    for _ in range(100):
        held = reader.read(lm, (720, 1280))
        assert reader.why == "" and reader.hidden == ("left_ankle",)
    np.testing.assert_allclose(held, good)
    assert reader.visibility[POSE_JOINTS.index("left_ankle")] == 0.0
    # the share of the 8 limb landmarks of low confidence, which weighs the silhouette
    # beside the landmarks (``SilhouetteFallback.evidence``): one here, none before
    assert reader.limbs_hidden == 1 / 8
    lm[[13, 15], 2] = 0.2  # the left elbow and wrist too: the far arm and leg of a side view
    reader.read(lm, (720, 1280))
    assert reader.limbs_hidden == 3 / 8
    # without the torso there is no pose: a frame of legs alone
    lm[[11, 12], 2] = 0.1
    assert np.isnan(reader.read(lm, (720, 1280))).all() and "torso" in reader.why
    assert reader.hidden[:2] == ("left_shoulder", "right_shoulder") and not reader.upright
    assert reader.limbs_hidden == 1.0  # (no pose: the silhouette alone can speak)
    reader.read(good_lm, (720, 1280))
    assert reader.limbs_hidden == 0.0
    model.close()


def test_native_log_lines_are_silenced_and_python_errors_are_not(capfd) -> None:
    import os

    from vision._person import quiet_native_stderr

    # (a line of its own, looked for anywhere: a pose model of an earlier test may still
    # log the real one from its native thread, outside this block, into this test's
    # capture, even between its "INFO: " and the rest)
    with quiet_native_stderr():
        os.write(2, b"native line written while quiet\n")
    os.write(2, b"after\n")
    err = capfd.readouterr().err
    assert "while quiet" not in err and "after\n" in err
    with pytest.raises(ZeroDivisionError), quiet_native_stderr():
        1 / 0  # noqa: B018
    os.write(2, b"restored\n")
    assert "restored\n" in capfd.readouterr().err
