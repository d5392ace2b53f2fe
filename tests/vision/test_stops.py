"""A stop keeps what was done: signals to mimic perform and graph walk, the decision log."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from control.motion import read_bvh
from mimic.cli import main
from tests.conftest import REPO
from tests.vision.conftest import RECORDING

MIMIC = [sys.executable, "-m", "mimic"]


def _start(argv: list[str]) -> subprocess.Popen[str]:
    env = dict(os.environ)  # the tests' shared cache (conftest.session_cache)
    return subprocess.Popen(
        [*MIMIC, *argv],
        cwd=REPO,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _wait_for(path: Path, proc: subprocess.Popen[str], lines: int, timeout: float = 240) -> None:
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        tmp = list(path.parent.glob(f".{path.name}.*.tmp*"))
        if tmp and tmp[0].read_text().count("\n") >= lines:
            return
        if proc.poll() is not None:
            pytest.fail(f"mimic ended early: {proc.communicate()}")
        time.sleep(0.2)
    pytest.fail("no decisions logged in time")


@pytest.mark.slow
def test_a_stopped_perform_writes_what_was_performed(mocap: Path, tmp_path: Path) -> None:
    """SIGTERM (exit 143) and Ctrl-C (SIGINT, exit 0), each to its own run: both runs go
    side by side (they pace themselves to the media's clock)."""
    runs = []
    for sig, rc in [(signal.SIGTERM, 143), (signal.SIGINT, 0)]:
        folder = tmp_path / sig.name
        folder.mkdir()
        out, log = folder / "a.bvh", folder / "d.jsonl"
        log.write_text("an old log\n")
        argv = ["perform", "--video", str(RECORDING), str(mocap), "--clips", "13_30"]
        argv += ["--k", "12", "--realtime", "--live-port", "0", "--no-fuse"]  # (a stop's test)
        runs.append((sig, rc, out, log, _start([*argv, "--out", str(out), "--log", str(log)])))
    for sig, _, _, log, proc in runs:
        _wait_for(log, proc, 10)  # a second of decisions
        proc.send_signal(sig)
    for sig, rc, out, log, proc in runs:
        _, stderr = proc.communicate(timeout=120)
        assert proc.returncode == rc, stderr
        assert f"stopped by {sig.name}" in stderr
        lines = [json.loads(x) for x in log.read_text().splitlines()]
        assert len(lines) >= 10 and lines[-1]["t"] < 11.0  # stopped well before the end
        motion = read_bvh(out)
        # the BVH holds what was performed, from the avatar's start (where the performer
        # was first located) up to the stop
        start = next(x["t"] for x in lines if "located" in x)
        assert motion.n_frames >= 0.9 * (lines[-1]["t"] - start) * 15
        assert not list(out.parent.glob(".*.tmp*"))


def test_a_failed_start_keeps_the_old_log(mocap: Path, tmp_path: Path) -> None:
    log = tmp_path / "d.jsonl"
    log.write_text("an old log\n")
    argv = ["perform", "--video", str(RECORDING), str(mocap), "--clips", "99_*"]
    assert main([*argv, "--log", str(log)]) == 2
    assert log.read_text() == "an old log\n" and not list(tmp_path.glob(".*.tmp*"))


@pytest.mark.slow
def test_sigterm_during_graph_walk_leaves_no_temporary_file(mocap: Path, tmp_path: Path) -> None:
    out = tmp_path / "walk.bvh"
    argv = [
        "graph",
        "walk",
        str(mocap),
        "--clips",
        "13_30",
        "--seconds",
        "1800",  # half an hour: over a second of writing (here) to catch it in
        "--out",
        str(out),
    ]
    proc = _start(argv)
    t0 = time.monotonic()
    while not list(tmp_path.glob(".walk.bvh.*")) and time.monotonic() - t0 < 240:
        if proc.poll() is not None:
            pytest.fail(f"walk ended early: {proc.communicate()}")
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    proc.communicate(timeout=60)
    assert proc.returncode == 143
    assert not list(tmp_path.glob(".walk.bvh.*")) and not out.exists()
