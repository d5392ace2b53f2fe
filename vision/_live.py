"""A live view for the performer: a local web page with the latest frame and state.

OpenCV here is headless (no window), so the view is a page served on ``127.0.0.1`` only:
open ``http://127.0.0.1:PORT/`` in a browser on the same machine. The page shows the
performer's silhouette beside the avatar (``/frame.jpg``, fetched again and again) and
the current action, match cost and decision latency (``/state.json``); ``/stream`` is the
same picture as an MJPEG stream for other viewers.

The server is bounded: at most ``max_clients`` requests are served at once (the rest get
503 at once, from the serving thread), a socket that sends nothing for ``idle_timeout``
seconds is closed, and ``close()`` ends every stream and request.
"""

from __future__ import annotations

import contextlib
import json
import socket
import threading
from collections.abc import Sequence
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from control.motion import Clip

from ._video import performer_pane

__all__ = ["LivePainter", "LiveView"]

_PAGE = b"""<!doctype html><html><head><meta charset="utf-8"><title>mimic live</title>
<style>
body{background:#1d1f24;color:#ddd;font-family:sans-serif;margin:0;text-align:center}
h3{margin:10px}#v{width:96vw;max-width:1280px;background:#000}
#s{font-size:20px;margin:8px}b{color:#fff}
</style></head><body>
<h3>mimic: you (left) and the avatar (right)</h3>
<img id="v" alt="waiting for the first frame">
<div id="s">action <b id="a">-</b> &middot; match cost <b id="c">-</b>
&middot; decision <b id="l">-</b> ms &middot; <span id="t">-</span></div>
<script>
const v = document.getElementById("v");
let shown = -1;
async function tick() {
  try {
    const s = await (await fetch("/state.json", {cache: "no-store"})).json();
    document.getElementById("a").textContent = s.action ?? "-";
    document.getElementById("c").textContent = s.cost == null ? "-" : s.cost.toFixed(3);
    document.getElementById("l").textContent =
      s.latency_ms == null ? "-" : s.latency_ms.toFixed(1);
    document.getElementById("t").textContent =
      (s.clip ? s.clip + ":" + s.clip_frame + " \\u00b7 " : "") + s.t.toFixed(1) + " s";
    if (s.frame !== shown && s.frame >= 0) {
      const blob = await (await fetch("/frame.jpg?n=" + s.frame, {cache: "no-store"})).blob();
      const old = v.src;
      v.src = URL.createObjectURL(blob);
      if (old) URL.revokeObjectURL(old);
      shown = s.frame;
      document.title = "mimic live: frame " + shown;
    }
  } catch (e) {}
  setTimeout(tick, 100);
}
tick();
</script></body></html>"""


class _Server(ThreadingHTTPServer):
    daemon_threads = True
    request_queue_size = 64  # accept quickly: the cap is on threads, not connections

    def __init__(self, address: tuple[str, int], handler: Any, max_clients: int) -> None:
        self._slots = threading.BoundedSemaphore(max_clients)
        self._open: set[Any] = set()  # sockets being served
        self._lock = threading.Lock()
        super().__init__(address, handler)

    def drop_all(self) -> None:
        """Shut every socket being served (their threads then end)."""
        with self._lock:
            open_now = list(self._open)
        for sock in open_now:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)

    def process_request(self, request: Any, client_address: Any) -> None:
        if not self._slots.acquire(blocking=False):
            # full: answer 503 here, briefly, instead of starting another thread
            try:
                request.settimeout(1.0)
                request.sendall(
                    b"HTTP/1.0 503 Service Unavailable\r\nContent-Length: 0\r\n"
                    b"Connection: close\r\n\r\n"
                )
            except OSError:
                pass
            self.shutdown_request(request)
            return
        super().process_request(request, client_address)

    def process_request_thread(self, request: Any, client_address: Any) -> None:
        with self._lock:
            self._open.add(request)
        try:
            super().process_request_thread(request, client_address)
        finally:
            with self._lock:
                self._open.discard(request)
            self._slots.release()


