"""Where frames come from: a webcam, a video file, a folder of masks, a silhouette video.

Every source yields ``Frame`` objects with a media time in seconds. A file source ends
(``read()`` returns ``None``); a camera never ends: when it fails it yields frames
without an image while it reconnects with back-off, so the performance loop keeps going.
``realtime=True`` paces a file as if it were a camera: a frame is given no earlier than
its media time, and, as a camera's frames are, the frames whose time passed while the
loop was busy with an earlier one are dropped (``dropped``), so a loop slower than the
file's frame rate follows it late by a frame, not by more and more.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "CameraSource",
    "Frame",
    "MaskFolderSource",
    "Source",
    "SourceError",
    "VideoSource",
    "looks_like_silhouettes",
    "open_source",
]

log = logging.getLogger(__name__)

IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm"}


class SourceError(OSError):
    """A source that cannot be opened or read; the message names it."""


@dataclass(frozen=True)
class Frame:
    """One frame: ``t`` seconds of media time; ``image`` (H, W, 3) BGR, or ``mask``
    (H, W) bool for sources that are already silhouettes, or ``landmarks`` (33, 3) for
    sources that already give body landmarks (MediaPipe Pose's 33 points: x, y in
    pixels, visibility in [0, 1]), with the person's ``mask`` beside them where the
    source has it (the silhouette matched beside the landmarks: ``vision._fallback``);
    none when the source has nothing right now (a camera reconnecting), and then
    ``problem`` may say why (an unreadable mask file)."""

    t: float
    index: int
    image: NDArray[np.uint8] | None = None
    mask: NDArray[np.bool_] | None = None
    problem: str = ""
    landmarks: NDArray[np.float64] | None = None


class Source(Protocol):
    fps: float
    name: str

    def read(self) -> Frame | None: ...

    def close(self) -> None: ...


class _Pacer:
    """A file's media clock against the wall clock (``realtime``), from the first frame."""

    def __init__(self, realtime: bool) -> None:
        self.realtime = realtime
        self.start: float | None = None
        self.clock: Callable[[], float] = time.monotonic
        self.sleep: Callable[[float], None] = time.sleep

    def wait(self, t: float) -> None:
        """Until media time ``t`` (at once when not ``realtime``)."""
        if not self.realtime:
            return
        now = self.clock()
        if self.start is None:
            self.start = now - t
        delay = self.start + t - now
        if delay > 0:
            self.sleep(delay)

    def passed(self, t: float) -> bool:
        """Whether media time ``t`` has already passed (``realtime``, once started)."""
        return self.realtime and self.start is not None and self.clock() >= self.start + t


class VideoSource:
    """A video file. ``silhouette=True``: the video already holds binary silhouettes
    (white on black), so frames come as masks (no segmentation)."""

    def __init__(self, path: str | Path, silhouette: bool = False, realtime: bool = False) -> None:
        self.path = Path(path)
        self.name = str(self.path)
        if self.path.is_dir():
            raise SourceError(
                f"{self.path}: a folder, not a video file (a folder of mask images is read "
                "with --masks)"
            )
        if not self.path.is_file():
            raise SourceError(f"{self.path}: no such video file")
        self._cap = cv2.VideoCapture(str(self.path))
        if not self._cap.isOpened():
            raise SourceError(f"{self.path}: cannot open this video (unknown format or codec)")
        fps = float(self._cap.get(cv2.CAP_PROP_FPS) or 0.0)
        self.fps = fps if 1.0 <= fps <= 1000.0 else 30.0
        self.silhouette = silhouette
        #: the frame count the container declares (0: unknown): fewer frames read means
        #: a truncated file
        n = self._cap.get(cv2.CAP_PROP_FRAME_COUNT)
        self.expected_frames = int(n) if np.isfinite(n) and 0 < n < 1e9 else 0
        self._i = 0
        self._ended = False  # read to its end (not stopped early by --seconds or a stop)
        self._pacer = _Pacer(realtime)
        self.realtime = realtime  # paced like a camera
        #: frames dropped to keep up (``realtime``): the next frame's time had come
        self.dropped = 0

    @property
    def frames_read(self) -> int:
        return self._i

    def truncated(self) -> str:
        """After the last frame: why the video seems cut short ("" when it does not, or
        when reading stopped before the video's end)."""
        if self._ended and self.expected_frames and self._i < self.expected_frames - 1:
            return (
                f"{self.path}: the video ended after {self._i} of the {self.expected_frames} "
                "frames its header declares (a truncated or damaged file?)"
            )
        return ""

    def read(self) -> Frame | None:
        while self._pacer.passed((self._i + 1) / self.fps):  # late: the next is due too
            if not self._cap.grab():
                self._ended = True
                return None
            self._i += 1
            self.dropped += 1
        ok, img = self._cap.read()
        if not ok or img is None:
            self._ended = True
            return None
        t = self._i / self.fps
        self._pacer.wait(t)
        i = self._i
        self._i += 1
        if self.silhouette:
            gray = img if img.ndim == 2 else img[..., 1]
            return Frame(t, i, mask=gray > 127)
        return Frame(t, i, image=np.asarray(img, dtype=np.uint8))

    def close(self) -> None:
        self._cap.release()


