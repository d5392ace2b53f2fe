"""Parametric actions (Peng et al. §6): examples found by DTW, registered, blended to a
target, and chained."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from control.graph import rotate_y, yaw_of
from control.motion import load_library, read_bvh
from control.transition import Chainer, ChainPlayer, ParametricAction
from control.transition._examples import find_examples
from mimic.cli import main

#: one of the nine strikes of 02_05 (seconds), its right wrist's apex in the middle
STRIKE = "02_05:6.67-7.6"


def _model(chainer: Chainer, spec: str = STRIKE, **kw: object) -> ParametricAction:
    ref = chainer.action(spec)
    return ParametricAction(
        chainer.feat,
        chainer.root,
        chainer.quats,
        chainer.skeleton,
        chainer.fps,
        (ref.start, ref.stop),
        **kw,  # type: ignore[arg-type]
    )


def test_one_squat_finds_every_squat_of_both_takes(chainer: Chainer) -> None:
    # the squats, counted independently: the pelvis's deep dips inside Squat labels
    from scipy.signal import find_peaks  # (imported here: the quick tier never runs this)

    names = [c.name for c in chainer.clips]
    dips = []
    for name in ("13_29", "13_30"):
        clip = chainer.clips[names.index(name)]
        y = clip.motion.root_pos[:, 1]
        low, _ = find_peaks(-y, prominence=0.15)
        first = int(chainer.feat.clip_start[names.index(name)])
        dips += [first + int(f) for f in low if clip.label_at(int(f)) == "Squat"]
    assert len(dips) == 4  # two squats in each take
    ref = dips[0]
    found = find_examples(chainer.feat, ref - 10, ref + 10, chainer.nu)
    assert found[0].start == ref - 10 and found[0].cost == 0.0  # the reference itself
    assert len(found) == len(dips)
    for d in dips:  # each squat is inside exactly one example
        assert sum(e.start <= d < e.stop for e in found) == 1
    for e in found:  # and every example is a squat
        c = int(np.searchsorted(chainer.feat.clip_start, e.start, side="right") - 1)
        mid = (e.start + e.stop) // 2 - int(chainer.feat.clip_start[c])
        assert chainer.clips[c].label_at(mid) == "Squat"
    with pytest.raises(ValueError, match="not a stretch"):
        find_examples(chainer.feat, 10, 10)


def test_an_examples_own_parameter_gives_that_example(chainer: Chainer) -> None:
    model = _model(chainer)
    # the strikes of 02_05 (nine; the last, cut short by the clip's end, is borderline)
    names = [c.name for c in chainer.clips]
    clip = np.searchsorted(chainer.feat.clip_start, [e.start for e in model.examples], "right")
    assert len(model.examples) >= 8 and {names[c - 1] for c in clip} == {"02_05"}
    for i, p in enumerate(model.params):
        got = model.request(p)
        assert got.weights[i] == 1.0 and not got.clamped
        np.testing.assert_array_equal(got.motion.quats, model.quats[i])
        np.testing.assert_array_equal(got.motion.root_pos, model.roots[i])
        np.testing.assert_allclose(got.reached, p, atol=1e-12)
    # the reference's blend is its library frames, in the action frame
    ref = chainer.action(STRIKE)
    lib_root = chainer.root[ref.start : ref.stop]
    yaw = float(yaw_of(chainer.quats[ref.start, 0]))
    expect = rotate_y(lib_root - lib_root[0] * np.array([1.0, 0.0, 1.0]), -yaw)
    np.testing.assert_allclose(model.roots[0], expect, atol=1e-12)
    np.testing.assert_array_equal(model.quats[0][:, 1:], chainer.quats[ref.start : ref.stop, 1:])


def test_a_target_between_examples_is_reached_closer_than_any_example(
    chainer: Chainer, rng: np.random.Generator
) -> None:
    model = _model(chainer)
    off, nearest = [], []
    for _ in range(12):
        pick = rng.choice(len(model.params), 3, replace=False)
        target = rng.dirichlet(np.ones(3)) @ model.params[pick]
        got = model.request(target)
        assert not got.clamped and np.isclose(got.weights.sum(), 1.0) and got.weights.min() >= 0
        off.append(np.linalg.norm(got.reached - target))
        nearest.append(np.min(np.linalg.norm(model.params - target, axis=1)))
    # measured: 2.7 cm against 11.3 cm for the nearest example (benchmarks/bench_parametric)
    assert np.mean(off) < 0.5 * np.mean(nearest) and max(off) < 0.08
    # the voxels answer too, less exactly
    fast = [model.request(t, voxels=True) for t in model.params[:3] * 0.5 + model.params[3:6] * 0.5]
    assert all(np.isfinite(b.reached).all() for b in fast)


def test_a_target_out_of_reach_is_clamped_and_bad_targets_are_refused(chainer: Chainer) -> None:
    model = _model(chainer)
    far = model.params.mean(axis=0) + np.array([0.0, 0.0, 3.0])
    got = model.request(far)
    assert got.clamped and model.inside(got.target)
    assert got.target[2] <= model.params[:, 2].max() + 1e-9
    for bad in ((0.0, 1.0), (np.nan, 1.0, 0.5)):
        with pytest.raises(ValueError, match="three finite numbers"):
            model.request(bad)  # type: ignore[arg-type]
    with pytest.raises(KeyError, match="unknown role"):
        _model(chainer, effector="right_tail")
    with pytest.raises(ValueError, match="key must be"):
        _model(chainer, key="middle")


def test_a_chain_strikes_three_targets_between_other_actions(chainer: Chainer) -> None:
    targets = [(0.45, 1.3, 0.55), (0.35, 1.55, 0.5), (0.5, 1.0, 0.6)]
    specs = ["label:Squat", *(f"{STRIKE}@{x},{y},{z}" for x, y, z in targets), "02_01"]
    result = chainer.chain(specs)
    assert len(result.blends) == 3
    blended = np.flatnonzero(result.sources == -2)
    # every strike is played, most of each (entered within its first third)
    m = chainer.action(STRIKE).stop - chainer.action(STRIKE).start
    assert blended.size >= 3 * (m - m // 3)
    for (_, blend), target in zip(result.blends, targets, strict=True):
        assert np.linalg.norm(blend.reached - blend.target) < 0.08
        assert not blend.clamped or np.linalg.norm(blend.target - target) > 0
    with pytest.raises(ValueError, match="unknown action"):
        chainer.action("nowhere@1,2,3")
    # the game loop's request with a target plays the same kind of frames
    player = ChainPlayer(chainer)
    player.request("02_01")
    player.request(STRIKE, target=targets[0])
    srcs = [player.next()[2] for _ in range(120)]
    assert -2 in srcs and srcs[-1] == srcs[-2]  # the blend played, then the last pose held


@pytest.mark.slow  # (a whole command)
def test_mimic_chain_takes_a_target_and_says_how_close_it_got(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "strikes.bvh"
    argv = ["chain", "02_01", f"{STRIKE}@0.45,1.3,0.55", f"{STRIKE}@0.5,1.0,3", "--clips", "02_0*"]
    assert main([*argv, "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert "a blend of" in said and "cm from (0.45, 1.30, 0.55)" in said
    far = next(line for line in said.splitlines() if line.startswith(f"{STRIKE}@right_wrist=0.5,"))
    assert far.endswith("clamped into their hull)")  # z = 3 m is out of reach
    assert read_bvh(out).n_frames > 30
    assert main(["chain", "02_01@0.1,x,0.3", "--clips", "02_0*", "--out", str(out)]) == 2
    assert "unknown action" in capsys.readouterr().err


@pytest.mark.slow
def test_a_turning_step_turns_by_the_angle_asked(
    mocap: Path, tmp_path_factory: pytest.TempPathFactory
) -> None:
    lib = load_library(mocap, clips=["02_0*", "03_0*"], cache_dir=tmp_path_factory.mktemp("c"))
    walks = Chainer(lib.clips, seed=1)
    act = walks.action("03_04:7.8-8.8@turn=30")  # a step turning left, found in both walks
    assert act.blend is not None and not act.blend.clamped and act.blend.weights.max() < 1
    yaw = np.unwrap(yaw_of(act.blend.motion.quats[:, 0]))
    assert abs(np.degrees(yaw[-1] - yaw[0]) - 30.0) < 1.0
    assert abs(act.blend.reached[0] - 30.0) < 1.0
    assert walks.action("03_04:7.8-8.8@turn=300").blend.clamped  # type: ignore[union-attr]
