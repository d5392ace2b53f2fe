"""The live page's server: one local page that is the performer's camera and the avatar's
stage.

``Stage`` serves ``http://127.0.0.1:PORT/`` (the page, ``vision/static``) and a WebSocket
at ``/ws`` with the ``websockets`` library's threaded server: the performance loop runs
in its own thread and publishes to the stage, so a server with one thread a connection
fits it without an event loop to share. Each page gets the library skeleton once, then
the newest avatar pose, state and performer picture as they come (a slow page gets the
newest, never a backlog). With ``camera=True`` the first page is also the camera: its
frames go to ``BrowserCamera``, the source the loop reads; a second page only watches,
but one that opened within the camera's grace before the camera page closed (a reload
the server saw the old page leave only after) takes over as the camera.

Limits: bound to 127.0.0.1, and a request naming another host (a DNS-rebinding page) or
a WebSocket from another origin is refused; at most ``max_clients`` pages at once, and
``SPARE_CONNECTIONS`` more connections (the next gets 503); a connection that does not
finish its handshake within ``idle_timeout`` seconds, or stops answering pings for as
long, is closed; ``close()`` ends them all.
"""

from __future__ import annotations

import contextlib
import json
import socket
import sys
import threading
import time
from collections.abc import Callable
from http import HTTPStatus
from pathlib import Path
from typing import Any

from websockets.datastructures import Headers
from websockets.exceptions import ConnectionClosed
from websockets.http11 import Request, Response
from websockets.sync.server import Server, ServerConnection, serve

from ._browser import BrowserCamera

__all__ = ["MAX_MESSAGE", "Stage"]

STATIC = Path(__file__).with_name("static")
_FILES = {
    "/": ("stage.html", "text/html; charset=utf-8"),
    "/stage.js": ("stage.js", "text/javascript; charset=utf-8"),
    "/three.module.min.js": ("three.module.min.js", "text/javascript; charset=utf-8"),
    "/three.LICENSE": ("three.LICENSE", "text/plain; charset=utf-8"),
}
#: connections at once beyond the pages: loading a page, ``/state.json``
SPARE_CONNECTIONS = 8
_BUSY = b"HTTP/1.1 503 Service Unavailable\r\nContent-Length: 0\r\nConnection: close\r\n\r\n"
#: bytes a WebSocket message may have: a bigger one closes its connection (1009); a
#: frame under this but over ``BrowserCamera.max_bytes`` is refused with a message
MAX_MESSAGE = 16 << 20


