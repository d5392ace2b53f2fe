"""Choice and sketch on the live page (``mimic play``): a click and a drawn path each
drive the avatar, in a real browser; bad commands are refused with a reason."""

from __future__ import annotations

import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from benchmarks._chromium import Chromium
from benchmarks._page import free_port
from control.graph import rotate_y
from vision import PlaySession, Stage

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_bad_commands_are_refused_and_good_ones_are_taken(setup: Any) -> None:
    lib, layer, _ = setup
    with Stage(port=0) as stage:
        session = PlaySession(stage, lib.clips, layer, seed=1)
        bad = [
            ({"type": "choose", "option": "1", "offer": 1}, "whole numbers"),
            ({"type": "sketch", "points": "here"}, "[x, z] pairs"),
            ({"type": "sketch", "points": [[0, 0]]}, "2 to 2000"),
            ({"type": "sketch", "points": [[0, 0], [0, 0.1]]}, "too short"),
            ({"type": "sketch", "points": [[0, 0], [float("nan"), 1]]}, "finite"),
            ({"type": "sketch", "points": [[0, 0], [1, 1]] * 1001}, "2 to 2000"),
            ({"type": "dance"}, "unknown command"),
        ]
        for message, why in bad:
            assert why in session.command(message)
        session.run(0.5)  # offers are made once the avatar is free
        assert session.offered and session.offer_id > 0
        assert session.command({"type": "choose", "option": 0, "offer": session.offer_id}) == ""
        stale = {"type": "choose", "option": 0, "offer": session.offer_id - 1}
        assert session.command(stale) == ""  # checked by the loop: the offer has gone
        session.run(0.2)
        assert [p["kind"] for p in session.performed] == ["choice"]
        # a path from where the avatar is, 2 m ahead of it to its right
        yaw, trans = session.avatar.root_transform()
        here = rotate_y(session.data.root[session.avatar.frame], float(yaw)) + trans
        ahead = [[here[0] + 0.5 * k, here[2] - 0.5 * k] for k in range(1, 5)]
        assert session.command({"type": "sketch", "points": ahead}) == ""
        session.run(0.2)
        assert [p["kind"] for p in session.performed] == ["choice", "sketch"]
        assert session.avatar.busy  # taking the planned path


@pytest.mark.slow
def test_a_click_and_a_drawn_path_drive_the_avatar_in_the_page(
    mocap: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from mimic.cli import main

    port = free_port()
    out = tmp_path / "play.bvh"
    # (the page has drawn its path about 5 s in)
    argv = ["play", str(mocap), "--clips", "13_30", "--k", "12", "--seconds", "10"]
    argv += ["--live-port", str(port), "--out", str(out)]
    done: dict[str, int] = {}
    run = threading.Thread(target=lambda: done.update(rc=main(argv)))
    run.start()
    try:
        with Chromium(f"http://127.0.0.1:{port}/", camera=False) as browser:
            browser.wait_for("window.mimic.offers > 0 && window.mimic.controls", 90)
            browser.evaluate("document.querySelector('#choices button').click()")
            time.sleep(1.0)
            # a drag across the floor in front of the avatar, as a mouse draws it
            x0, y0, w, h = browser.evaluate(
                "(() => { const r = document.querySelector('#stage3d canvas')"
                ".getBoundingClientRect(); return [r.left, r.top, r.width, r.height]; })()"
            )
            pts = [
                (x0 + w * (0.5 + 0.3 * k / 20), y0 + h * (0.8 - 0.1 * k / 20)) for k in range(21)
            ]
            browser.call("Input.dispatchMouseEvent", type="mouseMoved", x=pts[0][0], y=pts[0][1])
            browser.call(
                "Input.dispatchMouseEvent",
                type="mousePressed",
                x=pts[0][0],
                y=pts[0][1],
                button="left",
                buttons=1,
                clickCount=1,
            )
            for x, y in pts[1:]:
                browser.call("Input.dispatchMouseEvent", type="mouseMoved", x=x, y=y, buttons=1)
            browser.call(
                "Input.dispatchMouseEvent",
                type="mouseReleased",
                x=pts[-1][0],
                y=pts[-1][1],
                button="left",
                clickCount=1,
            )
            browser.wait_for("window.mimic.plans > 0", 30)
            run.join(timeout=60)
    finally:
        run.join(timeout=60)
    assert done.get("rc") == 0
    said = capsys.readouterr().out
    assert "1 actions chosen, 1 paths followed" in said
    check = REPO.parent / "shared" / "tools" / "check_bvh.py"
    subprocess.run([sys.executable, str(check), str(out)], check=True, capture_output=True)