class LiveView:
    """Serve frames (BGR or grey ``uint8`` images) and a state as a live page on
    localhost."""

    def __init__(
        self,
        port: int = 8765,
        fps: float = 15.0,
        max_clients: int = 8,
        idle_timeout: float = 10.0,
    ) -> None:
        if max_clients < 1:
            raise ValueError("max_clients must be at least 1")
        self._jpeg: bytes | None = None
        self._n = -1  # frames published so far - 1
        self._state: dict[str, Any] = {"t": 0.0}
        self._cond = threading.Condition()
        self._closed = threading.Event()
        self._period = 1.0 / fps
        view = self

        class Handler(BaseHTTPRequestHandler):
            timeout = idle_timeout  # an idle socket is closed after this
            protocol_version = "HTTP/1.1"  # keep-alive: the page's requests reuse one

            def log_message(self, *args: Any) -> None:  # quiet
                pass

            def _send(self, body: bytes, kind: str) -> None:
                self.send_response(200)
                self.send_header("Content-Type", kind)
                self.send_header("Content-Length", str(len(body)))
                self.send_header("Cache-Control", "no-store")
                self.end_headers()
                self.wfile.write(body)

            def do_GET(self) -> None:
                if view._closed.is_set():
                    self.send_error(503)
                    self.close_connection = True
                    return
                path = self.path.split("?", 1)[0]
                if path == "/":
                    self._send(_PAGE, "text/html; charset=utf-8")
                elif path == "/state.json":
                    self._send(json.dumps(view.state()).encode(), "application/json")
                elif path == "/frame.jpg":
                    jpeg = view.latest()
                    if jpeg is None:
                        self.send_error(404, "no frame yet")
                    else:
                        self._send(jpeg, "image/jpeg")
                elif path == "/stream":
                    self._stream()
                else:
                    self.send_error(404)

            def _stream(self) -> None:
                self.close_connection = True
                self.send_response(200)
                self.send_header("Content-Type", "multipart/x-mixed-replace; boundary=frame")
                self.send_header("Connection", "close")
                self.end_headers()
                seen = -2
                try:
                    while not view._closed.is_set():
                        got = view.wait_frame(after=seen, timeout=1.0)
                        if got is None:
                            continue
                        seen, jpeg = got
                        self.wfile.write(b"--frame\r\nContent-Type: image/jpeg\r\n")
                        self.wfile.write(f"Content-Length: {len(jpeg)}\r\n\r\n".encode())
                        self.wfile.write(jpeg + b"\r\n")
                        if view._closed.wait(view._period):
                            break
                except (BrokenPipeError, ConnectionResetError, TimeoutError):
                    return

        self._server = _Server(("127.0.0.1", port), Handler, max_clients)
        self.port = int(self._server.server_address[1])
        self._thread = threading.Thread(
            target=self._server.serve_forever, name="mimic-live", daemon=True
        )
        self._thread.start()

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}/"

    def update(self, image: NDArray[np.uint8], **state: Any) -> None:
        """Publish a frame, and optionally the state shown beside it."""
        ok, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 85])
        if ok:
            with self._cond:
                self._jpeg = buf.tobytes()
                self._n += 1
                self._cond.notify_all()
        if state:
            self.set_state(**state)

    def set_state(self, **state: Any) -> None:
        """Set fields of the state (``t``, ``action``, ``cost``, ``latency_ms``, ``clip``,
        ``clip_frame``)."""
        with self._cond:
            self._state.update(state)

    def state(self) -> dict[str, Any]:
        with self._cond:
            return {**self._state, "frame": self._n}

    def latest(self) -> bytes | None:
        with self._cond:
            return self._jpeg

    def wait_frame(self, after: int = -2, timeout: float | None = None) -> tuple[int, bytes] | None:
        """The newest frame (its number and JPEG) once there is one newer than ``after``;
        ``None`` on timeout or once closed."""
        with self._cond:
            ok = self._cond.wait_for(
                lambda: self._closed.is_set() or (self._jpeg is not None and self._n > after),
                timeout,
            )
            if not ok or self._closed.is_set() or self._jpeg is None:
                return None
            return self._n, self._jpeg

    def close(self) -> None:
        """Stop serving: streams end, the port is released."""
        self._closed.set()
        with self._cond:
            self._cond.notify_all()
        self._server.shutdown()
        self._server.drop_all()
        self._server.server_close()
        self._thread.join(timeout=5.0)

    def __enter__(self) -> LiveView:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class LivePainter:
    """Feeds a ``LiveView`` from ``perform``: ``on_frame`` draws the performer as the
    side-by-side video does (``vision._video.performer_pane``: a colour frame with the
    person mask and the landmarks over it, or the mask in white) beside the avatar's
    current library frame (its silhouette from the bank's camera that matched, orange on
    blue) at most ``fps`` times a second;
    ``on_decision`` sets the state (action, match cost, decision latency)."""

    PANE = (480, 360)

    def __init__(self, view: LiveView, clips: Sequence[Clip], graph: Any, bank: Any) -> None:
        from silhouette_bank import capsule_body

        self.view = view
        self.graph = graph
        self.ring = bank.settings.ring
        self.by_name = {c.name: c for c in clips}
        self.bodies = {c.name: capsule_body(c.motion.skeleton, bank.settings.body) for c in clips}
        self.view_index = 0
        self._last = -1.0
        self._period = view._period

    def on_frame(
        self,
        t: float,
        mask: NDArray[np.bool_] | None,
        avatar: Any,
        picture: tuple[Any, Any] = (None, None),
    ) -> None:
        if t - self._last < self._period - 1e-9:
            return
        self._last = t
        from silhouette_bank import motion_silhouettes

        w, h = self.PANE
        left = performer_pane((w, h), mask, *picture)
        clip_name, f = self.graph.locate(avatar.frame)
        clip = self.by_name[clip_name]
        sil = motion_silhouettes(clip.motion, self.bodies[clip_name], self.ring, np.array([f]))
        v = min(self.view_index, sil.shape[1] - 1)
        a = cv2.resize(sil[0, v], (w, h), interpolation=cv2.INTER_NEAREST) > 0
        right = np.empty((h, w, 3), dtype=np.uint8)
        right[:] = (70, 40, 20)  # BGR: dark blue
        right[a] = (40, 150, 255)  # orange
        label = clip.label_at(f)
        self.view.update(
            np.concatenate((left, right), axis=1),
            t=round(t, 3),
            clip=clip_name,
            clip_frame=int(f),
            action=label or clip_name,
        )

    def on_decision(self, entry: dict[str, Any]) -> None:
        if entry.get("view") is not None:
            self.view_index = int(entry["view"])
        state: dict[str, Any] = {"t": entry["t"]}
        if entry.get("decision") is not None:
            state.update(cost=entry.get("cost"), latency_ms=entry.get("latency_ms"))
        else:
            state.update(cost=None, latency_ms=None, why=entry.get("reason"))
        self.view.set_state(**state)
