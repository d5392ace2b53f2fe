"""Block terrain: the grid under the captured feet, terrain environments, and the eq. 8
tracker keeping planted feet on blocks of the right level."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from control.graph import (
    BlendSettings,
    GraphOptions,
    build_graph,
    captured_terrain,
    compose,
    foot_track,
    rotate_y,
    terrain_options,
)
from control.motion import Clip, Motion, load_library, read_bvh
from control.sketch import (
    SketchFileError,
    SketchSettings,
    SketchTracker,
    environment_mesh,
    read_environment,
    read_sketch,
)
from mimic.cli import main
from tests.conftest import REPO

TERRAIN = REPO / "benchmarks" / "sketch" / "terrain.json"
TERRAIN_PATH = REPO / "benchmarks" / "sketch" / "terrain_path.json"


@pytest.fixture(scope="module")
def blocks(mocap: Path, tmp_path_factory: pytest.TempPathFactory):
    lib = load_library(mocap, clips=["03_*"], cache_dir=tmp_path_factory.mktemp("c"))
    env = read_environment(TERRAIN)
    assert env.terrain is not None
    options, cap = terrain_options(lib.clips, env.terrain.block)
    return lib, build_graph(lib.clips, options), cap, env


def _shifted(clip: Clip, shift: np.ndarray) -> Clip:
    m = clip.motion
    moved = Motion(m.skeleton, m.root_pos + shift, m.quats, m.fps, m.name, m.source)
    return dataclasses.replace(clip, motion=moved)


def test_captured_terrain_finds_three_levels_and_the_grid(blocks) -> None:
    lib, _, cap, _ = blocks
    # three levels one block apart (the capture's blocks are 0.13-0.19 m high)
    assert len(cap.levels) == 3 and np.all(np.diff(cap.levels) > 0.1)
    assert 0.12 < cap.rise < 0.19
    # planted feet gather at block centres: far from uniform on both axes
    assert min(cap.coherence) > 0.35
    # moving the clips moves the grid with them (modulo a block)
    shift = np.array([0.2, 0.0, -0.1])
    moved = captured_terrain([_shifted(c, shift) for c in lib.clips], cap.block)
    d = (np.array(moved.origin) - np.array(cap.origin) - shift[[0, 2]]) / cap.block
    np.testing.assert_allclose(d, np.round(d), atol=1e-6)
    np.testing.assert_allclose(moved.levels, cap.levels, atol=1e-9)
    with pytest.raises(ValueError, match="too few planted feet"):
        captured_terrain([lib.clips[0]], n_levels=20)


def test_terrain_environment_file_and_levels(tmp_path: Path) -> None:
    env = read_environment(TERRAIN)
    t = env.terrain
    assert env.kind == "terrain" and t is not None and t.levels.shape == (13, 8)
    pts = np.random.default_rng(0).uniform(-4, 8, size=(500, 2))
    got = t.level_at(pts)
    assert got.tolist() == [t.level_at_point(x, z) for x, z in pts]
    assert t.level_at(np.array([[-100.0, 0.0]]))[0] == 0  # outside the grid: the ground
    x0, z0 = t.corner
    assert t.level_at(np.array([[x0 + 3.5 * t.block, z0 + 3.5 * t.block]]))[0] == t.levels[3, 3]
    # the blocks as a mesh for videos: one box per raised block, as high as its level
    verts, faces = environment_mesh(env, rise=0.15)
    heights = np.unique(np.round(verts[:, 1], 6))
    assert heights.tolist() == [0.0, 0.15, 0.3, 0.45]
    assert len(verts) == 8 * int((t.levels > 0).sum()) and faces.max() < len(verts)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"kind": "terrain", "block": 0.6, "corner": [0, 0]}, "a terrain needs 'levels'"),
        ({"kind": "terrain", "block": 0, "corner": [0, 0], "levels": [[0]]}, "'block' must be"),
        (
            {"kind": "terrain", "block": 0.6, "corner": [0, 0], "levels": [[0, 1], [1]]},
            "levels row 1: 1 blocks, but row 0 has 2",
        ),
        (
            {"kind": "terrain", "block": 0.6, "corner": [0, 0], "levels": [[0, 1.5]]},
            "levels row 0 block 1: expected a whole number",
        ),
        ({"kind": "maze", "levels": [[0]]}, "unknown keys levels"),
    ],
)
def test_bad_terrains_are_named(tmp_path: Path, data: dict, message: str) -> None:
    p = tmp_path / "t.json"
    p.write_text(json.dumps(data))
    with pytest.raises(SketchFileError, match=f"t.json: {message}"):
        read_environment(p)


def _placed_feet(t: SketchTracker) -> tuple[np.ndarray, np.ndarray]:
    """Toe ``(T, 2, 3)`` and support ``(T, 2, 2)`` of the planned frames as placed (no
    blending), from first principles: the start map and each transition's alignment."""
    yaw, trans = t._start
    jumps = dict(zip(t.jumps, t.edges, strict=True))
    toes, support = [], []
    for i, f in enumerate(t.frames):
        if i in jumps:
            al = t.graph.align[jumps[i]].astype(np.float64)
            yaw, trans = compose(yaw, trans, float(al[0]), al[1:])
        toes.append(rotate_y(t.blocks.toe[f], yaw) + trans)
        s = np.zeros((2, 3))
        s[:, [0, 2]] = t.blocks.support[f]
        support.append((rotate_y(s, yaw) + trans)[:, [0, 2]])
    return np.array(toes), np.array(support)


