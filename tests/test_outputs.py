"""The fault suite of the outputs (issue 60): what ``mimic perform`` and ``mimic
evaluate`` write is checked before any work, never replaces an input or another output,
and is replaced as a set only when every file of it was written."""

from __future__ import annotations

import errno
import hashlib
import os
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import mimic.perform
from mimic.cli import main
from mimic.outputs import Output, OutputError, OutputSet
from tests.vision.conftest import RECORDING


def _sum(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture
def video(tmp_path: Path) -> Path:
    """A copy of the committed recording and its ground-truth sidecar."""
    copy = tmp_path / "in.mkv"
    shutil.copy(RECORDING, copy)
    shutil.copy(f"{RECORDING}.json", f"{copy}.json")
    return copy


def _perform(mocap: Path, video: Path, *more: str) -> int:
    # (--no-fuse: these tests are about what is written, not how the avatar is chosen, and
    # the pose model reading every silhouette for the landmarks' voice is most of a run)
    argv = ["perform", "--video", str(video), str(mocap), "--clips", "13_30", "--k", "12"]
    return main([*argv, "--seconds", "2", "--no-fuse", *more])


@pytest.mark.parametrize(
    ("option", "target"),
    [
        ("--out", "in.mkv"),
        ("--log", "in.mkv"),
        ("--video-out", "in.mkv"),
        ("--log", "in.mkv.json"),  # the ground truth beside the recording
        ("--out", "in.mkv.link"),  # a hard link to the input: the same file
    ],
)
def test_an_output_over_an_input_is_refused_before_any_work(
    mocap: Path,
    video: Path,
    option: str,
    target: str,
    capsys: pytest.CaptureFixture[str],
) -> None:
    folder = video.parent
    os.link(video, folder / "in.mkv.link")
    before = {p.name: _sum(p) for p in folder.iterdir()}
    assert _perform(mocap, video, option, str(folder / target)) == 2
    captured = capsys.readouterr()
    assert f"{option} {folder / target}: the same file as" in captured.err
    assert "an output never replaces an input" in captured.err
    assert "motion library" not in captured.err  # (nothing was loaded: said at once)
    assert {p.name: _sum(p) for p in folder.iterdir()} == before


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["--out", "same.x", "--log", "same.x"], "--log {d}/same.x: the same file as --out"),
        (["--out", "c.bvh", "--log", "c.bvh.json"], "the same file as --out's timing file"),
        (["--log", "a.mp4", "--video-out", "a.mp4"], "two outputs cannot share a file"),
    ],
)
def test_outputs_that_collide_are_refused_naming_both(
    mocap: Path, video: Path, argv: list[str], said: str, capsys: pytest.CaptureFixture[str]
) -> None:
    d = video.parent
    argv = [a if a.startswith("--") else str(d / a) for a in argv]
    assert _perform(mocap, video, *argv) == 2
    assert said.format(d=d) in capsys.readouterr().err
    assert sorted(p.name for p in d.iterdir()) == ["in.mkv", "in.mkv.json"]


