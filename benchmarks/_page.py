"""The live page end to end (``bench_vision --page``): a headless Chromium whose fake
camera plays a real clip is the camera of ``mimic perform --camera browser``, on the
default library with its defaults, as a performer's browser would be.

Per clip: the camera-frame-to-avatar-pose time the page measures on its own clock (from
when it had the frame to when the pose made after that frame arrived; p50, p99 over the
whole run), the frames a second it sent (the fake camera plays at the clip's rate; the
page sends at most two frames the loop has not answered), and, for a labelled clip, the
avatar's agreement with the labels beside ``mimic evaluate``'s on the file.
"""

from __future__ import annotations

import contextlib
import json
import socket
import tempfile
import threading
import time
import urllib.request
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from benchmarks._chromium import Chromium, write_y4m

SHARED_VIDEO = Path(__file__).resolve().parents[2] / "shared" / "video"
LABELS = Path(__file__).with_name("videos") / "shared_labels.csv"


def video_y4m(video: Path, out: Path, long_side: int = 640) -> tuple[float, float]:
    """``video`` as a ``.y4m`` of at most ``long_side`` pixels; (seconds, fps)."""
    cap = cv2.VideoCapture(str(video))
    fps = float(cap.get(cv2.CAP_PROP_FPS))
    frames: list[NDArray[np.uint8]] = []
    while (got := cap.read())[0]:
        img = got[1]
        s = min(1.0, long_side / max(img.shape[:2]))
        size = (round(img.shape[1] * s / 2) * 2, round(img.shape[0] * s / 2) * 2)
        frames.append(np.asarray(cv2.resize(img, size, interpolation=cv2.INTER_AREA), np.uint8))
    cap.release()
    write_y4m(frames, out, fps)
    return len(frames) / fps, fps


def free_port() -> int:
    """A port on 127.0.0.1 free now (for a run's page)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def page_state(port: int) -> dict[str, Any]:
    """The run's ``/state.json``."""
    with urllib.request.urlopen(f"http://127.0.0.1:{port}/state.json", timeout=2) as r:
        return dict(json.loads(r.read()))


def wait_for_reading(port: int, run: threading.Thread, timeout: float = 120.0) -> None:
    """Until the run (``run``, serving its page on ``port``) reads its page's camera, so
    that a page opened now gives it the clip's first frame."""
    t0 = time.monotonic()
    while True:
        if not run.is_alive() or time.monotonic() - t0 > timeout:
            raise RuntimeError(f"the run on port {port} did not start reading its page's camera")
        with contextlib.suppress(OSError):
            if page_state(port).get("camera") == "no page yet":
                return
        time.sleep(0.1)


def page_run(root: Path, video: Path, seconds: float | None = None) -> dict[str, Any]:
    """One run of ``mimic perform --camera browser`` fed ``video`` (module docstring)."""
    from control.motion import load_library
    from mimic.cli import main
    from vision import agreement, library_actions, truth_for

    with tempfile.TemporaryDirectory() as tmp:
        y4m = Path(tmp) / "camera.y4m"
        length, fps = video_y4m(video, y4m)
        seconds = seconds or length - 0.3
        port = free_port()
        log = Path(tmp) / "log.jsonl"
        argv = ["perform", "--camera", "browser", str(root), "--seconds", f"{seconds:.1f}"]
        argv += ["--live-port", str(port), "--log", str(log)]
        done: dict[str, int] = {}
        run = threading.Thread(target=lambda: done.update(rc=main(argv)))
        run.start()
        wait_for_reading(port, run)
        latencies: list[float] = []
        frames, sent_for = 0, 0.0
        with Chromium(f"http://127.0.0.1:{port}/", y4m) as browser:
            browser.wait_for("window.mimic.frames > 0", 60)
            t0 = time.monotonic()
            while run.is_alive():
                latencies = browser.evaluate("window.mimic.all")
                frames = browser.evaluate("window.mimic.frames")
                sent_for = time.monotonic() - t0
                time.sleep(0.5)
        run.join()
        decisions = [json.loads(line) for line in log.read_text().splitlines()]
    ms = np.array(latencies, dtype=float)
    out: dict[str, Any] = {
        "video": video.name,
        "clip_fps": fps,
        "seconds": seconds,
        "rc": done.get("rc"),
        "frames_sent": int(frames),
        "frames_per_second_sent": round(frames / max(sent_for, 1e-9), 2),
        "camera_to_avatar_ms_p50": round(float(np.percentile(ms, 50)), 1) if ms.size else None,
        "camera_to_avatar_ms_p99": round(float(np.percentile(ms, 99)), 1) if ms.size else None,
        "poses_measured": int(ms.size),
        "decisions": sum(d.get("decision") is not None for d in decisions),
        "decision_points": len(decisions),
    }
    labelled = video.name in LABELS.read_text() and seconds <= length  # (not looped)
    truth = truth_for(str(video), str(LABELS)) if labelled else None
    if truth is not None:
        clips = load_library(root, mirror="labelled").clips  # (perform's, for landmarks)
        got = agreement(decisions, clips, truth, known=library_actions(clips))
        out["agreement_best_lag_le_1s"] = got["best_at_lag_le_1s"]
        with tempfile.TemporaryDirectory() as tmp:  # the same clip as a file
            said = Path(tmp) / "evaluate.json"
            main(["evaluate", str(video), str(root), "--labels", str(LABELS), "--json", str(said)])
            out["file_agreement_best_lag_le_1s"] = json.loads(said.read_text())["best_at_lag_le_1s"]
    return out


def page(root: Path) -> dict[str, Any]:
    """The page on two real clips: squats (labelled, 5 frames/s) and pose_1 (30 frames/s,
    its 4 s looped by the fake camera for 15 s: the rate the page and loop sustain)."""
    return {
        "pose_squats": page_run(root, SHARED_VIDEO / "pose_squats.mp4"),
        "pose_1_looped": page_run(root, SHARED_VIDEO / "pose_1.mp4", seconds=15.0),
    }