class MaskFolderSource:
    """A folder of mask images (any of PNG, JPEG, BMP, TIFF, PGM), in name order, at ``fps``."""

    def __init__(self, folder: str | Path, fps: float = 30.0, realtime: bool = False) -> None:
        self.folder = Path(folder)
        self.name = str(self.folder)
        if not self.folder.is_dir():
            raise SourceError(f"{self.folder}: not a folder of mask images")
        self.files = sorted(p for p in self.folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
        if not self.files:
            raise SourceError(
                f"{self.folder}: no mask images ({', '.join(sorted(IMAGE_SUFFIXES))})"
            )
        if not fps > 0:
            raise ValueError("fps must be positive")
        self.fps = float(fps)
        self._i = 0
        self._pacer = _Pacer(realtime)
        self.realtime = realtime  # paced like a camera
        #: the files that could not be read (each one a frame without a silhouette)
        self.skipped: list[str] = []
        #: files passed over to keep up (``realtime``): the next one's time had come
        self.dropped = 0

    def read(self) -> Frame | None:
        while self._i + 1 < len(self.files) and self._pacer.passed((self._i + 1) / self.fps):
            self._i += 1
            self.dropped += 1
        if self._i >= len(self.files):
            return None
        path = self.files[self._i]
        try:
            img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        except cv2.error:
            img = None
        t = self._i / self.fps
        self._pacer.wait(t)
        i = self._i
        self._i += 1
        if img is None or img.size == 0:  # skipped, said, and the run goes on
            self.skipped.append(path.name)
            return Frame(t, i, problem=f"unreadable mask {path.name}")
        return Frame(t, i, mask=img > 127)

    def close(self) -> None:
        pass


#: seconds a camera may take to give its first frame (some take a few to start)
FIRST_WAIT = 20.0


class _Newest:
    """An opened camera read in a thread of its own, its newest frame kept.

    OpenCV hands a camera's frames over in the order they came, from a queue of a few
    buffers (V4L2's: four), so a loop slower than the camera is given frames up to that
    many frames old. Read as fast as the camera gives them, with only the newest kept, a
    loop is given the frame of now, and those it had no time for are dropped, counted
    (opencv/opencv#13145). ``read`` waits for a frame not given before, and once the
    camera fails gives the failure (the thread has ended)."""

    def __init__(self, cap: Any, clock: Callable[[], float]) -> None:
        self.cap = cap
        self._clock = clock
        self._ready = threading.Condition()
        #: the newest frame (ok, image, when); whether it is not given yet (``_fresh``),
        #: the frames dropped since the last given, and whether the camera has failed
        self._newest: tuple[bool, Any, float] = (False, None, 0.0)
        self._dropped = 0
        self._fresh = self._failed = self._stop = False
        self._thread = threading.Thread(target=self._run, name="mimic-camera", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        ok = True
        while ok:
            try:
                got, img = self.cap.read()
            except Exception as exc:  # (a reader that raised is a camera lost: reopened)
                log.warning("reading the camera failed: %s", exc)
                got, img = False, None
            ok = bool(got) and img is not None
            with self._ready:
                if self._stop:
                    return
                if not ok:  # (after the last frame, if that was not given yet)
                    self._failed = True
                else:
                    self._dropped += self._fresh  # the one before was never given
                    self._newest, self._fresh = (True, img, self._clock()), True
                self._ready.notify_all()

    def read(self) -> tuple[bool, Any, float, int]:
        """The newest frame not given before ``(ok, image, when, dropped)``, waited for;
        ``dropped``: the frames read since the last one given and never given. Once the
        camera has failed and its last frame was given: ``ok`` False."""
        with self._ready:
            self._ready.wait_for(lambda: self._fresh or self._failed)
            dropped, self._dropped = self._dropped, 0
            if not self._fresh:
                return False, None, self._clock(), dropped
            self._fresh = False
            return (*self._newest, dropped)

    def close(self) -> None:
        """Stop reading and release the camera (once the thread is out of its read)."""
        with self._ready:
            self._stop = True
        self._thread.join(timeout=2.0)
        if not self._thread.is_alive():
            self.cap.release()


class CameraSource:
    """A webcam. Once it has given a frame, failures never end the stream: it yields
    empty frames and reopens the device with back-off (``min_backoff`` seconds, doubling
    up to ``max_backoff``): a camera unplugged for a moment is waited for. One that has
    given no frame ``first_wait`` seconds after the start raises ``SourceError`` (no such
    camera, or one in use: retrying that forever helped nobody). Each frame is the newest
    the camera has given (``_Newest``), its time when it came; ``dropped`` counts those
    the loop had no time for. ``opener`` replaces ``cv2.VideoCapture(index)`` (tests)."""

    live = True  # frames come as they happen (segmentation and search choose by it)

    def __init__(
        self,
        index: int,
        fps: float = 30.0,
        max_backoff: float = 8.0,
        opener: Callable[[], Any] | None = None,
        min_backoff: float = 0.5,
        first_wait: float = FIRST_WAIT,
    ) -> None:
        self.index = index
        self.name = f"camera {index}"
        self.fps = fps
        self.max_backoff = max_backoff
        self._open = opener or (lambda: cv2.VideoCapture(index))
        self._cap: _Newest | None = None
        self._t0 = time.monotonic()
        self._i = 0
        self.min_backoff = min_backoff
        self._backoff = min_backoff
        self._retry_at = 0.0
        self.reconnects = 0
        self.first_wait = first_wait
        self._seen = False  # a frame came: from then on, waited for whatever happens
        self.dropped = 0

    def _connect(self) -> bool:
        now = time.monotonic()
        if now < self._retry_at:
            return False
        cap = self._open()
        if cap is not None and cap.isOpened():
            self._cap = _Newest(cap, time.monotonic)
            self._backoff = self.min_backoff
            return True
        log.warning("%s not available; retrying in %.1f s", self.name, self._backoff)
        self._retry_at = now + self._backoff
        self._backoff = min(self._backoff * 2.0, self.max_backoff)
        return False

    def read(self) -> Frame | None:
        t = time.monotonic() - self._t0
        i = self._i
        self._i += 1
        if not self._seen and t > self.first_wait:
            raise SourceError(
                f"{self.name}: no frame in {self.first_wait:g} s (no such camera, or one "
                "in use by another program? try another --camera index)"
            )
        if self._cap is None and not self._connect():
            time.sleep(1.0 / self.fps)
            return Frame(t, i)
        assert self._cap is not None
        ok, img, when, dropped = self._cap.read()
        self.dropped += dropped
        if not ok:
            log.warning("%s lost; reconnecting", self.name)
            self._cap.close()
            self._cap = None
            self.reconnects += 1
            return Frame(t, i)
        self._seen = True
        return Frame(when - self._t0, i, image=img)

    def close(self) -> None:
        if self._cap is not None:
            self._cap.close()
            self._cap = None


def open_source(
    camera: int | None = None,
    video: str | None = None,
    masks: str | None = None,
    silhouette: bool | None = None,
    realtime: bool = False,
    fps: float = 30.0,
) -> Source:
    """The one source named. A video is read as silhouettes when ``silhouette`` is True,
    or when it is None and it looks like one (``looks_like_silhouettes``)."""
    if sum(x is not None for x in (camera, video, masks)) != 1:
        raise ValueError("give exactly one of a camera, a video or a folder of masks")
    if camera is not None:
        return CameraSource(camera, fps=fps)
    if masks is not None:
        return MaskFolderSource(masks, fps=fps, realtime=realtime)
    assert video is not None
    if silhouette is None:
        silhouette = looks_like_silhouettes(video)
    return VideoSource(video, silhouette=silhouette, realtime=realtime)


def looks_like_silhouettes(video: str | Path, frames: int = 30, limit: int = 900) -> bool:
    """Whether a video holds binary silhouettes: each of its first ``frames`` frames that
    show anything (not all black; looked for among the first ``limit``) is grey and
    black-and-white only (under 1% of pixels in between). A video that is all black that
    far is taken as colour (a dark start says nothing about what follows).

    Raises ``SourceError`` for a video without frames."""
    probe = VideoSource(video)
    seen = informative = binary = 0
    try:
        while informative < frames and seen < limit and (frame := probe.read()) is not None:
            seen += 1
            img = frame.image
            assert img is not None
            if np.mean(img > 32) < 0.001:  # black: no evidence either way
                continue
            informative += 1
            grey = img.ndim == 2 or int(np.abs(np.diff(img.astype(np.int16), axis=2)).max()) <= 24
            if grey and np.mean((img > 32) & (img < 223)) < 0.01:
                binary += 1
    finally:
        probe.close()
    if seen == 0:
        raise SourceError(f"{video}: the video has no frames")
    return informative > 0 and binary == informative