@pytest.mark.slow
def test_an_unwritable_output_is_found_before_the_performance(
    mocap: Path, video: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert _perform(mocap, video, "--out", "/proc/x.bvh") == 2
    err = capsys.readouterr().err
    assert "--out /proc/x.bvh: cannot write in /proc" in err and ".tmp" not in err
    assert _perform(mocap, video, "--out", str(video.parent)) == 2
    assert f"--out {video.parent}: is a folder, not a file" in capsys.readouterr().err
    assert _perform(mocap, video, "--log", "/dev/null") == 2
    assert "--log /dev/null: is not a regular file" in capsys.readouterr().err
    # a folder that does not exist yet is made
    assert _perform(mocap, video, "--out", str(video.parent / "new" / "a.bvh")) == 0
    assert (video.parent / "new" / "a.bvh").stat().st_size > 0


def _old_set(folder: Path) -> dict[str, str]:
    for name in ("a.bvh", "a.bvh.json", "a.mp4", "a.jsonl"):
        (folder / name).write_text(f"the previous run's {name}\n")
    return {p.name: _sum(p) for p in folder.iterdir()}


@pytest.mark.gl
def test_a_video_that_fails_to_write_replaces_nothing(
    mocap: Path, video: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # OpenCV's writer drops frames without an error on a full disk: every other frame
    # is lost here, the file read back says so, and the previous set stays whole
    import cv2

    real = cv2.VideoWriter

    class Dropping:  # the MP4's writer only (not the run's own tape)
        fourcc = staticmethod(real.fourcc)

        def __init__(self, *args: Any) -> None:
            self.writer, self.n = real(*args), 0
            self.drop = str(args[0]).endswith(".mp4")

        def isOpened(self) -> bool:  # (OpenCV's name)
            return bool(self.writer.isOpened())

        def set(self, prop: int, value: float) -> bool:
            return bool(self.writer.set(prop, value))

        def write(self, img: np.ndarray) -> None:
            self.n += 1
            if self.n % 2 or not self.drop:
                self.writer.write(img)

        def release(self) -> None:
            self.writer.release()

    monkeypatch.setattr(cv2, "VideoWriter", Dropping)
    folder = video.parent
    before = _old_set(folder)
    out = [f"{o}={folder / n}" for o, n in (("--out", "a.bvh"), ("--video-out", "a.mp4"))]
    code = _perform(mocap, video, *out, "--log", str(folder / "a.jsonl"))
    captured = capsys.readouterr()
    assert code == 2, captured.err
    assert f"--video-out {folder / 'a.mp4'}: could not be written" in captured.err
    assert "nothing was replaced" in captured.err and "wrote" not in captured.out
    assert {p.name: _sum(p) for p in folder.iterdir()} == before  # no temporary file left


@pytest.mark.slow
def test_a_full_disk_names_the_file_and_keeps_the_previous_set(
    mocap: Path, video: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def full(*args: Any, **kwargs: Any) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(mimic.perform, "write_bvh", full)
    folder = video.parent
    before = _old_set(folder)
    code = _perform(mocap, video, "--out", str(folder / "a.bvh"), "--log", str(folder / "a.jsonl"))
    err = capsys.readouterr().err
    assert code == 2
    assert f"--out {folder / 'a.bvh'}: the disk is full: it needs more room than the" in err
    assert {p.name: _sum(p) for p in folder.iterdir()} == before  # the old log too


@pytest.mark.slow
def test_a_run_writes_its_set_and_says_only_what_it_wrote(
    mocap: Path, video: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = video.parent
    _old_set(folder)
    code = _perform(mocap, video, "--out", str(folder / "a.bvh"), "--log", str(folder / "a.jsonl"))
    out = capsys.readouterr().out
    assert code == 0
    assert f"wrote {folder / 'a.bvh'}\n" in out and f"wrote {folder / 'a.jsonl'}\n" in out
    assert "previous run" not in (folder / "a.jsonl").read_text()
    assert (folder / "a.mp4").read_text() == "the previous run's a.mp4\n"  # not asked for
    # a file that holds no video (a picture named .mp4): said as such, nothing written
    import cv2

    picture = folder / "p.mp4"
    assert cv2.imwrite(str(folder / "p.png"), np.full((40, 40, 3), 90, np.uint8))
    (folder / "p.png").rename(picture)
    code = _perform(mocap, picture, "--log", str(folder / "r.jsonl"))
    captured = capsys.readouterr()
    assert "wrote" not in captured.out and not (folder / "r.jsonl").exists()


@pytest.mark.slow
def test_a_source_that_gives_nothing_is_not_called_a_camera(
    mocap: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    masks = tmp_path / "masks"
    masks.mkdir()
    (masks / "0001.png").write_bytes(b"not a picture")
    argv = ["perform", "--masks", str(masks), str(mocap), "--clips", "13_30", "--k", "12"]
    assert main([*argv, "--log", str(tmp_path / "d.jsonl")]) == 2
    err = capsys.readouterr().err
    assert "no mask image in the folder could be read" in err and "camera" not in err


def test_the_set_checks_itself(tmp_path: Path) -> None:
    a = Output("--a", tmp_path / "x")
    with pytest.raises(OutputError, match=r"--b .*: the same file as --a"):
        OutputSet([a, Output("--b", tmp_path / "sub" / ".." / "x")])
    link = tmp_path / "link"
    link.symlink_to(tmp_path / "in")
    (tmp_path / "in").write_text("input")
    with pytest.raises(OutputError, match="the same file as --video"):
        OutputSet([Output("--out", link)], [("--video", tmp_path / "in")])
    with OutputSet([a]) as outputs:
        outputs.write(a, lambda p: p.write_text("new"))
        assert not a.path.exists()  # not before the commit
        assert outputs.commit() == [a]
    assert a.path.read_text() == "new" and sorted(os.listdir(tmp_path)) == ["in", "link", "x"]
    with pytest.raises(RuntimeError), OutputSet([a]) as outputs:
        outputs.write(a, lambda p: p.write_text("newer"))
        raise RuntimeError  # a failure before the commit: nothing replaced, nothing left
    assert a.path.read_text() == "new" and sorted(os.listdir(tmp_path)) == ["in", "link", "x"]


@pytest.mark.slow  # (it builds the library's graph, layer and bank first)
def test_a_stop_before_the_first_frame_says_stopped_and_writes_nothing(
    mocap: Path, video: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    class StoppedAtOnce(mimic.perform.StopOnSignal):  # Ctrl-C during the build
        def __call__(self) -> str:
            return "SIGINT"

    monkeypatch.setattr(mimic.perform, "StopOnSignal", StoppedAtOnce)
    folder = video.parent
    before = _old_set(folder)
    code = _perform(mocap, video, "--out", str(folder / "a.bvh"), "--log", str(folder / "a.jsonl"))
    captured = capsys.readouterr()
    assert code == 130
    assert "stopped by SIGINT before the first frame" in captured.err
    assert "camera" not in captured.err and "wrote" not in captured.out
    assert {p.name: _sum(p) for p in folder.iterdir()} == before


def test_a_full_disk_in_a_cache_write_names_the_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from control.artifacts import atomic_write

    target = tmp_path / "bank.npz"
    target.write_text("the old one")
    full = r"bank\.npz: the disk is full: writing it needs more room"
    with pytest.raises(OSError, match=full), atomic_write(target) as fh:
        fh.write("x")
        raise OSError(errno.ENOSPC, "No space left on device")
    assert target.read_text() == "the old one" and os.listdir(tmp_path) == ["bank.npz"]


def test_a_cache_that_is_a_file_is_said(
    mocap: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "cache").write_text("not a folder")
    monkeypatch.setenv("MIMIC_CACHE", str(tmp_path / "cache"))
    assert main(["graph", "build", str(mocap), "--clips", "13_30"]) == 2
    err = capsys.readouterr().err
    assert f"$MIMIC_CACHE={tmp_path / 'cache'}: is a file, not a folder" in err


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["graph", "walk", "--seconds", "2", "--out", "{d}"], "--out {d}: is a folder"),
        (["graph", "build", "--out", "/proc/g.npz"], "--out /proc/g.npz: cannot write in /proc"),
        (["chain", "02_01", "--out", "{d}/c.bvh", "--video", "{d}/c.bvh"], "two outputs"),
        (
            ["sketch", "--path", "{d}/p.json", "--out", "{d}/p.json"],
            "--out {d}/p.json: the same file as --path",
        ),
        (["choose", "--script", "{d}/p.json", "--out", "{d}/p.json"], "the same file as --script"),
        (["record", "13_29", "--out", "/proc/r.mkv"], "--out /proc/r.mkv: cannot write"),
        # a video's suffix picks its container: one that holds no such video is said first
        (["record", "13_29", "--out", "{d}/r.txt"], "--out {d}/r.txt: a video in FFV1 cannot"),
        (["chain", "02_01", "--out", "{d}/c.bvh", "--video", "{d}/c"], "a file without a suffix"),
        (
            ["sketch", "--path", "{d}/p.json", "--out", "{d}/s.bvh", "--video", "{d}/s.webm"],
            "ending '.webm'",
        ),
        (["perform", "--video", "{d}/p.json", "--video-out", "{d}/v.txt"], "name it .mp4"),
    ],
)
def test_every_command_checks_its_outputs_first(
    mocap: Path, tmp_path: Path, argv: list[str], said: str, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "p.json").write_text("the input")
    argv = [a.format(d=tmp_path) for a in argv]
    assert main([*argv, "--library", str(mocap)]) == 2
    err = capsys.readouterr().err
    assert said.format(d=tmp_path) in err and "motion library" not in err
    assert (tmp_path / "p.json").read_text() == "the input"
    assert sorted(os.listdir(tmp_path)) == ["p.json"]  # (no probe left behind)
