"""The choice interface on the playground, and `mimic choose`."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from control.avatar import Avatar
from control.choice import offer
from control.clusters import HigherLayer, LayerSettings, cached_higher_layer
from control.graph import FrameData, GraphOptions, MotionGraph, cached_graph
from control.motion import Library, read_bvh
from mimic.cli import main


@pytest.fixture(scope="module")
def playground(playground_lib: Library, prebuild) -> tuple[MotionGraph, HigherLayer, FrameData]:
    """The playground's graph and higher layer from the tests' cache: those `mimic choose
    --clips '01_*' --k 25` loads (tests/prebuild.py builds them in the background)."""
    prebuild.wait("playground")
    g, _, _ = cached_graph(playground_lib.clips, GraphOptions())
    layer, _, _ = cached_higher_layer(g, playground_lib.clips, LayerSettings(k=25))
    return g, layer, FrameData(g, playground_lib.clips)


def test_options_are_dispersed_valid_and_performed(playground, playground_lib: Library) -> None:
    g, layer, data = playground
    frames = np.random.default_rng(5).choice(np.flatnonzero(g.in_scc), 25, replace=False)
    counts = []
    for f in frames:
        avatar = Avatar(g, playground_lib.clips, start=int(f))
        options = offer(layer, avatar, data, n=4, lookahead=(0.0, 6.0))
        counts.append(len(options))
        assert 1 <= len(options) <= 4
        assert len({o.cluster for o in options}) == len(options)
        for o in options:
            assert o.frames[0] == f and o.key_frame == o.frames[-1]
            assert layer.labels[o.key_frame] == o.cluster
            assert o.seconds <= 6.0 + 1e-9
            np.testing.assert_allclose(o.root_path[0], data.root[f])  # fixed coordinates
            assert o.root_path.shape == (o.frames.size, 3)
        o = options[-1]
        avatar.take(o.frames, o.edges)
        while avatar.busy:
            avatar.step()
        assert avatar.frame == o.key_frame and layer.labels[avatar.frame] == o.cluster
    assert np.mean(counts) > 2.5


def test_region_limits_the_options(playground, playground_lib: Library) -> None:
    g, layer, data = playground
    f = int(np.flatnonzero(g.in_scc)[100])
    avatar = Avatar(g, playground_lib.clips, start=f)
    here = data.root[f]
    near = offer(layer, avatar, data, region=(float(here[0]), float(here[2]), 1.0))
    assert all(np.hypot(*(o.root_path[-1] - here)[[0, 2]]) <= 1.0 for o in near)
    assert offer(layer, avatar, data, region=(here[0] + 100.0, here[2], 1.0)) == []


@pytest.mark.slow
def test_scripted_two_minute_session(
    mocap: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    script = tmp_path / "choices.txt"
    script.write_text("# pick, wait, pick ...\n1\n2\nwait 3\n1\n" + "2\n1\n" * 12)
    out = tmp_path / "choose.bvh"
    argv = ["choose", str(mocap), "--clips", "01_*", "--k", "25", "--seconds", "120"]
    assert main([*argv, "--script", str(script), "--out", str(out), "--lookahead", "0"]) == 0
    text = capsys.readouterr().out
    assert "[1]" in text and "reached cluster" in text and "did not reach" not in text
    motion = read_bvh(out)
    assert motion.n_frames >= 120 * 15
    bad = tmp_path / "bad.txt"
    bad.write_text("1\nleft\n")
    assert main([*argv, "--script", str(bad), "--out", str(tmp_path / "x.bvh")]) == 2
    assert "bad.txt:2" in capsys.readouterr().err