def test_tracker_keeps_planted_feet_on_blocks(blocks) -> None:
    lib, g, cap, env = blocks
    sketch = read_sketch(TERRAIN_PATH)
    t = SketchTracker(g, lib.clips, sketch, env, SketchSettings(), captured=cap)
    t.run(40.0)
    assert t.goal >= len(t.goals) and not t.stuck
    toe, support = _placed_feet(t)
    states = t.blocks.states[np.array(t.frames)]
    levels = env.terrain.level_at(support.reshape(-1, 2)).reshape(-1, 2)
    # every planted foot of the plan stands on a block top: its height above the captured
    # ground matches the block's level to a fraction of a block (the captured levels are
    # not exactly evenly spaced, and a toe is not always flat)
    err = np.abs(toe[..., 1] - cap.toe_floor - levels * t.blocks.rise)[states]
    assert err.max() < 0.6 * t.blocks.rise and np.percentile(err, 95) < 0.4 * t.blocks.rise
    # and the synthesized motion keeps them there at most planted frames
    report = t.terrain_report(t.motion())
    assert report["planted_off_block"] <= 0.1 * report["planted_frames"]
    assert report["foot_height_error_mean_m"] < 0.05


def test_tracker_needs_a_matching_terrain_graph(blocks) -> None:
    lib, g, _, env = blocks
    sketch = read_sketch(TERRAIN_PATH)
    flat = build_graph(lib.clips, GraphOptions(coords="relative"))
    with pytest.raises(ValueError, match="needs a terrain graph"):
        SketchTracker(flat, lib.clips, sketch, env)
    other = build_graph(lib.clips, dataclasses.replace(g.options, block=0.5))
    with pytest.raises(ValueError, match=r"blocks are 0\.6096 m but the graph's are 0\.5 m"):
        SketchTracker(other, lib.clips, sketch, env)
    with pytest.raises(ValueError, match="mirrored"):
        terrain_options([dataclasses.replace(c, mirrored=True) for c in lib.clips])
    assert foot_track(lib.clips).states.shape == (g.n_frames, 2)


@pytest.mark.slow  # (a whole command)
def test_cli_sketch_on_terrain(mocap: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "t.bvh"
    argv = ["sketch", str(mocap), "--path", str(TERRAIN_PATH), "--env", str(TERRAIN)]
    assert main([*argv, "--out", str(out)]) == 2
    assert "pass --clips" in capsys.readouterr().err
    assert main([*argv, "--clips", "03_*", "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    terrain = summary["eq. 8"]["terrain"]
    assert summary["eq. 8"]["followed"] and terrain["planted_frames"] > 50
    assert "min_clearance_m" not in summary["eq. 8"]  # no obstacles: nothing to report
    assert read_bvh(out).n_frames > 50


def test_synthesis_anchor_is_checked() -> None:
    with pytest.raises(ValueError, match="anchor must be 'output' or 'source'"):
        BlendSettings(anchor="x")
