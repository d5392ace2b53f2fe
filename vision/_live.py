"""A live view for the performer: a local web page that streams the latest frame.

OpenCV here is headless (no window), so the view is an MJPEG stream served on
``127.0.0.1`` only: open ``http://127.0.0.1:PORT/`` in a browser on the same machine.
"""

from __future__ import annotations

import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = ["LiveView"]

_PAGE = b"""<!doctype html><html><head><title>mimic</title></head>
<body style="background:#222;color:#ddd;font-family:sans-serif;text-align:center">
<h3>mimic: you (left) and the avatar (right)</h3><img src="/stream" style="width:90vw">
</body></html>"""


class LiveView:
    """Serve frames (BGR or grey ``uint8`` images) as a live page on localhost."""

    def __init__(self, port: int = 8765, fps: float = 15.0) -> None:
        self._jpeg: bytes | None = None
        self._cond = threading.Condition()
        self._period = 1.0 / fps
        view = self

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, *args: Any) -> None:  # quiet
                pass

            def do_GET(self) -> None:
                if self.path == "/":
                    self.send_response(200)
                    self.send_header("Content-Type", "text/html")
                    self.end_headers()
                    self.wfile.write(_PAGE)
                    return
                if self.path != "/stream":
                    self.send_error(404)
                    return
                self.send_response(200)
                self.send_header("Content-Type", "multipart/x-mixed-replace; boundary=frame")
                self.end_headers()
                try:
                    while True:
                        jpeg = view.wait_frame()
                        self.wfile.write(b"--frame\r\nContent-Type: image/jpeg\r\n")
                        self.wfile.write(f"Content-Length: {len(jpeg)}\r\n\r\n".encode())
                        self.wfile.write(jpeg + b"\r\n")
                        time.sleep(view._period)
                except (BrokenPipeError, ConnectionResetError):
                    return

        self._server = ThreadingHTTPServer(("127.0.0.1", port), Handler)
        self._server.daemon_threads = True
        self.port = int(self._server.server_address[1])
        self._thread = threading.Thread(target=self._server.serve_forever, daemon=True)
        self._thread.start()

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}/"

    def update(self, image: NDArray[np.uint8]) -> None:
        ok, buf = cv2.imencode(".jpg", image)
        if ok:
            with self._cond:
                self._jpeg = buf.tobytes()
                self._cond.notify_all()

    def wait_frame(self) -> bytes:
        with self._cond:
            while self._jpeg is None:
                self._cond.wait(1.0)
            return self._jpeg

    def close(self) -> None:
        self._server.shutdown()
        self._server.server_close()
