"""Chaining named actions on the exercise and subject-02 clips."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from control.graph import joint_jumps
from control.motion import load_library, read_bvh
from control.transition._chain import Chainer
from control.transition._tgraph import CandidatePaths
from mimic.cli import main
from tests.conftest import REPO


def test_actions_by_clip_range_and_label(chainer: Chainer) -> None:
    a = chainer.action("02_01")
    assert (
        a.stop - a.start
        == chainer.clips[[c.name for c in chainer.clips].index("02_01")].motion.n_frames
    )
    r = chainer.action("13_29:1.0-2.0")
    assert r.stop - r.start == 15
    lab = chainer.action("label:squat")
    clip = next(c for c in chainer.clips if "Squat" in c.label_names)
    start = lab.start - chainer.feat.clip_start[chainer.clips.index(clip)]
    assert clip.label_at(int(start)) == "Squat"
    for bad in ("zz_01", "13_29:5-1", "label:Cartwheel", "13_29:0-999"):
        with pytest.raises(ValueError):
            chainer.action(bad)


def test_chain_and_reverse_play_every_action_smoothly(chainer: Chainer) -> None:
    order = ["label:JumpJack", "label:Squat", "02_05", "02_01"]
    for actions in (order, order[::-1]):
        r = chainer.chain(actions)
        assert [p[0] for p in r.pieces if p[0] != "bezier"] == [
            a.split(":")[-1] if a.startswith("label:") else a for a in actions
        ]
        assert r.motion.n_frames == r.sources.size
        # the last frames of the result are the last action itself
        last = chainer.action(actions[-1])
        assert r.sources[-1] == last.stop - 1
        assert joint_jumps(r.motion).max() < 60.0


def test_undirected_graph_plays_clips_backwards(chainer: Chainer) -> None:
    both = Chainer(chainer.clips, seed=1, directed=False)
    assert (
        both.graph.clip_backward.any() and both.paths.pairs.shape[0] >= chainer.paths.pairs.shape[0]
    )
    r = both.chain(["label:Squat", "label:JumpJack", "02_01"])
    assert joint_jumps(r.motion).max() < 60.0


def test_bezier_fallback_when_no_path(chainer: Chainer) -> None:
    empty = CandidatePaths(
        n_nodes=chainer.paths.n_nodes,
        pairs=np.zeros((0, 2), dtype=np.int64),
        first=np.zeros(1, dtype=np.int64),
        cost=np.zeros(0),
        offsets=np.zeros(1, dtype=np.int64),
        nodes=np.zeros(0, dtype=np.int64),
        k=5,
        max_cost=0.0,
    )
    saved = chainer.paths
    try:
        chainer.paths = empty
        r = chainer.chain(["label:JumpJack", "label:Squat"])
    finally:
        chainer.paths = saved
    assert r.bezier == 1 and ("bezier", int(np.argmax(r.sources < 0))) in r.pieces
    inter = np.flatnonzero(r.sources < 0)
    assert inter.size >= 1 and np.all(np.diff(inter) == 1)
    assert joint_jumps(r.motion).max() < 60.0
    assert dataclasses.is_dataclass(r)


@pytest.mark.slow  # (a whole command)
def test_cli_chain_writes_a_bvh_others_read(mocap: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "chain.bvh"
    argv = [
        "chain",
        "label:JumpJack",
        "label:Squat",
        "02_01",
        "--library",
        str(mocap),
        "--clips",
        "13_30",
        "--clips",
        "02_01",
        "--out",
        str(out),
    ]
    assert main(argv) == 0
    assert "label:JumpJack" in capsys.readouterr().out or out.exists()
    assert read_bvh(out).n_frames > 30
    check = subprocess.run(
        [sys.executable, str(REPO.parent / "shared" / "tools" / "check_bvh.py"), str(out)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert check.returncode == 0, check.stderr
    assert (
        main(
            [
                "chain",
                "nothing_like_this",
                "--library",
                str(mocap),
                "--clips",
                "02_01",
                "--out",
                str(out),
            ]
        )
        == 2
    )
    assert "unknown action" in capsys.readouterr().err


@pytest.mark.slow
def test_player_frame_by_frame_equals_the_batch_chain(mocap: Path, tmp_path_factory) -> None:
    from control.transition._chain import ChainPlayer

    lib = load_library(
        mocap, clips=["13_29", "13_30", "02_0*"], cache_dir=tmp_path_factory.mktemp("c")
    )
    order = ["label:JumpJack", "label:Squat", "02_05"]
    batch = Chainer(lib.clips, seed=4).chain(order)
    player = ChainPlayer(Chainer(lib.clips, seed=4))
    for a in order:
        player.request(a)
    got = [player.next() for _ in range(batch.motion.n_frames)]
    assert player.idle
    np.testing.assert_allclose(np.array([g[0] for g in got]), batch.motion.root_pos, atol=1e-9)
    np.testing.assert_allclose(np.array([g[1] for g in got]), batch.motion.quats, atol=1e-9)
    assert [g[2] for g in got] == batch.sources.tolist()
    assert player.next()[2] == got[-1][2]  # idle: holds the last pose


def test_interrupting_turns_towards_the_new_action(chainer: Chainer) -> None:
    from control.transition._chain import ChainPlayer

    player = ChainPlayer(chainer)
    player.request("label:JumpJack")
    player.request("label:Squat")
    frames = [player.next() for _ in range(10)]
    dodge = chainer.action("02_05")
    player.request(dodge, interrupt=True)  # the queued squat is dropped
    after = [player.next() for _ in range(400)]
    srcs = [s for _, _, s in after]
    assert any(dodge.start <= s < dodge.stop for s in srcs)
    squat = chainer.action("label:Squat")
    assert not any(squat.start <= s < squat.stop for s in srcs[-50:])
    q = np.array([f[1] for f in frames + after])
    from control.motion import qconj, qlog, qmul

    steps = np.degrees(np.linalg.norm(qlog(qmul(qconj(q[:-1]), q[1:])), axis=-1)).max()
    assert steps < 60.0
    with pytest.raises(ValueError, match="nothing requested"):
        ChainPlayer(chainer).next()
