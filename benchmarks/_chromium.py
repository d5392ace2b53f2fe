"""A headless Chromium with a fake camera, driven over the DevTools protocol: the live
page's test and ``bench_vision``'s end-to-end latency.

Chromium's fake camera plays a ``.y4m`` file (4:2:0, a short header; it reads no MP4),
looping; ``--use-fake-ui-for-media-stream`` answers the camera prompt. A one-shot
``--screenshot`` run never starts the camera, so the browser is kept running with
``--remote-debugging-port=0`` and asked for the page's state and a screenshot.
"""

from __future__ import annotations

import base64
import contextlib
import json
import os
import shutil
import signal
import subprocess
import tempfile
import time
import urllib.request
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray
from websockets.sync.client import connect

__all__ = ["Chromium", "chromium_path", "write_y4m"]


def chromium_path() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        if path := shutil.which(name):
            return path
    return None


def write_y4m(frames: Iterable[NDArray[np.uint8]], path: Path, fps: float) -> int:
    """BGR frames (all of one even size) as a 4:2:0 ``.y4m`` at ``fps``; the count."""
    n = 0
    num, den = (round(fps * 1000), 1000) if fps != round(fps) else (round(fps), 1)
    with open(path, "wb") as fh:
        for img in frames:
            h, w = img.shape[:2]
            if n == 0:
                fh.write(f"YUV4MPEG2 W{w} H{h} F{num}:{den} Ip A1:1 C420jpeg\n".encode())
            fh.write(b"FRAME\n")
            fh.write(cv2.cvtColor(img, cv2.COLOR_BGR2YUV_I420).tobytes())
            n += 1
    return n


class Chromium:
    """A headless Chromium showing ``url``, its fake camera fed ``y4m`` (``None``: the
    browser's own test pattern; ``camera=False``: no camera at all). ``evaluate`` runs
    JavaScript in the page, ``screenshot`` returns it as BGR."""

    def __init__(
        self,
        url: str,
        y4m: Path | None = None,
        camera: bool = True,
        size: tuple[int, int] = (1280, 800),
        allow_camera: bool = True,
    ) -> None:
        exe = chromium_path()
        if exe is None:
            raise RuntimeError("no Chromium here: apt-get install chromium (.ci/run does)")
        # (a helper process may still write into the profile as it ends)
        self._dir = tempfile.TemporaryDirectory(
            prefix="mimic-chromium-", ignore_cleanup_errors=True
        )
        profile = Path(self._dir.name)
        cmd = [
            exe,
            "--headless=new",
            "--no-sandbox",
            "--hide-scrollbars",
            "--mute-audio",
            "--no-first-run",
            "--remote-debugging-port=0",
            f"--user-data-dir={profile}",
            f"--window-size={size[0]},{size[1]}",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
        ]
        if camera:
            cmd.append("--use-fake-device-for-media-stream")
            if y4m is not None:
                cmd.append(f"--use-file-for-fake-video-capture={y4m}")
        if allow_camera:
            cmd.append("--use-fake-ui-for-media-stream")
        else:
            cmd.append("--deny-permission-prompts")
        # Chromium keeps its single-instance socket in a folder of $TMPDIR, removed only
        # at a clean exit: a browser ended by a signal left one in /tmp each time
        env = {**os.environ, "TMPDIR": str(profile)}
        self._proc = subprocess.Popen(  # its own process group: close() ends its helpers too
            [*cmd, url],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
            env=env,
        )
        self._id = 0
        self._stack = contextlib.ExitStack()
        try:
            self._ws = self._stack.enter_context(
                connect(self._page_socket(profile, url), max_size=64 << 20)
            )
        except Exception:
            self.close()
            raise

    def _page_socket(self, profile: Path, url: str, timeout: float = 60.0) -> str:
        active = profile / "DevToolsActivePort"
        t0 = time.monotonic()
        while time.monotonic() - t0 < timeout:
            if self._proc.poll() is not None:
                raise RuntimeError(f"Chromium exited at once ({self._proc.returncode})")
            if active.is_file() and (text := active.read_text().split()):
                port = int(text[0])
                with contextlib.suppress(OSError):
                    with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list") as r:
                        pages = [p for p in json.load(r) if p.get("type") == "page"]
                    for p in pages:
                        if p.get("url", "").startswith(url.rstrip("/")):
                            return str(p["webSocketDebuggerUrl"])
            time.sleep(0.2)
        raise RuntimeError(f"Chromium did not open {url} in {timeout:g} s")

    def call(self, method: str, **params: Any) -> dict[str, Any]:
        self._id += 1
        self._ws.send(json.dumps({"id": self._id, "method": method, "params": params}))
        while True:
            reply = json.loads(self._ws.recv(timeout=60))
            if reply.get("id") == self._id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return dict(reply.get("result", {}))

    def evaluate(self, expression: str) -> Any:
        got = self.call("Runtime.evaluate", expression=expression, returnByValue=True)
        if "exceptionDetails" in got:
            raise RuntimeError(f"{expression}: {got['exceptionDetails']}")
        return got["result"].get("value")

    def wait_for(self, expression: str, timeout: float = 60.0) -> Any:
        """The value of ``expression`` once it is truthy (an expression that throws, as
        one naming what the page has not made yet, is false; so is a page that has no
        script context yet, still loading)."""
        guarded = f"(() => {{ try {{ return ({expression}); }} catch (e) {{ return null; }} }})()"
        t0 = time.monotonic()
        while time.monotonic() - t0 < timeout:
            try:
                value = self.evaluate(guarded)
            except RuntimeError as e:
                if "execution context" not in str(e):
                    raise
                value = None
            if value:
                return value
            time.sleep(0.2)
        raise TimeoutError(f"{expression}: still false after {timeout:g} s")

    def screenshot(self) -> NDArray[np.uint8]:
        data = base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"])
        img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
        assert img is not None
        return np.asarray(img, dtype=np.uint8)

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self._stack.close()
        for sig in (signal.SIGTERM, signal.SIGKILL):
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self._proc.pid, sig)
            try:
                self._proc.wait(timeout=10)
                break
            except subprocess.TimeoutExpired:
                continue
        time.sleep(0.2)  # the group's helpers end as the browser does
        self._dir.cleanup()

    def __enter__(self) -> Chromium:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
