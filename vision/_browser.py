"""The live page's webcam as a source: frames a browser sends over the stage's socket.

The page (``vision/static/stage.js``) grabs each new camera frame, scales it down, and
sends it as one binary message: the frame's time on the page's clock (float64 little
endian, milliseconds) and a JPEG. ``BrowserCamera`` keeps only the newest frame, as a
camera does: a loop slower than the page drops frames rather than falling behind. Media
time is the page's own frame times, so the performer's tempo is the camera's, not the
network's; a page that reconnects continues where the last one stopped.

Until a page sends a frame, ``read`` gives empty frames at media time 0 (the loop keeps
its clock and its stop checks going). A camera page that closes gives empty frames for
``grace`` seconds, in case it comes back (a reload); then the source ends and the run
writes what it did, as after Ctrl-C.
"""

from __future__ import annotations

import struct
import threading
import time
from typing import Any

import cv2
import numpy as np

from ._sources import Frame

__all__ = ["BrowserCamera"]

#: seconds between reminders that the run waits for the page
REMIND = 30.0


def jpeg_size(data: bytes) -> tuple[int, int] | None:
    """A JPEG's (width, height) from its frame header, without decoding it (a small file
    may declare a huge picture); ``None`` for what is not a JPEG."""
    if data[:2] != b"\xff\xd8":
        return None
    i = 2
    while i + 9 <= len(data):
        if data[i] != 0xFF:
            return None
        marker = data[i + 1]
        if marker == 0xFF:  # fill byte
            i += 1
            continue
        length = int.from_bytes(data[i + 2 : i + 4], "big")
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):  # a frame header
            height = int.from_bytes(data[i + 5 : i + 7], "big")
            width = int.from_bytes(data[i + 7 : i + 9], "big")
            return width, height
        i += 2 + length
    return None


#: seconds the run waits for a closed camera page to come back (a reload) before the
#: source ends
GRACE_S = 5.0


class BrowserCamera:
    """Frames from the stage's camera page (module docstring)."""

    fps = 30.0  # nominal: the loop paces nothing by it
    live = True  # frames come as they happen (segmentation and search choose by it)

    def __init__(
        self,
        stage: Any,
        grace: float | None = None,
        max_bytes: int = 4 << 20,
        max_side: int = 4096,
        wait: float = 0.25,
    ) -> None:
        self.name = "the page's camera"
        self.stage = stage
        self.grace = GRACE_S if grace is None else grace
        self.max_bytes, self.max_side, self.wait = max_bytes, max_side, wait
        self._cond = threading.Condition()
        self._owner: int | None = None  # the page that is the camera
        self._offset: float | None = None  # media t = page ms / 1000 - offset
        self._image: Any = None
        self._stamp = 0.0  # the newest frame's page time (ms)
        self._t = 0.0  # media time of the newest frame, or of the last empty one
        self._mono = time.monotonic()  # when _t was last set
        self._fresh = False
        self._gone_at: float | None = None
        self._i = 0
        self._closed = False
        self._reading = False  # frames before the loop's first read are dropped
        #: frames received, and refused (not a JPEG, too big)
        self.received = self.refused = 0
        #: why the source ended ("" while it has not)
        self.ended = ""
        #: the page time (ms) of the frame ``read`` gave last (the pose sent after it
        #: carries it back, so the page measures camera-to-avatar time on its own clock)
        self.last_stamp: float | None = None

    # --- the stage's side ---------------------------------------------------------------

    def attach(self, page: int) -> bool:
        """A page connected: it becomes the camera when there is none."""
        with self._cond:
            if self._owner is not None:
                return False
            self._owner, self._offset, self._gone_at = page, None, None
            return True

    def detach(self, page: int, why: str = "") -> None:
        with self._cond:
            if self._owner != page:
                return
            self._owner = None
            self._gone_at = time.monotonic()
            t = self._t
        if not self._closed:
            self.stage.say(
                f"the camera page closed at {t:.1f} s of media"
                + (f" ({why})" if why else "")
                + f": the run ends in {self.grace:g} s unless it comes back"
            )

    def put(self, page: int, message: bytes) -> str:
        """Take a frame from the camera page; what is wrong with it ("" when nothing)."""
        n = len(message)
        problem = ""
        if n > self.max_bytes:
            problem = f"a frame of {n} bytes: over the {self.max_bytes} bytes a frame may have"
        elif n <= 8:
            problem = f"a frame of {n} bytes: a frame is 8 bytes of time, then a JPEG"
        size = jpeg_size(message[8:]) if not problem else None
        if size is not None and max(size) > self.max_side:  # said before it is decoded
            problem = f"a frame of {size[0]}x{size[1]}: over {self.max_side} pixels a side"
        if not problem:
            (stamp,) = struct.unpack_from("<d", message)
            buf = np.frombuffer(message, dtype=np.uint8, offset=8)
            ok = size is not None and np.isfinite(stamp)
            image = cv2.imdecode(buf, cv2.IMREAD_COLOR) if ok else None
            if image is None:
                problem = f"a frame of {n} bytes that is not a JPEG (or has no finite time)"
        with self._cond:
            if problem:
                self.refused += 1
                first = self.refused == 1
            else:
                self.received += 1
                if self._owner == page and self._reading:
                    if self._offset is None:  # a new page: on from where the last one was
                        self._offset = stamp / 1000.0 - self._t
                    self._image, self._stamp, self._fresh = image, stamp, True
                    self._cond.notify_all()
        if problem and first:  # said once in the terminal (the page hears each one)
            self.stage.say(f"{self.name}: {problem} (refused; more are counted, not said)")
        return problem

    def _waiting(self) -> str:
        if self._owner is None:
            return "waiting for the page: open it in a browser on this machine"
        return "waiting for the page's camera: allow it in the browser"

    def status(self) -> str:
        """Where the camera stands, for the page and ``/state.json``."""
        with self._cond:
            if not self._reading:
                return "not yet read (the run is getting ready)"
            if self._owner is None:
                return "the camera page closed" if self._gone_at is not None else "no page yet"
            return "receiving frames" if self.received else "waiting for the page's first frame"

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    # --- the loop's side (a Source) -------------------------------------------------------

    def read(self) -> Frame | None:
        with self._cond:
            self._reading = True
            self._cond.wait_for(lambda: self._fresh or self._closed, self.wait)
            if self._closed:
                self.ended = self.ended or "stopped"
                return None
            i = self._i
            self._i += 1
            if self._fresh:
                self._fresh = False
                assert self._offset is not None
                # media time never runs back (a page's clock is monotonic; a new page is
                # shifted to go on from the last frame)
                self._t = max(self._t, self._stamp / 1000.0 - self._offset)
                self._mono = time.monotonic()
                self.last_stamp = self._stamp
                return Frame(self._t, i, image=self._image)
            self.last_stamp = None
            gone = self._gone_at is not None and time.monotonic() - self._gone_at > self.grace
            if gone:
                self.ended = f"the camera page closed and did not come back in {self.grace:g} s"
                return None
            if self.received == 0:  # no page yet: media time has not begun
                now = time.monotonic()
                if now - self._mono >= REMIND:  # said now and then, not once and forgotten
                    self._mono = now
                    self.stage.say(f"{self.name}: {self._waiting()} ({self.stage.url})")
                return Frame(0.0, i)
            now = time.monotonic()
            self._t += now - self._mono
            self._mono = now
            return Frame(self._t, i)
