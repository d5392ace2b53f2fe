"""The live page's server and the page's camera as a source: what the page gets, who is
the camera, and every bad thing a page can send or do (quick, no browser: a WebSocket
client stands in for the page)."""

from __future__ import annotations

import contextlib
import json
import socket
import struct
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Callable, Iterator
from typing import Any

import cv2
import numpy as np
import pytest
from websockets.exceptions import ConnectionClosed, InvalidStatus
from websockets.sync.client import ClientConnection, connect

from vision import BrowserCamera, Stage

SKELETON = {"names": ["hips", "head"], "parents": [-1, 0], "offsets": [[0, 0, 0], [0, 0.5, 0]]}


def _jpeg(w: int = 64, h: int = 48) -> bytes:
    img = np.zeros((h, w, 3), np.uint8)
    img[10:30, 20:40] = 255
    return cv2.imencode(".jpg", img)[1].tobytes()


def _frame(stamp_ms: float, jpeg: bytes | None = None) -> bytes:
    return struct.pack("<d", stamp_ms) + (jpeg if jpeg is not None else _jpeg())


def _get(url: str) -> bytes:
    with urllib.request.urlopen(url, timeout=5) as r:
        return bytes(r.read())


def _page(stage: Stage) -> ClientConnection:
    return connect(f"ws://127.0.0.1:{stage.port}/ws", open_timeout=5)


def _until(ws: ClientConnection, kind: str, timeout: float = 5.0) -> dict[str, Any]:
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        message = ws.recv(timeout=timeout)
        if isinstance(message, str) and (got := json.loads(message))["type"] == kind:
            return dict(got)
    raise TimeoutError(kind)


class Said(list[str]):
    def __call__(self, text: str) -> None:
        self.append(text)


def _soon(ok: Callable[[], bool], timeout: float = 5.0) -> bool:
    """Whether ``ok()`` holds within ``timeout`` seconds (what the server does with a
    message happens on its own thread, a moment after the message is sent)."""
    t0 = time.monotonic()
    while not ok():
        if time.monotonic() - t0 > timeout:
            return False
        time.sleep(0.01)
    return True


def test_the_page_its_files_and_state_are_served_to_this_machine_only() -> None:
    with Stage(port=0) as stage:
        page = _get(stage.url).decode()
        assert 'src="/stage.js"' in page
        js = _get(stage.url + "stage.js").decode()
        assert 'from "./three.module.min.js"' in js
        three = _get(stage.url + "three.module.min.js")
        assert len(three) > 500_000 and b"REVISION" in three
        stage.set_state(t=1.5, action="Squat")
        state = json.loads(_get(stage.url + "state.json"))
        assert state["action"] == "Squat" and state["t"] == 1.5
        with pytest.raises(urllib.error.HTTPError) as got:
            _get(stage.url + "nothing")
        got.value.close()
        assert got.value.code == 404
        # a page of another host (DNS rebinding) is refused, and a socket of another origin
        bad = urllib.request.Request(stage.url, headers={"Host": f"evil.example:{stage.port}"})
        with pytest.raises(urllib.error.HTTPError) as got, urllib.request.urlopen(bad, timeout=5):
            pass
        got.value.close()
        assert got.value.code == 403
        with pytest.raises(InvalidStatus) as refused:
            connect(f"ws://127.0.0.1:{stage.port}/ws", origin="http://evil.example")  # type: ignore[arg-type]
        assert refused.value.response.status_code == 403


def test_each_page_gets_the_skeleton_then_the_newest_pose_and_state() -> None:
    with Stage(port=0) as stage:
        stage.set_skeleton(SKELETON)
        with _page(stage) as ws:
            hello = _until(ws, "hello")
            assert hello["role"] == "viewer" and hello["skeleton"] == SKELETON
            for i in range(50):  # a burst: the page gets the newest, not a backlog
                stage.publish_pose({"t": i / 30, "root": [0, 1, 0], "q": [[1, 0, 0, 0]] * 2})
            stage.set_state(t=2.0, action="Jog", cost=1.25)
            stage.publish_picture(_jpeg())
            poses, state, picture = [], None, None
            t0 = time.monotonic()
            while time.monotonic() - t0 < 5 and (state is None or picture is None or not poses):
                m = ws.recv(timeout=5)
                if isinstance(m, bytes):
                    picture = m
                elif (got := json.loads(m))["type"] == "pose":
                    poses.append(got)
                elif got["type"] == "state" and got.get("action") == "Jog":
                    state = got
            assert state is not None and state["cost"] == 1.25
            assert picture is not None and picture[:2] == b"\xff\xd8"
            assert len(poses) < 50 and poses[-1]["t"] == pytest.approx(49 / 30)


