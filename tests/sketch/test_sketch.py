"""The sketch interface: files, clearance, the eq. 8 tracker and ``mimic sketch``."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from matplotlib.path import Path as MplPath
from scipy.spatial import cKDTree

from control.clusters import LayerSettings, cached_higher_layer
from control.graph import GraphOptions, build_graph
from control.motion import Library, load_library, read_bvh
from control.sketch import (
    Environment,
    SketchFileError,
    SketchSettings,
    SketchTracker,
    path_deviation,
    read_environment,
    read_sketch,
)
from control.sketch._ground import resample_polyline
from mimic.cli import main
from tests.conftest import REPO

MAZE = REPO / "benchmarks" / "sketch" / "maze.json"
MAZE_PATH = REPO / "benchmarks" / "sketch" / "maze_path.json"
WALKS = ["02_01", "02_02", "02_03", "03_01", "03_02", "03_03", "03_04"]


@pytest.fixture(scope="module")
def walks(mocap: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Library, object]:
    lib = load_library(mocap, clips=WALKS, cache_dir=tmp_path_factory.mktemp("c"))
    return lib, build_graph(lib.clips, GraphOptions(coords="relative"))


# --- files --------------------------------------------------------------------------------


def test_sketch_files_json_and_csv(tmp_path: Path) -> None:
    j = tmp_path / "a.json"
    j.write_text(json.dumps({"points": [[0, 0], [0, 0], [1, 2], [3, 4]]}))
    assert read_sketch(j).tolist() == [[0, 0], [1, 2], [3, 4]]  # repeated point dropped
    c = tmp_path / "a.csv"
    c.write_text("x,z\n0,0  # start\n\n1.5,2\n")
    assert read_sketch(c).tolist() == [[0, 0], [1.5, 2]]


@pytest.mark.parametrize(
    ("name", "text", "message"),
    [
        ("b.csv", "0,0\n1,2,3\n", r"b\.csv:2: expected 'x,z'"),
        ("b.csv", "0,0\n1,nan\n", r"b\.csv: line 2: coordinates must be finite"),
        ("b.csv", "0,0\nx,1\n", r"b\.csv: line 2: coordinates must be numbers"),
        ("b.json", '{"points": [[0, 0]]}', r"b\.json: a sketch needs at least 2 distinct"),
        ("b.json", '{"points": [[0, 0], [1]]}', r"b\.json: point 1: expected a pair"),
        ("b.json", '{"points": [[0, 0],\n [1, 2]', r"b\.json:2: not valid JSON"),
    ],
)
def test_bad_sketches_name_file_and_place(tmp_path: Path, name: str, text: str, message: str):
    p = tmp_path / name
    p.write_text(text)
    with pytest.raises(SketchFileError, match=message):
        read_sketch(p)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"kind": "lava"}, "unknown environment kind 'lava'"),
        ({"kind": "maze", "obstacles": [[[0, 0], [1, 1]]]}, "obstacle 0: a polygon needs 3"),
        ({"kind": "maze", "obstacles": [[[0, 0], [1, 1], [2, 2]]]}, "obstacle 0: .* no area"),
        ({"kind": "maze", "bounds": [0, 0, -1, 1]}, "'bounds' must have xmax > xmin"),
        ({"kind": "maze", "walls": []}, "unknown keys walls"),
    ],
)
def test_bad_environments_are_named(tmp_path: Path, data: dict, message: str) -> None:
    p = tmp_path / "env.json"
    p.write_text(json.dumps(data))
    with pytest.raises(SketchFileError, match=f"env.json: {message}"):
        read_environment(p)
    with pytest.raises(SketchFileError, match="no such file"):
        read_environment(tmp_path / "none.json")


def test_clearance_agrees_with_matplotlib_inside_test(rng: np.random.Generator) -> None:
    env = read_environment(MAZE)
    pts = rng.uniform(-3, 11, size=(4000, 2))
    got = env.clearance(pts)
    inside = np.zeros(len(pts), dtype=bool)
    for poly in env.obstacles:
        inside |= MplPath(poly).contains_points(pts)
    x0, z0, x1, z1 = env.bounds
    outside = (pts[:, 0] < x0) | (pts[:, 0] > x1) | (pts[:, 1] < z0) | (pts[:, 1] > z1)
    assert np.array_equal(got < 0, inside | outside)
    # the distance: to the edges sampled every millimetre, and the walls (scipy's k-d tree)
    edges = [np.roll(p, -1, axis=0) for p in env.obstacles]
    dense = np.concatenate(
        [
            a + np.linspace(0, 1, int(np.ceil(np.linalg.norm(b - a) / 1e-3)) + 1)[:, None] * (b - a)
            for poly, nxt in zip(env.obstacles, edges, strict=True)
            for a, b in zip(poly, nxt, strict=True)
        ]
    )
    near = cKDTree(dense).query(pts)[0]
    wall = np.abs(np.stack([pts[:, 0] - x0, x1 - pts[:, 0], pts[:, 1] - z0, z1 - pts[:, 1]]))
    want = np.minimum(near, wall.min(axis=0))
    np.testing.assert_allclose(np.abs(got)[~outside], want[~outside], atol=1e-3)
    assert (got[:5] == np.array([env.clearance(p[None])[0] for p in pts[:5]])).all()
    # distance of a free point: to the nearest edge
    e = Environment(obstacles=(np.array([[0.0, 0], [2, 0], [2, 1], [0, 1]]),))
    assert e.clearance(np.array([[3.0, 0.5], [1.0, 2.0], [1.0, 0.25]])) == pytest.approx(
        [1.0, 1.0, -0.25]
    )


def test_resample_and_deviation() -> None:
    sketch = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0]])
    goals = resample_polyline(sketch, 0.5)
    assert len(goals) == 6 and goals[-1] == pytest.approx([2, 1])
    assert np.allclose(np.linalg.norm(np.diff(goals, axis=0), axis=1), 0.5)
    d = path_deviation(np.array([[1.0, 0.3], [3.0, 0.5], [2.0, 2.0]]), sketch)
    assert d == pytest.approx([0.3, 1.0, 1.0])


# --- tracking -----------------------------------------------------------------------------


def test_maze_is_followed_without_collision_and_facing_term_helps(walks) -> None:
    lib, g = walks
    sketch, env = read_sketch(MAZE_PATH), read_environment(MAZE)
    t = SketchTracker(g, lib.clips, sketch, env)
    t.run(90.0)
    root = t.root_path()
    assert t.goal == len(t.goals) and not t.stuck
    assert env.clearance(root).min() >= t.settings.body_radius
    dev = path_deviation(root, sketch)
    assert dev.mean() < 0.2 and dev.max() < 0.5
    # the plan is a path of the graph and the synthesized motion follows it
    syn = t.motion()
    assert syn.motion.n_frames == len(t.frames)
    final = syn.motion.root_pos[-1, [0, 2]]
    assert np.linalg.norm(final - root[-1]) < 0.1
    base = SketchTracker(g, lib.clips, sketch, env, SketchSettings(c=0.0))
    base.run(90.0)
    assert path_deviation(base.root_path(), sketch).mean() > 2 * dev.mean()


def test_sketch_drawn_while_the_avatar_moves(walks) -> None:
    lib, g = walks
    full = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 5.0]])
    t = SketchTracker(g, lib.clips, full[:2])
    while not t.done:
        t.step()
    assert t.goal == len(t.goals)
    n = len(t.frames)
    t.extend(full[2:])  # more of the path is drawn
    assert not t.done
    t.run(60.0)
    assert t.done and not t.stuck and len(t.frames) > n
    assert path_deviation(t.root_path(), full).mean() < 0.3
    # a sketch already within reach where the avatar stands is followed at once
    short = SketchTracker(g, lib.clips, np.array([[0.0, 0.0], [0.0, 0.3]]))
    assert short.step() == 0 and short.done and not short.stuck


def test_dead_end_is_backed_out_of_or_reported(walks) -> None:
    lib, g = walks
    # a wall right across the path, with no way round inside the bounds
    env = Environment(
        obstacles=(np.array([[-5.0, 3.0], [5.0, 3.0], [5.0, 3.5], [-5.0, 3.5]]),),
        bounds=(-5.0, -1.0, 5.0, 8.0),
    )
    t = SketchTracker(g, lib.clips, np.array([[0.0, 0.0], [0.0, 6.0]]), env)
    t.run(30.0)
    assert t.stuck and t.backtracks > 0
    assert env.clearance(t.root_path()).min() >= t.settings.body_radius


# --- the first approach: actions chosen by DTW ------------------------------------------


#: the walks' higher layer: ``mimic sketch --approach actions --k 10 --bound 3
#: --tree-nodes 512`` (``tests/prebuild.py`` builds it in the background)
ACTIONS_LAYER = LayerSettings(k=10, bound_seconds=3.0, max_nodes=512)


@pytest.fixture(scope="module")
def actions(walks, session_cache: Path, prebuild):
    """The walks' higher layer, from the tests' cache: the one ``mimic sketch --approach
    actions ... --coords relative`` on the walks loads."""
    lib, g = walks
    prebuild.wait("walks")
    cache = session_cache / "graph"
    return cached_higher_layer(g, lib.clips, ACTIONS_LAYER, cache_dir=cache)[0]


@pytest.mark.parametrize("side", [1.0, -1.0])
def test_first_approach_turns_the_way_the_sketch_does(walks, actions, side: float) -> None:
    lib, g = walks
    sketch = np.array([[0.0, 0.0], [0.0, 1.5], [2.5 * side, 3.0], [4.0 * side, 3.0]])
    t = SketchTracker(g, lib.clips, sketch, None, SketchSettings(), layer=actions)
    t.run(20.0)
    assert t.goal >= len(t.goals) and not t.stuck and len(t.expansions) > 1
    root = t.root_path()
    assert np.sign(root[-1, 0]) == side and abs(root[-1, 0]) > 2.0
    assert path_deviation(root, sketch).mean() < 0.6
    # each step performed one whole most probable motion: the frames play on or follow
    # the graph's transitions (synthesis checks every step)
    assert t.motion().motion.n_frames == len(t.frames)


def test_first_approach_avoids_obstacles_and_checks_its_inputs(walks, actions) -> None:
    lib, g = walks
    env = read_environment(MAZE)
    sketch = read_sketch(MAZE_PATH)[:3]
    t = SketchTracker(g, lib.clips, sketch, env, SketchSettings(), layer=actions)
    t.run(15.0)
    assert len(t.frames) > 1
    assert env.clearance(t.root_path()).min() >= t.settings.body_radius
    other = build_graph(lib.clips, GraphOptions(coords="relative", threshold=0.2))
    with pytest.raises(ValueError, match="same graph"):
        SketchTracker(other, lib.clips, sketch, None, layer=actions)


# --- the command --------------------------------------------------------------------------


@pytest.mark.slow
def test_cli_sketch_writes_bvh_png(mocap: Path, tmp_path: Path, capsys) -> None:
    out, png = tmp_path / "s.bvh", tmp_path / "s.png"
    clips = [a for c in WALKS for a in ("--clips", c)]
    argv = ["sketch", str(mocap), *clips, "--path", str(MAZE_PATH), "--env", str(MAZE)]
    assert main([*argv, "--out", str(out), "--png", str(png), "--baseline", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["eq. 8"]["followed"] and "no facing term" in summary
    assert read_bvh(out).n_frames > 100 and png.stat().st_size > 1000
    check = REPO.parent / "shared" / "tools" / "check_bvh.py"
    if check.is_file():  # the independent reader beside the data
        r = subprocess.run([sys.executable, str(check), str(out)], capture_output=True)
        assert r.returncode == 0, r.stdout + r.stderr
    # the first approach, compared with the search (on the relative graph: the higher
    # layer is the ``actions`` fixture's, from the tests' cache)
    actions = ["--approach", "actions", "--k", "10", "--bound", "3", "--tree-nodes", "512"]
    actions += ["--coords", "relative"]
    assert main([*argv, "--out", str(out), *actions, "--baseline", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert set(summary) == {"out", "actions (DTW)", "eq. 8"}
    assert summary["actions (DTW)"]["motion_seconds"] > 5
    bad = tmp_path / "bad.csv"
    bad.write_text("0,0\n1\n")
    assert main(["sketch", str(mocap), "--path", str(bad), "--out", str(out)]) == 2
    assert "bad.csv:2: expected 'x,z'" in capsys.readouterr().err