def _say(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


class _Client:
    """One page: its connection and the newest of each thing to send it."""

    def __init__(self, conn: ServerConnection, number: int) -> None:
        self.conn = conn
        self.number = number
        self.camera = False
        self.opened = time.monotonic()
        self.cond = threading.Condition()
        self.latest: dict[str, Any] = {}  # "pose", "state", "picture": newest only
        self.notes: list[str] = []  # JSON notices, all sent, in order
        self.closed = False

    def post(self, kind: str, message: Any) -> None:
        with self.cond:
            if kind == "note":
                self.notes.append(message)
            else:
                self.latest[kind] = message
            self.cond.notify()

    def sender(self) -> None:
        """Send what was posted until the connection ends (its own thread)."""
        while True:
            with self.cond:
                self.cond.wait_for(lambda: self.closed or self.notes or self.latest, 1.0)
                if self.closed:
                    return
                notes, self.notes = self.notes, []
                latest, self.latest = self.latest, {}
            try:
                for text in notes:
                    self.conn.send(text)
                for message in latest.values():
                    self.conn.send(message)
            except (ConnectionClosed, OSError):
                return


class Stage:
    """The local page's server (module docstring). ``publish_*`` are called from the
    performance loop; ``camera`` is the page's camera as a source (``camera=True``)."""

    def __init__(
        self,
        port: int = 8765,
        camera: bool = False,
        max_clients: int = 8,
        idle_timeout: float = 10.0,
        say: Callable[[str], None] = _say,
    ) -> None:
        if max_clients < 1:
            raise ValueError("max_clients must be at least 1")
        self.say = say
        self.max_clients = max_clients
        self._lock = threading.Lock()
        self._clients: dict[int, _Client] = {}
        self._numbers = 0
        self._hello: dict[str, Any] = {"type": "hello", "skeleton": None}
        self._state: dict[str, Any] = {"t": 0.0}
        self._extra: dict[str, str] = {}  # the newest message of each other kind
        #: takes a page's command (``choose``, ``sketch``: ``mimic play``) and says what
        #: is wrong with it ("" when nothing); ``None``: the run takes no commands
        self.on_command: Callable[[dict[str, Any]], str] | None = None
        #: the newest statistics a page reported (camera-to-avatar latency, frame rate)
        self.page_stats: dict[str, Any] = {}
        self.camera = BrowserCamera(self) if camera else None
        self._server: Server = serve(
            self._handle,
            "127.0.0.1",
            port,
            process_request=self._http,
            max_size=MAX_MESSAGE,
            open_timeout=idle_timeout,
            ping_interval=idle_timeout,
            ping_timeout=idle_timeout,
            close_timeout=2.0,
            compression=None,  # JPEG does not compress; poses are small
            server_header=None,
        )
        self.port = int(self._server.socket.getsockname()[1])
        self._bound_connections(max_clients + SPARE_CONNECTIONS)
        self._thread = threading.Thread(
            target=self._server.serve_forever, name="mimic-stage", daemon=True
        )
        self._thread.start()

    def _bound_connections(self, most: int) -> None:
        """At most ``most`` connections served at once (a thread each): the next is
        answered 503 by the accepting thread and closed."""
        server = self._server
        inner = server.handler
        slots = threading.BoundedSemaphore(most)

        def bounded(sock: socket.socket, addr: Any) -> None:
            if not slots.acquire(blocking=False):
                with contextlib.suppress(OSError):
                    sock.settimeout(1.0)
                    sock.sendall(_BUSY)
                sock.close()
                # as the library's own handler does when it ends (else shutdown waits)
                with server.lock:
                    getattr(server, "handler_threads", set()).discard(threading.current_thread())
                return
            try:
                inner(sock, addr)
            finally:
                slots.release()

        self._server.handler = bounded  # (read by serve_forever at each connection)

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}/"

    # --- HTTP --------------------------------------------------------------------------

    def _http(self, conn: ServerConnection, request: Request) -> Response | None:
        host = request.headers.get("Host", "")
        if host not in (f"127.0.0.1:{self.port}", f"localhost:{self.port}"):
            return conn.respond(HTTPStatus.FORBIDDEN, "this page is served to this machine only\n")
        path = request.path.split("?", 1)[0]
        if path == "/ws":
            origin = request.headers.get("Origin")
            if origin is not None and origin not in (f"http://{host}",):
                return conn.respond(HTTPStatus.FORBIDDEN, f"origin {origin} may not connect\n")
            with self._lock:
                full = len(self._clients) >= self.max_clients
            if full:
                return conn.respond(
                    HTTPStatus.SERVICE_UNAVAILABLE,
                    f"{self.max_clients} pages are open already: close one\n",
                )
            return None  # the WebSocket handshake goes on
        if path == "/state.json":
            return self._response(json.dumps(self.state()).encode(), "application/json")
        if path not in _FILES:
            return conn.respond(HTTPStatus.NOT_FOUND, "not found\n")
        name, kind = _FILES[path]
        return self._response((STATIC / name).read_bytes(), kind)

    @staticmethod
    def _response(body: bytes, kind: str) -> Response:
        headers = Headers()
        headers["Content-Type"] = kind
        headers["Content-Length"] = str(len(body))
        headers["Cache-Control"] = "no-store"
        return Response(200, "OK", headers, body)

    # --- WebSocket ---------------------------------------------------------------------

    def _handle(self, conn: ServerConnection) -> None:
        with self._lock:
            self._numbers += 1
            client = _Client(conn, self._numbers)
            self._clients[client.number] = client
            hello = dict(self._hello)
        camera = self.camera
        if camera is not None:
            client.camera = camera.attach(client.number)
            hello["role"] = "camera" if client.camera else "viewer"
            if not client.camera:
                self.say("a second page opened: it shows the run; the first stays the camera")
                hello["note"] = "another page is the camera: this one only shows the avatar"
        else:
            hello["role"] = "viewer"
        hello["controls"] = self.on_command is not None
        client.post("note", json.dumps(hello))
        client.post("state", json.dumps({"type": "state", **self.state()}))
        with self._lock:
            extra = dict(self._extra)
        for kind, text in extra.items():
            client.post(kind, text)
        sender = threading.Thread(target=client.sender, name="mimic-stage-send", daemon=True)
        sender.start()
        why = ""
        try:
            for message in conn:
                if isinstance(message, bytes):
                    self._frame(client, message)
                else:
                    self._text(client, message)
        except ConnectionClosed as exc:
            close = exc.sent if exc.sent is not None and exc.sent.code != 1000 else exc.rcvd
            why = f"{close.code} {close.reason}".strip() if close is not None else ""
            if close is not None and close.code not in (1000, 1001) and not client.camera:
                self.say(f"a page's connection closed ({why})")
        finally:
            with self._lock:
                self._clients.pop(client.number, None)
            with client.cond:
                client.closed = True
                client.cond.notify()
            if camera is not None and client.camera:
                camera.detach(client.number, why)
                self._take_over(camera)

    def _take_over(self, camera: BrowserCamera) -> None:
        """A page that opened while the camera page was still open becomes the camera
        once that one has gone: the newest that opened within the camera's grace. A
        reloaded page can open before the server sees the old one close, and would
        otherwise only show the run while the run waits for a camera; a page opened
        longer ago is someone watching, and stays so."""
        now = time.monotonic()
        with self._lock:
            waiting = [
                c for c in self._clients.values() if not c.camera and now - c.opened <= camera.grace
            ]
        newest = max(waiting, key=lambda c: c.number, default=None)
        if newest is not None and camera.attach(newest.number):
            newest.camera = True
            hello = {"type": "hello", "role": "camera", "controls": self.on_command is not None}
            hello["note"] = "the camera page before this one closed: this page is the camera"
            newest.post("note", json.dumps(hello))
            self.say("the page that opened last took over as the camera")

    def _frame(self, client: _Client, message: bytes) -> None:
        if self.camera is None or not client.camera:
            self.note(client, "this page is not the camera: its frames are not used")
            return
        problem = self.camera.put(client.number, message)
        if problem:
            self.note(client, problem, level="error")

    def _text(self, client: _Client, text: str) -> None:
        try:
            message = json.loads(text)
            kind = message["type"]
        except (ValueError, KeyError, TypeError):
            self.note(client, f"a message that is not JSON with a type: {text[:60]!r}", "error")
            return
        if kind == "camera-error":
            name = str(message.get("name", "Error"))[:60]
            said = str(message.get("message", ""))[:200]
            self.say(f"the page could not open a camera: {name}: {said} ({_ADVICE.get(name, '')})")
        elif kind in ("choose", "sketch"):
            if self.on_command is None:
                self.note(client, "this run takes no commands (choice and sketch: mimic play)")
            elif problem := self.on_command(message):
                self.note(client, problem, "error")
        elif kind == "stats":
            self.page_stats = {
                k: message[k]
                for k in ("p50_ms", "p99_ms", "fps", "frames", "n")
                if isinstance(message.get(k), int | float)
            }
        else:
            self.note(client, f"unknown message type {kind!r}", "error")

    def note(self, client: _Client, text: str, level: str = "info") -> None:
        """A message for one page (shown on it)."""
        client.post("note", json.dumps({"type": "note", "level": level, "text": text}))

    # --- publishing (from the performance loop) -----------------------------------------

    def _post(self, kind: str, message: Any) -> None:
        with self._lock:
            clients = list(self._clients.values())
        for client in clients:
            client.post(kind, message)

    def set_skeleton(self, skeleton: dict[str, Any]) -> None:
        """The avatar's skeleton (sent to each page once, before its poses)."""
        with self._lock:
            self._hello["skeleton"] = skeleton
        self._post("note", json.dumps({"type": "skeleton", "skeleton": skeleton}))

    def publish_pose(self, pose: dict[str, Any]) -> None:
        self._post("pose", json.dumps({"type": "pose", **pose}))

    def publish_picture(self, jpeg: bytes) -> None:
        """The performer as the loop saw them (a JPEG: frame, mask, landmarks)."""
        self._post("picture", jpeg)

    def publish_extra(self, kind: str, text: str) -> None:
        """Another kind of message (``options``, ``plan``): its newest goes to each page,
        and to pages that open later."""
        with self._lock:
            self._extra[kind] = text
        self._post(kind, text)

    def set_state(self, **state: Any) -> None:
        with self._lock:
            self._state.update(state)
            now = dict(self._state)
        self._post("state", json.dumps({"type": "state", **now}))

    def state(self) -> dict[str, Any]:
        with self._lock:
            now = {**self._state, "pages": len(self._clients)}
        if self.camera is not None:
            now["camera"] = self.camera.status()
        return now

    def broadcast(self, text: str, level: str = "info") -> None:
        """A message for every page."""
        self._post("note", json.dumps({"type": "note", "level": level, "text": text}))

    # --- the end ------------------------------------------------------------------------

    def close(self) -> None:
        """Stop serving: every page's connection ends, the port is released."""
        if self.camera is not None:
            self.camera.close()
        self._server.shutdown(reason="the run ended")  # (closes every page's connection)
        self._thread.join(timeout=5.0)

    def __enter__(self) -> Stage:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


_ADVICE = {
    "NotAllowedError": "allow the camera for this page in the browser, then reload it",
    "NotFoundError": "no camera on this machine: plug one in, then reload the page",
    "NotReadableError": "the camera is in use by another program",
    "OverconstrainedError": "the camera cannot give the size asked for",
}
