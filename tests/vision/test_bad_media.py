"""Bad media: nothing matched against garbage, nothing used silently."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from control.motion import read_bvh
from mimic.cli import main
from tests.vision.conftest import RECORDING
from vision import MaskFolderSource, PerformSettings, VideoSource, looks_like_silhouettes, perform


def _video(path: Path, frames: list[np.ndarray], fps: float = 30.0) -> Path:
    h, w = frames[0].shape[:2]
    out = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"FFV1"), fps, (w, h))
    for f in frames:
        out.write(f)
    out.release()
    return path


def test_a_colour_video_that_starts_black_is_not_taken_for_silhouettes(
    tmp_path: Path, rng: np.random.Generator
) -> None:
    black = [np.zeros((60, 80, 3), np.uint8)] * 5
    colour = [rng.integers(0, 256, (60, 80, 3), dtype=np.uint8) for _ in range(5)]
    assert not looks_like_silhouettes(_video(tmp_path / "c.mkv", black + colour))
    assert not looks_like_silhouettes(_video(tmp_path / "b.mkv", black))  # no evidence: colour
    assert looks_like_silhouettes(RECORDING)
    # and the user can say so
    from mimic.cli import build_parser
    from mimic.run_args import silhouette_flag

    for word, meant in (("yes", True), ("no", False), ("auto", None)):
        args = build_parser().parse_args(
            ["perform", "--video", "c.mkv", "--silhouette-video", word]
        )
        assert silhouette_flag(args) is meant


def test_white_frames_are_no_performer(setup, tmp_path: Path) -> None:
    lib, layer, bank = setup
    for i in range(45):
        cv2.imwrite(str(tmp_path / f"{i:03d}.png"), np.full((120, 160), 255, np.uint8))
    r = perform(MaskFolderSource(tmp_path), layer, bank, lib.clips, PerformSettings())
    assert r.decisions and all(d.get("decision") is None for d in r.decisions)
    assert {d["reason"] for d in r.decisions} == {"the mask covers 100% of the frame"}


@pytest.mark.slow  # (mimic perform builds the library's graph, layer and bank first)
def test_a_truncated_video_is_said(mocap: Path, tmp_path: Path, capsys) -> None:
    cut = tmp_path / "cut.mkv"
    cut.write_bytes(RECORDING.read_bytes()[:60_000])
    v = VideoSource(cut)
    while v.read() is not None:
        pass
    assert "cut.mkv: the video ended after" in v.truncated()
    assert "of the 360 frames" in v.truncated()
    whole = VideoSource(RECORDING)
    while whole.read() is not None:
        pass
    assert whole.truncated() == ""
    early = VideoSource(cut)  # stopped before its end (--seconds, a stop): nothing to say
    for _ in range(5):
        early.read()
    assert early.truncated() == ""
    # (--no-fuse: the pose model reading every silhouette, for the landmarks' voice, is
    # most of a run, and these tests are about what is said of the media)
    argv = ["perform", "--video", str(cut), str(mocap), "--clips", "13_30", "--k", "12"]
    argv += ["--no-fuse"]
    assert main(argv) == 0
    assert "warning: " in capsys.readouterr().err
    assert main([*argv, "--seconds", "1"]) == 0
    assert "warning: " not in capsys.readouterr().err


def test_a_late_start_says_where_the_avatar_begins(
    setup, mocap: Path, tmp_path: Path, capsys
) -> None:
    # two seconds of nobody (black), then the recording
    src = cv2.VideoCapture(str(RECORDING))
    frames = [np.zeros((120, 160, 3), np.uint8)] * 60
    while (got := src.read())[0]:
        frames.append(got[1])
    late = _video(tmp_path / "late.mkv", frames)
    log, out = tmp_path / "d.jsonl", tmp_path / "a.bvh"
    argv = ["perform", "--video", str(late), str(mocap), "--clips", "13_30", "--k", "12"]
    assert main([*argv, "--no-fuse", "--seconds", "6", "--log", str(log), "--out", str(out)]) == 0
    said = capsys.readouterr().out
    lines = [json.loads(x) for x in log.read_text().splitlines()]
    start = next(x["t"] for x in lines if "located" in x)
    assert start >= 2.0 and f"starts at {start:.2f} s of media" in said
    # the BVH's place in the input is written beside it (a BVH has no field for it)
    timing = json.loads((tmp_path / "a.bvh.json").read_text())
    assert timing["media_start_s"] == pytest.approx(start, abs=1e-3)
    assert timing["frames"] == read_bvh(out).n_frames
    assert timing["media_end_s"] == pytest.approx(6.0, abs=0.2)
