"""The live view: a page, its state and frames on localhost, a bounded server, and a
real browser showing both panes of a performance."""

from __future__ import annotations

import json
import shutil
import socket
import subprocess
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path

import cv2
import numpy as np
import pytest

from tests.vision.conftest import RECORDING
from vision import LivePainter, LiveView, MatchSettings, PerformSettings, VideoSource, perform


@pytest.mark.slow
def test_page_state_frames_and_the_mjpeg_stream() -> None:
    with LiveView(port=0) as view:
        with pytest.raises(urllib.error.HTTPError, match="404"):
            urllib.request.urlopen(view.url + "frame.jpg", timeout=5)
        view.update(np.full((24, 32, 3), 200, dtype=np.uint8), t=1.5, action="Squat", cost=0.5)
        with urllib.request.urlopen(view.url, timeout=5) as r:
            page = r.read()
        assert b"/frame.jpg" in page and b"/state.json" in page
        with urllib.request.urlopen(view.url + "state.json", timeout=5) as r:
            state = json.loads(r.read())
        assert state == {"t": 1.5, "action": "Squat", "cost": 0.5, "frame": 0}
        with urllib.request.urlopen(view.url + "frame.jpg", timeout=5) as r:
            img = cv2.imdecode(np.frombuffer(r.read(), np.uint8), cv2.IMREAD_COLOR)
        assert img.shape == (24, 32, 3) and abs(int(img.mean()) - 200) < 3
        with urllib.request.urlopen(view.url + "stream", timeout=5) as r:
            head = r.read(200)
        assert b"--frame" in head and b"\xff\xd8" in head  # a JPEG follows the boundary


@pytest.mark.slow
def test_the_server_caps_its_threads_and_closes_idle_sockets() -> None:
    before = threading.active_count()
    with LiveView(port=0, max_clients=4, idle_timeout=0.5) as view:
        most = 0
        socks = []
        for _ in range(50):  # 50 clients that connect and say nothing
            socks.append(socket.create_connection(("127.0.0.1", view.port), timeout=5))
            most = max(most, threading.active_count() - before)
        # each is answered 503 at once (the server is full) or served, and then closed
        # after the idle timeout: none is left hanging
        answers = []
        for s in socks:
            s.settimeout(5.0)
            answers.append(s.recv(64))
            most = max(most, threading.active_count() - before)
            s.close()
        # the server's thread plus at most 4 serving threads, however many connect
        assert most <= 1 + 4
        assert all(a == b"" or a.startswith(b"HTTP/1.0 503") for a in answers)
        assert sum(a.startswith(b"HTTP/1.0 503") for a in answers) >= 10
        time.sleep(0.3)
        assert threading.active_count() - before <= 1
        # and it still serves
        with urllib.request.urlopen(view.url, timeout=5) as r:
            assert r.status == 200


@pytest.mark.slow
def test_close_ends_the_streams_and_frees_the_port() -> None:
    view = LiveView(port=0)
    view.update(np.zeros((8, 8, 3), dtype=np.uint8))
    r = urllib.request.urlopen(view.url + "stream", timeout=5)
    assert b"--frame" in r.read(64)
    t0 = time.perf_counter()
    view.close()
    rest = b""
    while chunk := r.read(4096):  # the stream ends: no frames after close()
        rest += chunk
        assert time.perf_counter() - t0 < 3.0
    r.close()
    assert time.perf_counter() - t0 < 3.0
    with socket.socket() as s:  # nothing listens there any more (as a restart would bind)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        s.bind(("127.0.0.1", view.port))


def _chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        if path := shutil.which(name):
            return path
    pytest.fail("no headless Chromium here: apt-get install chromium (.ci/run does)")


def test_a_browser_shows_the_performer_and_the_avatar(setup, tmp_path: Path) -> None:
    lib, layer, bank = setup
    with LiveView(port=0) as view:
        painter = LivePainter(view, lib.clips, layer.graph, bank)
        perform(
            VideoSource(RECORDING, silhouette=True),
            layer,
            bank,
            lib.clips,
            PerformSettings(match=MatchSettings(), seconds=3.0),
            on_frame=painter.on_frame,
            on_decision=painter.on_decision,
        )
        state = view.state()
        assert state["frame"] > 10 and state["action"] and state["cost"] is not None
        shot = tmp_path / "live.png"
        cmd = [
            _chromium(),
            "--headless=new",
            "--no-sandbox",
            "--disable-gpu",
            "--hide-scrollbars",
            f"--user-data-dir={tmp_path / 'profile'}",
            "--window-size=1200,800",
            "--virtual-time-budget=5000",
        ]
        # one browser run: the screenshot, and the page's DOM on stdout
        dom = subprocess.run(
            [*cmd, f"--screenshot={shot}", "--dump-dom", view.url],
            timeout=120,
            check=True,
            capture_output=True,
            text=True,
        ).stdout
    img = cv2.imread(str(shot))
    assert img is not None and img.shape[:2] == (800, 1200)
    # the picture spans 96% of the width: its left half holds the performer's white
    # silhouette, its right half the avatar's orange one on blue
    white = (img > 235).all(axis=2)
    orange = np.abs(img.astype(int) - (40, 150, 255)).sum(axis=2) < 60
    blue = np.abs(img.astype(int) - (70, 40, 20)).sum(axis=2) < 30
    assert white[:, :600].mean() > 0.01 and white[:, 600:].mean() < 0.002
    assert orange[:, 600:].mean() > 0.005 and orange[:, :600].mean() < 0.001
    assert blue[:, 600:].mean() > 0.2
    # the state line is filled in from /state.json
    assert f'<b id="a">{state["action"]}</b>' in dom
    assert '<b id="c">-</b>' not in dom and '<b id="l">-</b>' not in dom


@pytest.mark.slow
def test_perform_serves_the_live_view_while_it_runs(mocap: Path, tmp_path: Path) -> None:
    from mimic.cli import main

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    argv = [
        "perform",
        "--video",
        str(RECORDING),
        str(mocap),
        "--clips",
        "13_30",
        "--k",
        "12",
        "--realtime",
        "--seconds",
        "2",
        "--live-port",
        str(port),
    ]
    done: dict[str, int] = {}
    run = threading.Thread(target=lambda: done.update(rc=main(argv)))
    run.start()
    seen = None
    while run.is_alive() and seen is None:
        try:
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/state.json", timeout=2) as r:
                state = json.loads(r.read())
            if state["frame"] >= 0 and state["t"] > 0:
                seen = state
        except OSError:
            time.sleep(0.1)
    run.join(timeout=120)
    assert done.get("rc") == 0 and seen is not None and seen["t"] > 0
    with pytest.raises(OSError):  # closed with the run
        urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=2)
