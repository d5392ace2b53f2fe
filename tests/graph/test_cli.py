"""`mimic graph build` and `mimic graph walk` end to end on real clips."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from control.graph import load_graph
from control.motion import read_bvh
from mimic.cli import main
from tests.conftest import REPO
from vision import RecordSettings


@pytest.mark.slow  # (a whole command)
def test_build_prints_table_and_writes_graph(
    mocap: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "g.npz"
    args = ["graph", "build", str(mocap), "--clips", "02_0[1-4]", "--out", str(out)]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "likelihood" in text and "similarity" in text and "SCC" in text
    assert "built in" in text
    assert main([*args, "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["built"] is False  # the second run comes from the cache
    assert report["frames"] == 164 and report["possible"] == 164**2
    assert load_graph(out).n_edges == report["scc"]
    assert main(["graph", "build", str(mocap), "--clips", "02_0[1-4]", "--contact", "strict"]) == 0
    assert "N/A" in capsys.readouterr().out


@pytest.mark.slow
def test_walk_writes_a_bvh_that_other_tools_read(
    mocap: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "walk.bvh"
    common = [str(mocap), "--clips", "02_*", "--clips", "03_*", "--coords", "relative"]
    argv = ["graph", "walk", *common, "--seconds", "20", "--out", str(out), "--quality"]
    assert main([*argv, "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["frames"] == 300 and summary["transitions"] > 0
    assert summary["quality"]["walk"]["foot_slide_mean"] > 0
    motion = read_bvh(out)
    assert motion.n_frames == 300 and motion.fps == 15
    check = subprocess.run(
        [sys.executable, str(REPO.parent / "shared" / "tools" / "check_bvh.py"), str(out)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert check.returncode == 0, check.stdout + check.stderr


def test_walk_bad_arguments_are_clear_errors(
    mocap: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = ["graph", "walk", str(mocap), "--clips", "02_0[1-4]", "--out", str(tmp_path / "w.bvh")]
    assert main([*base, "--seconds", "5", "--start", "02_01"]) == 2
    assert "CLIP:FRAME" in capsys.readouterr().err
    assert main([*base, "--seconds", "5", "--start", "02_01:999"]) == 2
    assert "no frame 999" in capsys.readouterr().err
    assert main([*base, "--seconds", "0"]) == 2
    assert "--seconds" in capsys.readouterr().err
    assert main(["graph", "build", str(mocap), "--clips", "zz_*"]) == 2
    assert "no clip matches zz_*" in capsys.readouterr().err
    assert not (tmp_path / "w.bvh").exists()


def test_blend_reaches_the_avatar_and_leaves_the_graph_alone() -> None:
    from mimic.args import blend_seconds, graph_options
    from mimic.cli import build_parser

    parse = build_parser().parse_args
    plain = parse(["graph", "build"])
    half = parse(["graph", "build", "--blend", "0.5"])
    # the graph (and so its cache key) does not depend on the blend unless pruning reads it
    assert graph_options(plain) == graph_options(half)
    assert blend_seconds(plain) == 1.0 and blend_seconds(half) == 0.5
    pruned = parse(["graph", "build", "--case4", "prune", "--blend", "0.5"])
    assert graph_options(pruned).blend == 0.5
    with pytest.raises(SystemExit):  # argparse refuses it, naming --blend
        parse(["graph", "build", "--blend", "-1"])


def test_the_library_folder_is_given_the_same_way_everywhere(tmp_path: Path) -> None:
    from mimic.args import library_dir
    from mimic.cli import build_parser

    parse = build_parser().parse_args
    for argv in (
        ["library", "info"],
        ["graph", "build"],
        ["graph", "walk", "--seconds", "1", "--out", "w.bvh"],
        ["choose", "--out", "c.bvh"],
        ["perform", "--video", "v.mkv"],
        ["evaluate", "v.mkv", "--json", "r.json"],
        ["record", "13_29", "--out", "r.mkv"],
        ["chain", "02_01", "--out", "c.bvh"],
        ["sketch", "--path", "p.json", "--out", "s.bvh"],
        ["bank", "build"],
    ):
        assert library_dir(parse([*argv, "--library", str(tmp_path)])) == str(tmp_path), argv
    assert library_dir(parse(["graph", "build", str(tmp_path)])) == str(tmp_path)
    with pytest.raises(ValueError, match="two library folders"):
        library_dir(parse(["graph", "build", str(tmp_path), "--library", "/elsewhere"]))


def test_record_films_a_performer_of_other_proportions(
    mocap: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "r.mkv"
    base = ["record", "13_29", str(mocap), "--to", "0.4", "--fps", "15", "--size", "80x60"]
    assert main([*base, "--legs", "1.1", "--arms", "0.9", "--out", str(out)]) == 0
    side = json.loads(Path(f"{out}.json").read_text())
    body = side["settings"]["body"]
    assert (body["legs"], body["arms"]) == (1.1, 0.9) and len(side["frames"]) == 6
    assert "wrote" in capsys.readouterr().out
    assert main([*base, "--legs", "3", "--out", str(tmp_path / "bad.mkv")]) == 2
    assert "argument --legs: must be a number from 0.5 to 2" in capsys.readouterr().err
    assert not (tmp_path / "bad.mkv").exists()


@pytest.mark.gl
def test_record_films_a_colour_performer_for_a_pose_model(
    mocap: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # the shaded body on a plain background, for a pose model; the camera going round
    # the performer as it films
    base = ["record", "13_29", str(mocap), "--to", "0.4", "--fps", "15", "--size", "80x60"]
    colour = tmp_path / "c.mkv"
    assert main([*base, "--colour", "--turn", "90", "--out", str(colour)]) == 0
    side = json.loads(Path(f"{colour}.json").read_text())
    assert side["settings"]["colour"] and side["settings"]["turn"] == 90.0
    cap = cv2.VideoCapture(str(colour))
    ok, img = cap.read()
    cap.release()
    assert ok and img.shape == (60, 80, 3)
    background = np.array(RecordSettings().background)
    body = np.abs(img.astype(int) - background).sum(axis=2) > 30
    assert 0.02 < body.mean() < 0.5  # a performer, lit and shaded: not one grey
    assert len({tuple(px) for px in img[body][::5]}) > 10
    # a turn or an azimuth that is not a number is said, and nothing is written
    bad = tmp_path / "bad.mkv"
    assert main([*base, "--colour", "--turn", "nan", "--out", str(bad)]) == 2
    assert "argument --turn: must be a number from" in capsys.readouterr().err
    assert main([*base, "--azimuth", "inf", "--out", str(bad)]) == 2
    assert "argument --azimuth: must be a number from" in capsys.readouterr().err
    assert not bad.exists()
