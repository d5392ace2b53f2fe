"""Sources (files, masks, a camera that fails), segmentation and mask cleanup."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest

from tests.conftest import REPO
from vision import (
    CameraSource,
    MaskFolderSource,
    Segmenter,
    SourceError,
    VideoSource,
    clean_mask,
    open_source,
)
from vision._record import add_mask_noise
from vision._segment import clean_mask_others

RECORDING = REPO / "recordings" / "13_29_first12s_160x120.mkv"
REAL = REPO.parent / "shared" / "video" / "pose_1.mp4"


def test_video_sources_and_autodetection() -> None:
    src = open_source(video=str(RECORDING))
    assert isinstance(src, VideoSource) and src.silhouette and src.fps == 30.0
    first = src.read()
    assert first is not None and first.mask is not None and first.t == 0.0
    second = src.read()
    assert second is not None and second.t == pytest.approx(1 / 30)
    src.close()
    colour = open_source(video=str(REAL))
    frame = colour.read()
    assert frame is not None and frame.image is not None and frame.image.ndim == 3
    colour.close()


def test_bad_sources_are_clear_errors(tmp_path: Path) -> None:
    with pytest.raises(SourceError, match="no such video file"):
        VideoSource(tmp_path / "missing.mp4")
    with pytest.raises(SourceError, match=r"a folder, not a video file .* --masks"):
        VideoSource(tmp_path)
    junk = tmp_path / "junk.mp4"
    junk.write_text("not a video")
    with pytest.raises(SourceError, match=r"junk\.mp4: cannot open"):
        VideoSource(junk)
    with pytest.raises(SourceError, match="no mask images"):
        MaskFolderSource(tmp_path)
    # one unreadable mask is skipped and said, and the rest are read
    (tmp_path / "a.png").write_bytes(b"broken")
    cv2.imwrite(str(tmp_path / "b.png"), np.full((4, 4), 255, np.uint8))
    folder = MaskFolderSource(tmp_path)
    first, second = folder.read(), folder.read()
    assert first is not None and first.mask is None and first.problem == "unreadable mask a.png"
    assert second is not None and second.mask is not None and second.mask.all()
    assert folder.read() is None and folder.skipped == ["a.png"]
    with pytest.raises(ValueError, match="exactly one"):
        open_source()


def test_mask_folder_in_name_order(tmp_path: Path) -> None:
    for i in (2, 0, 1):
        m = np.zeros((20, 20), dtype=np.uint8)
        m[i : i + 5, 5:10] = 255
        cv2.imwrite(str(tmp_path / f"m{i:03d}.png"), m)
    src = MaskFolderSource(tmp_path, fps=10)
    frames = [src.read() for _ in range(4)]
    assert frames[3] is None
    assert [f.t for f in frames[:3]] == [0.0, 0.1, 0.2]
    assert [int(np.argmax(f.mask.any(axis=1))) for f in frames[:3]] == [0, 1, 2]


class _Clock:
    """A wall clock for a paced source: ``sleep`` moves it, and so does ``work``."""

    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.now += seconds


@pytest.mark.parametrize("kind", ["video", "masks"])
def test_a_file_paced_in_real_time_drops_what_a_slow_loop_cannot_take(
    kind: str, tmp_path: Path
) -> None:
    """``realtime``: a frame comes no earlier than its time, and a loop that keeps up gets
    every frame; one slower than the frame rate gets the newest frame whose time has
    come, the rest dropped as a camera drops them, so it stays within a frame of the
    media clock instead of falling further behind at every frame."""
    if kind == "masks":
        for i in range(40):
            cv2.imwrite(str(tmp_path / f"m{i:03d}.png"), np.full((4, 4), 255, np.uint8))

    def source(realtime: bool = True) -> VideoSource | MaskFolderSource:
        if kind == "video":
            src: VideoSource | MaskFolderSource = VideoSource(
                RECORDING, silhouette=True, realtime=realtime
            )
        else:
            src = MaskFolderSource(tmp_path, fps=30.0, realtime=realtime)
        clock = _Clock()
        src._pacer.clock, src._pacer.sleep = clock, clock.sleep
        return src

    keeping_up = source()
    got = [keeping_up.read() for _ in range(10)]
    assert [f.index for f in got if f is not None] == list(range(10))
    assert keeping_up.dropped == 0
    assert keeping_up._pacer.clock() == pytest.approx(100.0 + 9 / 30)  # waited for each
    slow = source()  # a loop that takes 0.105 s a frame: over three frames' time
    clock = slow._pacer.clock
    assert isinstance(clock, _Clock)
    frames = []
    for _ in range(10):
        f = slow.read()
        assert f is not None
        frames.append(f)
        assert 0.0 <= clock() - 100.0 - f.t < 1 / 30  # the newest frame whose time came
        clock.now += 0.105
    assert [f.index for f in frames] == [0, 3, 6, 9, 12, 15, 18, 22, 25, 28]
    assert slow.dropped == 19
    unpaced = source(realtime=False)  # not paced: every frame, at once
    assert [f.index for f in (unpaced.read() for _ in range(5)) if f] == list(range(5))
    assert unpaced.dropped == 0 and unpaced._pacer.clock() == 100.0


class _FlakyCapture:
    def __init__(self, frames: int) -> None:
        self.left = frames

    def isOpened(self) -> bool:
        return True

    def read(self) -> tuple[bool, np.ndarray | None]:
        if self.left <= 0:
            return False, None
        self.left -= 1
        return True, np.zeros((4, 4, 3), dtype=np.uint8)

    def release(self) -> None:
        pass


def test_camera_reconnects_with_backoff_and_never_ends() -> None:
    opened = {"n": 0}

    def opener() -> object:
        opened["n"] += 1
        return None if opened["n"] in (1, 3) else _FlakyCapture(3)

    cam = CameraSource(0, fps=1000.0, max_backoff=0.004, opener=opener, min_backoff=0.001)
    got = [cam.read() for _ in range(200)]
    assert all(f is not None for f in got)
    with_images = sum(f.image is not None for f in got if f is not None)
    assert with_images >= 6 and cam.reconnects >= 2 and opened["n"] >= 4


class _Ticking:
    """A camera that gives a frame every ``period`` seconds, its number in its pixels."""

    def __init__(self, period: float) -> None:
        self.period = period
        self.k = 0
        self.released = False

    def isOpened(self) -> bool:
        return True

    def read(self) -> tuple[bool, np.ndarray]:
        time.sleep(self.period)
        self.k += 1
        return True, np.full((2, 2, 3), self.k % 256, np.uint8)

    def release(self) -> None:
        self.released = True


def test_a_camera_gives_a_slow_loop_its_newest_frame() -> None:
    """OpenCV queues a camera's frames, so a loop slower than the camera read them in
    turn, later and later; it is now given the newest, those it had no time for
    dropped and counted, and a loop that keeps up is given every frame."""
    made: list[_Ticking] = []

    def ticking(period: float) -> Callable[[], _Ticking]:
        return lambda: made.append(_Ticking(period)) or made[-1]

    cam = CameraSource(0, fps=100.0, opener=ticking(0.01))
    numbers, times = [], []
    for _ in range(6):
        f = cam.read()
        assert f is not None and f.image is not None
        numbers.append(int(f.image[0, 0, 0]))
        times.append(f.t)
        time.sleep(0.1)  # a loop ten frames slower than the camera
    cam.close()
    assert (np.diff(numbers) >= 5).all(), numbers  # about 10 on each time, not 1
    assert np.all(np.diff(times) > 0.05) and cam.dropped >= 5 * 5
    assert made[-1].released
    cam = CameraSource(0, fps=33.0, opener=ticking(0.03))
    got = [cam.read() for _ in range(8)]
    cam.close()
    numbers = [int(f.image[0, 0, 0]) for f in got if f is not None and f.image is not None]
    assert numbers == list(range(1, 9)) and cam.dropped == 0


def test_a_camera_that_never_gives_a_frame_is_given_up_saying_so() -> None:
    cam = CameraSource(7, fps=1000.0, opener=lambda: None, min_backoff=0.001, first_wait=0.05)
    with pytest.raises(SourceError, match=r"camera 7: no frame in 0.05 s \(no such camera"):
        for _ in range(10_000):
            cam.read()
    # one that has given a frame is waited for however long it is gone
    opened = {"n": 0}

    def opener() -> object:
        opened["n"] += 1
        return _FlakyCapture(1) if opened["n"] == 1 else None

    cam = CameraSource(0, fps=1000.0, opener=opener, min_backoff=0.001, first_wait=0.01)
    got = [cam.read() for _ in range(100)]
    assert sum(f is not None and f.image is not None for f in got) == 1


def _scene(t: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(1)
    bg = (rng.random((120, 160, 3)) * 120 + 60).astype(np.uint8)
    img = bg.copy()
    truth = np.zeros((120, 160), dtype=bool)
    if t >= 30:
        x = 20 + (t - 30) * 2
        truth[30:100, x : x + 25] = True
        img[truth] = (30, 200, 60)
    noise = np.random.default_rng(t).normal(0, 3, img.shape)
    return np.clip(img + noise, 0, 255).astype(np.uint8), truth


@pytest.mark.parametrize(("method", "adapt"), [("mog2", 0.0), ("mog", 0.0), ("knn", 0.001)])
def test_segmenter_finds_the_performer(method: str, adapt: float) -> None:
    seg = Segmenter(method, learn_frames=30, adapt=adapt)
    ious = []
    for t in range(70):
        img, truth = _scene(t)
        mask = seg.apply(img)
        if t < 30:
            assert mask is None  # learning, nobody in view
        else:
            assert mask is not None
            ious.append((mask & truth).sum() / (mask | truth).sum())
    assert min(ious) > 0.8


def test_clean_mask_keeps_the_largest_blob_and_fills_holes() -> None:
    m = np.zeros((60, 60), dtype=np.uint8)
    m[10:50, 20:40] = 1
    m[25:28, 28:31] = 0  # a hole
    m[5, 5] = 1  # speckle
    m[52:56, 50:54] = 1  # a smaller blob
    out = clean_mask(m)
    assert out is not None and out[26, 29] and not out[5, 5] and not out[53, 52]
    assert clean_mask(np.zeros((60, 60))) is None
    assert clean_mask(np.pad(np.ones((2, 2)), 29)) is None  # too small


def test_clean_mask_counts_other_people_in_view() -> None:
    """A second blob at least ``RIVAL`` times the kept one's area is another person in
    view; a smaller one (a hand, a chair) is not; the largest is the one kept."""
    m = np.zeros((100, 200), dtype=bool)
    m[20:90, 20:50] = True  # 2100 pixels: the performer
    m[30:90, 120:150] = True  # 1800: someone beside them
    m[5:10, 180:190] = True  # 50: a speck
    out, others = clean_mask_others(m)
    assert others == 1 and out is not None and out[50, 35] and not out[50, 135]
    assert np.array_equal(out, clean_mask(m))
    m[30:90, 120:150] = False
    m[60:90, 120:140] = True  # 600 pixels: less than half the performer's
    assert clean_mask_others(m)[1] == 0
    assert clean_mask_others(np.zeros((60, 60))) == (None, 0)


def test_clean_mask_on_its_box_is_clean_mask_on_the_whole_image() -> None:
    """clean_mask works on the box around the mask with a margin: the same pixels as the
    smoothing, largest blob and hole filling on the whole image, with blobs inside,
    touching an edge and a corner, holes open to the box's edge, and speckle."""
    from vision._segment import _largest_blob

    rng = np.random.default_rng(3)
    for trial in range(40):
        m = np.zeros((48, 64), dtype=np.uint8)
        for _ in range(rng.integers(1, 4)):
            y, x = rng.integers(-4, 44), rng.integers(-4, 60)
            m[max(y, 0) : y + rng.integers(3, 30), max(x, 0) : x + rng.integers(3, 30)] = 1
        m = add_mask_noise(m, rng, edge=1.0, holes=3)
        m[rng.random(m.shape) < 0.01] = 1  # speckle
        whole, others_whole = _largest_blob(m, 0.003 * m.size)
        got, others = clean_mask_others(m)
        assert (got is None) == (whole is None), trial
        assert others == others_whole, trial
        if got is not None and whole is not None:
            assert np.array_equal(got, whole), trial


def test_clean_mask_keeps_a_thin_arm_with_ragged_edges() -> None:
    """A performer far from the camera: a body and an arm 3 pixels wide held out, the
    mask's edges ragged (a pixel either side flipped at random, as ``mimic record``
    makes them). The arm must stay whole: the outline descriptor reads how far it
    reaches (a 3x3 opening cuts it short on most such masks)."""
    rng = np.random.default_rng(0)
    short = 0
    for _ in range(20):
        m = np.zeros((90, 120), dtype=np.uint8)
        m[10:80, 20:40] = 1  # the body
        m[25:28, 40:100] = 1  # the arm, to column 99
        m = add_mask_noise(m, rng, edge=1.0, holes=0)
        out = clean_mask(m)
        assert out is not None
        short += int(np.flatnonzero(out[20:34].any(axis=0)).max() < 96)
    assert short <= 4