def test_the_first_page_is_the_camera_and_a_second_only_watches() -> None:
    said = Said()
    with Stage(port=0, camera=True, say=said) as stage:
        camera = stage.camera
        assert camera is not None and camera.read() is not None  # the loop starts reading
        with _page(stage) as first, contextlib.ExitStack() as stack:
            assert _until(first, "hello")["role"] == "camera"  # (before the second opens)
            second = stack.enter_context(_page(stage))
            hello = _until(second, "hello")
            assert hello["role"] == "viewer" and "another page is the camera" in hello["note"]
            assert any("a second page opened" in s for s in said)
            second.send(_frame(0.0))  # its frames are not used, and it is told so
            assert "not the camera" in _until(second, "note")["text"]
            for k in range(3):
                first.send(_frame(1000.0 + 100.0 * k))
                time.sleep(0.05)
            frames = []
            while len(frames) < 1:
                f = camera.read()
                assert f is not None
                if f.image is not None:
                    frames.append(f)
            assert frames[-1].image.shape == (48, 64, 3)  # type: ignore[union-attr]
            assert camera.last_stamp == 1200.0 and frames[-1].t == pytest.approx(0.2)
        assert json.loads(_get(stage.url + "state.json"))["camera"]


def test_bad_frames_are_refused_with_a_message_and_the_run_goes_on() -> None:
    said = Said()
    with Stage(port=0, camera=True, say=said) as stage:
        camera = stage.camera
        assert camera is not None
        camera.read()
        with _page(stage) as ws:
            _until(ws, "hello")
            ws.send(b"\x00\x01")
            assert "8 bytes of time, then a JPEG" in _until(ws, "note")["text"]
            ws.send(_frame(5.0, b"not a jpeg at all"))
            assert "not a JPEG" in _until(ws, "note")["text"]
            ws.send(_frame(float("nan")))
            assert "not a JPEG (or has no finite time)" in _until(ws, "note")["text"]
            ws.send(_frame(6.0, b"\xff" * (camera.max_bytes + 1)))
            assert "over the" in _until(ws, "note")["text"]
            # a small file declaring a huge picture is refused before it is decoded
            bomb = bytearray(_jpeg())
            sof = bomb.index(b"\xff\xc0")
            bomb[sof + 5 : sof + 9] = (60000).to_bytes(2, "big") * 2
            ws.send(_frame(7.0, bytes(bomb)))
            assert "60000x60000: over 4096 pixels a side" in _until(ws, "note")["text"]
            ws.send("{not json")
            assert "not JSON" in _until(ws, "note")["text"]
            ws.send(
                json.dumps({"type": "camera-error", "name": "NotAllowedError", "message": "no"})
            )
            ws.send(_frame(10.0))  # a good frame after all that is taken
            assert _soon(lambda: camera.received == 1) and camera.refused == 5
        said_all = "\n".join(said)
        assert (
            "could not open a camera: NotAllowedError" in said_all
            and "allow the camera" in said_all
        )
        assert said_all.count("refused; more are counted") == 1  # said once, not per frame
        # a message over the socket's limit closes that page's connection (1009), said
        with _page(stage) as ws:
            _until(ws, "hello")
            ws.send(b"\x00" * (17 << 20))
            with pytest.raises(ConnectionClosed) as closed:
                while True:
                    ws.recv(timeout=5)
            assert closed.value.rcvd is not None and closed.value.rcvd.code == 1009
        assert _soon(lambda: any("closed" in s and "1009" in s for s in said))


@contextlib.contextmanager
def _read_camera(said: Said, grace: float = 0.5) -> Iterator[tuple[Stage, BrowserCamera]]:
    """A stage whose camera the run has begun to read (frames are taken from then on),
    with a camera page awaited ``grace`` seconds once it closes."""
    with Stage(port=0, camera=True, say=said) as stage:
        camera = stage.camera
        assert camera is not None
        camera.grace = grace
        camera.read()
        yield stage, camera


def test_the_camera_page_closing_ends_the_source_after_its_grace() -> None:
    said = Said()
    with _read_camera(said) as (stage, camera):
        with _page(stage) as ws:
            _until(ws, "hello")
            ws.send(_frame(0.0))
            ws.send(_frame(400.0))
            assert _soon(lambda: camera.received == 2)
        t0 = time.monotonic()
        last = None
        while (f := camera.read()) is not None:
            last = f
            assert time.monotonic() - t0 < 5
        assert last is not None and last.t >= 0.4  # media time went on while it waited
        assert "did not come back" in camera.ended
        assert any("the camera page closed at" in s for s in said)


def test_a_page_that_comes_back_goes_on_where_the_last_stopped() -> None:
    with Stage(port=0, camera=True, say=Said()) as stage:
        camera = stage.camera
        assert camera is not None
        camera.read()
        with _page(stage) as ws:
            _until(ws, "hello")
            ws.send(_frame(50_000.0))
            assert _soon(lambda: camera.received == 1)
        assert (f := camera.read()) is not None and f.t == 0.0
        with _page(stage) as ws:  # a reload: its clock starts again near 0
            # (the camera at once, or once the server has seen the old page go)
            assert _camera_hello(ws)
            ws.send(_frame(10.0))
            ws.send(_frame(110.0))
            assert _soon(lambda: camera.received == 3)
        got = [f for _ in range(3) if (f := camera.read()) is not None and f.image is not None]
        assert got and 0.0 <= got[-1].t < 1.0


def _camera_hello(ws: ClientConnection) -> bool:
    """Whether the page is told it is the camera within 5 s."""
    with contextlib.suppress(TimeoutError):
        while _until(ws, "hello")["role"] != "camera":
            pass
        return True
    return False


def test_a_reload_that_opens_before_the_old_page_closes_takes_over_as_the_camera() -> None:
    said = Said()
    with _read_camera(said) as (stage, camera):
        with contextlib.ExitStack() as pages:
            first = pages.enter_context(_page(stage))
            # (the second page opened once the first is told it is the camera: the
            # server registers a page after its handshake, so the two could swap)
            assert _until(first, "hello")["role"] == "camera"
            old = pages.enter_context(_page(stage))
            assert _until(old, "hello")["role"] == "viewer"
            time.sleep(0.7)  # opened beyond the grace before the camera goes: someone watching
            with _page(stage) as new:
                hello = _until(new, "hello")
                assert hello["role"] == "viewer" and "another page" in hello["note"]
                first.close()  # the camera page goes: the page opened last takes over
                got = _until(new, "hello")
                assert got["role"] == "camera" and "before this one closed" in got["note"]
                new.send(_frame(10.0))
                new.send(_frame(110.0))
                time.sleep(0.2)
                got = [
                    f for _ in range(3) if (f := camera.read()) is not None and f.image is not None
                ]
                assert got  # its frames drive the run
            with pytest.raises(TimeoutError):
                _until(old, "hello", timeout=0.5)
        assert any("took over as the camera" in s for s in said)


def test_pages_beyond_the_cap_get_503_and_close_frees_the_port() -> None:
    stage = Stage(port=0, max_clients=2)
    done = threading.Event()

    def wait_close(ws: ClientConnection) -> None:
        try:
            while True:
                ws.recv(timeout=10)
        except (ConnectionClosed, TimeoutError):
            done.set()

    with _page(stage) as first, _page(stage):
        time.sleep(0.1)
        with pytest.raises(InvalidStatus) as full, _page(stage):
            pass
        assert full.value.response.status_code == 503
        threading.Thread(target=wait_close, args=(first,), daemon=True).start()
        stage.close()
        assert done.wait(5.0)
    with socket.socket() as s:  # nothing listens there any more
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        s.bind(("127.0.0.1", stage.port))


def test_connections_beyond_the_cap_get_503_and_idle_ones_are_closed() -> None:
    with Stage(port=0, max_clients=1, idle_timeout=0.5) as stage:
        idle = [socket.create_connection(("127.0.0.1", stage.port)) for _ in range(9)]
        time.sleep(0.2)
        with socket.create_connection(("127.0.0.1", stage.port)) as extra:
            extra.settimeout(5)
            assert extra.recv(100).startswith(b"HTTP/1.1 503")
        for s in idle:  # a connection that sends nothing is closed after idle_timeout
            s.settimeout(5)
            with contextlib.suppress(ConnectionResetError):
                assert s.recv(100) == b""
            s.close()
        assert "<title>mimic</title>" in _get(stage.url).decode()  # and the slots are free


def test_a_run_waiting_for_the_page_says_so_now_and_then(monkeypatch: pytest.MonkeyPatch) -> None:
    import vision._browser

    monkeypatch.setattr(vision._browser, "REMIND", 0.2)
    said = Said()
    with Stage(port=0, camera=True, say=said) as stage:
        camera = stage.camera
        assert camera is not None
        camera.wait = 0.05
        t0 = time.monotonic()
        while time.monotonic() - t0 < 0.5:
            f = camera.read()
            assert f is not None and f.t == 0.0 and f.image is None
        assert any("waiting for the page: open it" in s and stage.url in s for s in said)
        with _page(stage) as ws:
            _until(ws, "hello")
            time.sleep(0.3)
            camera.read()
            assert "allow it in the browser" in said[-1]
