"""Following with the defaults (issue 17): direct jumps, the floor, the cached layer."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from benchmarks._landmarks import LandmarkSource, landmark_points
from control.avatar import JUMP, Avatar, JumpCosts
from control.dtw import dtw_batch
from control.graph import off_floor_seconds
from control.motion import load_library, read_bvh
from mimic.cli import main
from tests.vision.conftest import RECORDING
from vision import (
    FLOOR_ABOVE,
    Decision,
    Jump,
    LandingSettings,
    Matcher,
    MatchSettings,
    PerformSettings,
    RecordSettings,
    VideoSource,
    floor_level,
    on_the_floor,
    perform,
    record_clip,
)
from vision._landing import sparse_window


def test_clips_that_leave_the_floor_are_found(mocap: Path) -> None:
    lib = load_library(mocap, clips=["01_08", "01_01", "13_30", "02_04"])
    kept, out = on_the_floor(lib.clips)
    # sitting on the climbing frame, dangling the legs: left out; jumps and a balance on
    # one leg stay
    assert set(out) == {"01_08"} and out["01_08"] > 2.0
    assert {c.name for c in kept} == {"01_01", "13_30", "02_04"}
    assert abs(floor_level(lib.clips)) < 0.1


@pytest.mark.slow
def test_the_defaults_keep_the_avatar_on_the_floor(mocap: Path, tmp_path: Path, capsys) -> None:
    """A performer sitting up on something (01_08's climbing frame, which the avatar's
    world lacks): the avatar must not follow them into the air."""
    clip = load_library(mocap, fps=30, clips=["01_08"]).clip("01_08")
    video = tmp_path / "sitting.mkv"
    record_clip(clip, video, RecordSettings(), 180, 480)
    out = tmp_path / "avatar.bvh"
    args = ["perform", "--video", str(video), str(mocap), "--clips", "13_30", "--clips", "01_08"]
    args += ["--no-fuse"]  # (the floor-leaving clip is left out before any vote)
    assert main([*args, "--out", str(out), "--log", str(tmp_path / "log.jsonl")]) == 0
    err = capsys.readouterr().err
    assert "01_08" in err and "leave the floor" in err
    motion = read_bvh(out)
    floor = floor_level(load_library(mocap, clips=["13_30"]).clips)
    assert off_floor_seconds(motion, floor, FLOOR_ABOVE) <= 0.5


def _agreement(decisions: list[dict], side: dict, labels_of, lag: float) -> float:
    fps = float(side.get("fps", 30.0))
    truth = side["labels"]
    hits = []
    for d in decisions:
        k = round((d["t"] - lag) * fps)
        if 0 <= k < len(truth) and truth[k] is not None:
            hits.append(labels_of(d["clip"], d["clip_frame"]) == truth[k])
    return float(np.mean(hits))


@pytest.mark.slow
def test_the_defaults_follow_a_recording_of_a_library_clip(
    mocap: Path, tmp_path: Path, capsys
) -> None:
    """A recording of 13_30 made as the committed one of 13_29 was (another body and
    camera, ragged masks, a shadow; 12 s at 160x120), with 13_30 in the library (the vision
    fixtures' bank, from the tests' cache): the avatar does what the performer does."""
    clip = load_library(mocap, fps=30, clips=["13_30"]).clip("13_30")
    video = tmp_path / "13_30.mkv"
    record_clip(clip, video, dataclasses.replace(RecordSettings(), width=160, height=120), 0, 360)
    log = tmp_path / "log.jsonl"
    args = ["perform", "--video", str(video), str(mocap), "--clips", "13_30"]
    assert main([*args, "--log", str(log)]) == 0
    decisions = [json.loads(line) for line in log.read_text().splitlines()]
    side = json.loads(Path(f"{video}.json").read_text())
    lib = load_library(mocap, clips=["13_30"])

    def label(name: str, frame: int) -> str | None:
        return lib.clip(name).label_at(frame)

    assert max(_agreement(decisions, side, label, lag) for lag in (0.0, 0.5, 1.0)) >= 0.8
    said = capsys.readouterr()
    assert "direct jumps" in said.out
    # the take's five actions are voted among
    assert "actions: 5 labelled (Jog, JumpJack, KneeRaise, Squat, Twist)" in said.err


def test_a_source_of_landmarks_is_followed_by_the_pose_descriptor(setup, mocap: Path, tmp_path):
    """A performer's landmarks (13_30's joints on another body, seen by another camera,
    with 3% noise) straight from the source: the pose descriptor follows them; a
    silhouette descriptor refuses them, naming the source."""
    from silhouette_bank import BankSettings, build_bank

    lib, layer, silhouettes = setup
    clip = load_library(mocap, fps=30, clips=["13_30"]).clip("13_30")
    frames = np.arange(0, 360)  # 12 s
    px = landmark_points(clip.motion, RecordSettings(), np.random.default_rng(3), frames=frames)
    bank = build_bank(lib.clips, BankSettings(descriptor="pose"), tmp_path / "pose", workers=1)
    tracker = LandmarkSource(px, 30.0, name="tracker")
    r = perform(tracker, layer, bank, lib.clips, PerformSettings())
    made = [d for d in r.decisions if d["decision"] is not None]
    assert len(made) >= 100 and r.frames_with_media == 360
    side = {"fps": 30.0, "labels": [clip.label_at(f) for f in frames]}
    label = lib.clip("13_30").label_at
    assert (
        max(_agreement(r.decisions, side, lambda _n, f: label(f), lag) for lag in (0, 0.5, 1))
        >= 0.85
    )
    # a performer who stops for 3 s (at 5 s): the avatar holds still, and the log says so
    still = np.concatenate((np.arange(0, 150), np.full(90, 150), np.arange(151, 240)))
    px2 = landmark_points(clip.motion, RecordSettings(), np.random.default_rng(4), frames=still)
    r2 = perform(LandmarkSource(px2, 30.0), layer, bank, lib.clips, PerformSettings())
    pause = [d for d in r2.decisions if 6.0 <= d["t"] < 8.0]
    assert sum(bool(d.get("held")) for d in pause) >= 0.6 * len(pause)  # (16 of 20)
    assert not any(d.get("held") for d in r.decisions if d["t"] < 1.5)  # (a window in)
    with pytest.raises(ValueError, match="tracker: this source gives body landmarks"):
        tracker = LandmarkSource(px, 30.0, name="tracker")
        perform(tracker, layer, silhouettes, lib.clips, PerformSettings())


def test_jumps_keep_feet_on_the_floor(setup) -> None:
    lib, layer, bank = setup
    r = perform(VideoSource(RECORDING, silhouette=True), layer, bank, lib.clips, PerformSettings())
    assert r.avatar.n_jumps >= 1
    assert any("jump" in d for d in r.decisions)
    syn = r.avatar.motion()
    floor = floor_level(lib.clips)
    assert off_floor_seconds(syn.motion, floor, FLOOR_ABOVE) <= 0.5
    # without jumps: the paper's loop, no direct jump
    r2 = perform(
        VideoSource(RECORDING, silhouette=True),
        layer,
        bank,
        lib.clips,
        PerformSettings(match=MatchSettings(landing=LandingSettings(jumps=False))),
    )
    assert r2.avatar.n_jumps == 0 and not any("jump" in d for d in r2.decisions)


def test_right_after_a_jump_the_own_cost_is_the_window_played_into(setup) -> None:
    """The avatar has just jumped into frame ``j`` from far away. Its own cost (against
    which a jump must win) is that of the library window that plays into ``j``, as the
    search scores every window, not of the frames it has shown, which still hold the
    motion it jumped from: a performer doing that window costs it less."""
    _, layer, bank = setup
    m = Matcher(layer, bank)
    j = 200
    window = np.arange(j - m.n + 1, j + 1)
    shown = np.concatenate((np.arange(20, 20 + m.n), [j]))  # frames 20.., then the jump
    assert np.array_equal(m.lander.own_frames(j, shown), window)
    performer = bank.features[m.windows.to_bank[window], 0].astype(np.float64)
    queries = m.queries(performer)
    assert queries is not None
    own, shown_cost = (
        m.lander.own_cost(queries, m.lander.own_frames(j, shown)),
        m.lander.own_cost(queries, shown),
    )
    assert own < 0.25 * shown_cost
    # a library window is costed from the search's tables (float32 shape numbers), the
    # frames shown from the bank: the same cost to float32's precision
    for q in queries:
        q += 0.05 * np.random.default_rng(1).normal(size=q.shape)  # not the window itself
    st = m.settings
    by_bank = min(
        dtw_batch(q, m.windows.sequences(window), None, st.band, st.recency).min() for q in queries
    )
    assert m.lander.own_cost(queries, window) == pytest.approx(by_bank, rel=1e-5)
    # without own_from_library, the frames shown; and at a clip's first frames, which
    # have no window of their own, those too
    before = Matcher(layer, bank, MatchSettings(landing=LandingSettings(own_from_library=False)))
    assert np.array_equal(before.lander.own_frames(j, shown), shown)
    assert np.array_equal(m.lander.own_frames(3, shown), shown)


def test_a_jump_is_scored_by_its_match_and_with_a_blend_weight_by_its_blend_too(setup) -> None:
    """By default a jump goes to the frame after the best window that the avatar may land
    on (the blend plays no part); with ``blend_weight`` ``w`` each candidate's cost is
    times ``1 + w D / (D + D_max)``, so a far blend must match better to win."""
    lib, layer, bank = setup
    real = JumpCosts(layer.graph, lib.clips, anywhere=True)

    class Near:
        """The blend from the avatar's frame is short only into ``near``."""

        landing = real.landing
        near = -1

        def __call__(self, frame: int, targets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            _, align = real(frame, targets)
            return np.where(
                targets == self.near, 0.0, 100.0 * layer.graph.report["max_distance"]
            ), align

    costs = Near()
    frame, j = 40, 200  # the performer does the window that ends at frame j, seen from view 3
    recent = np.arange(frame - 30, frame + 1, dtype=np.int64)
    for w in (0.0, 1.0):
        m = Matcher(
            layer,
            bank,
            MatchSettings(landing=LandingSettings(blend_weight=w, min_play=0.0, phase_frames=0)),
        )
        window = np.arange(j - m.n + 1, j + 1)
        performer = bank.features[m.windows.to_bank[window], 3].astype(np.float64)
        performer += 0.02 * np.random.default_rng(0).normal(size=performer.shape)
        queries = m.queries(performer)
        assert queries is not None
        got = m.windows.index().search(
            queries, m.settings.band, m.settings.landing.top_windows, recency=m.settings.recency
        )
        target, ok, _ = m.lander.targets(frame, got, costs, queries)
        assert ok.sum() >= 3
        costs.near = int(target[ok][2])  # the third best match
        d = m.jump(frame, performer, recent, costs, queries)
        assert d is not None and d.frames[0] == frame and d.edges[0] == JUMP
        best = int(target[ok][0]) if w == 0 else costs.near
        assert d.jump.target == best and d.cost == pytest.approx(
            got[np.flatnonzero(ok)[0 if w == 0 else 2]][2]
        )
        assert d.jump.blend == (0.0 if w else 100.0 * layer.graph.report["max_distance"])


@pytest.mark.parametrize("bad", [{"top_windows": 0}, {"jump_ratio": 0.0}, {"blend_weight": -1.0}])
def test_bad_jump_settings_are_refused(bad) -> None:
    with pytest.raises(ValueError, match="top_windows must be"):
        LandingSettings(**bad)


@pytest.mark.parametrize(
    ("bad", "said"),
    [
        ({"hold_keep": 0.0}, "hold_keep"),
        ({"hold_keep": 1.5}, "hold_keep"),
        ({"hold_back": -1}, "hold_back"),
    ],
)
def test_bad_hold_settings_are_refused(bad, said) -> None:
    with pytest.raises(ValueError, match=said):
        LandingSettings(**bad)


@pytest.mark.slow
def test_the_playgrounds_climbs_are_left_out(mocap: Path, tmp_path: Path, capsys) -> None:
    """Before issue 17, ``mimic perform`` with no flags on the whole shared library played
    the playground's climbs (both feet 0.3-0.8 m up for seconds). Here every playground
    take that leaves the floor, beside one that does not: all are left out, and the
    avatar stays on the floor. (``.ci/run`` runs the whole default library, with no
    flags, on the same recording and checks the same.)"""
    climbs = ["--clips", "01_0[2-9]", "--clips", "01_1*"]
    out = tmp_path / "avatar.bvh"
    argv = ["perform", "--video", str(RECORDING), str(mocap), *climbs, "--clips", "13_30"]
    argv += ["--no-fuse"]  # (the floor-leaving clips are left out before any vote)
    assert main([*argv, "--out", str(out)]) == 0
    err = capsys.readouterr().err
    left = {f"01_{k:02d}" for k in range(2, 15)}
    assert "leave the floor" in err and all(name in err for name in left)
    lib = load_library(mocap, clips=["01_*", "13_30"])
    assert set(on_the_floor(lib.clips)[1]) == left  # the playground's floor-leaving takes
    motion = read_bvh(out)
    assert off_floor_seconds(motion, floor_level(lib.clips), FLOOR_ABOVE) <= 0.5


def test_a_jumps_target_moves_to_where_the_performers_last_frames_are() -> None:
    """``phased_targets``: a target a few frames off the library frames that match the
    performer's last ``PHASE_FRAMES`` moves onto them, within ``shift`` and within its
    clip's run; the nearer of two readings counts; ``shift`` 0 moves nothing."""
    from vision._windows import PHASE_FRAMES, phased_targets

    rng = np.random.default_rng(3)
    n, views, d = 120, 4, 6
    # a motion that moves on steadily: the further a frame from another, the less alike
    shape = (0.1 * np.arange(n)[:, None, None] * rng.normal(size=(1, views, d))).astype(np.float32)
    runs = np.repeat([0, 1], [60, 60])  # two clips' runs: frames 0-59 and 60-119
    end = 40  # the performer's last frames are the library's frames up to 40, view 2
    tail = shape[end - PHASE_FRAMES + 1 : end + 1, 2].astype(np.float64)
    query = np.concatenate((rng.normal(size=(10, d)), tail))
    query = np.concatenate((query, np.zeros((query.shape[0], 2))), axis=1)  # the centre
    other = query + 5.0  # a reading that matches nothing
    views_ = np.array([2, 2, 2, 2])
    target = np.array([end + 1 - 4, end + 1, end + 1 + 3, end + 1 + 9])
    got = phased_targets(target, views_, [other, query], shape, runs, 6)
    np.testing.assert_array_equal(got, [end + 1, end + 1, end + 1, end + 1 + 3])  # (9: 6 at most)
    np.testing.assert_array_equal(phased_targets(target, views_, [query], shape, runs, 0), target)
    # a target by the end of its run is moved only within it, never into the next clip
    near = np.array([58])
    assert 58 - 6 <= phased_targets(near, np.array([2]), [query], shape, runs, 6)[0] <= 59


def test_a_performer_standing_still_is_held_still(setup, monkeypatch) -> None:
    """A performer standing still in the pose of the avatar's frame: the avatar holds that
    frame (shown again, its root not moved on), rather than jump about among the
    library's windows, none of which stands still; a performer doing the window that
    plays into that frame is not held; ``still=False`` never holds."""
    lib, layer, bank = setup
    costs = JumpCosts(layer.graph, lib.clips, anywhere=True)
    m = Matcher(layer, bank)
    j = 200  # mid-squat in 13_30
    recent = np.arange(j - 30, j + 1, dtype=np.int64)
    noise = 0.01 * np.random.default_rng(2).normal(size=(m.n, bank.features.shape[2]))
    still = (
        np.repeat(bank.features[m.windows.to_bank[[j]], 3].astype(np.float64), m.n, axis=0) + noise
    )
    d = m.decide(j, still, recent, costs)
    assert d is not None and d.how == "held"
    assert np.all(d.frames == j) and np.all(d.edges == -1) and d.cost < d.runner_up
    window = m.windows.to_bank[np.arange(j - m.n + 1, j + 1)]
    moving = bank.features[window, 3].astype(np.float64) + noise
    d2 = m.decide(j, moving, recent, costs)
    assert d2 is not None and d2.how != "held"
    off = Matcher(layer, bank, MatchSettings(landing=LandingSettings(hold_still=False))).decide(
        j, still, recent, costs
    )
    assert off is not None and off.how != "held"

    # with no jump weighed (none of the best windows may be landed on, and the avatar is
    # at none of them), holding is weighed against playing on
    def nowhere(frame, got, costs, queries):
        target = np.array([g[0] for g in got], dtype=np.int64) + m.n
        return target, np.zeros(len(got), dtype=bool), np.zeros(len(got), dtype=bool)

    monkeypatch.setattr(m.lander, "targets", nowhere)
    d3 = m.decide(j, still, recent, costs)
    assert d3 is not None and d3.how == "held" and np.isfinite(d3.runner_up)
    # the avatar takes the hold: its frame shown again, standing where it stood
    avatar = Avatar(layer.graph, lib.clips, start=j, anywhere=True)
    avatar.take(d.frames, d.edges)
    for _ in range(5):
        avatar.step()
    syn = avatar.motion().motion
    np.testing.assert_allclose(syn.root_pos[1:], np.broadcast_to(syn.root_pos[0], (5, 3)))


def test_a_performer_still_in_another_pose_is_held_where_the_jump_lands(setup) -> None:
    """A performer standing still mid-squat while the avatar twists: the windows that
    match a still performer run through that pose and on, so a jump to the frame after
    the best one plays out of it. The avatar lands on a frame that plays into that jump's
    target and holds it, which matches the performer far better; with ``hold_back`` 0
    it jumps and plays on."""
    lib, layer, bank = setup
    costs = JumpCosts(layer.graph, lib.clips, anywhere=True)
    m = Matcher(layer, bank)
    at, pose = 60, 200  # twisting, and a squat's pose in 13_30
    assert lib.clips[0].label_at(at) == "Twist" and lib.clips[0].label_at(pose) == "Squat"
    recent = np.arange(at - 30, at + 1, dtype=np.int64)
    noise = 0.01 * np.random.default_rng(2).normal(size=(m.n, bank.features.shape[2]))
    still = (
        np.repeat(bank.features[m.windows.to_bank[[pose]], 3].astype(np.float64), m.n, axis=0)
        + noise
    )
    d = m.decide(at, still, recent, costs)
    assert d is not None and d.how == "held" and d.jump is not None
    assert d.frames[0] == at and d.edges[0] == JUMP and np.all(d.edges[1:] == -1)
    assert np.all(d.frames[1:] == d.jump.target) and lib.clips[0].label_at(d.jump.target) == "Squat"
    plain = MatchSettings(landing=LandingSettings(hold_back=0))
    d0 = Matcher(layer, bank, plain).decide(at, still, recent, costs)
    assert d0 is not None and d0.how != "held" and d0.jump is not None
    assert d0.frames[2] == d0.frames[1] + 1  # (it plays on)
    assert d.cost < 0.8 * d0.cost
    # held there, the next decision holds it again
    avatar = Avatar(layer.graph, lib.clips, start=at, anywhere=True)
    avatar.take(d.frames, d.edges)
    for _ in range(m.n):
        avatar.step()
    shown = avatar.recent(31)
    assert shown[-1] == d.jump.target
    again = m.decide(int(shown[-1]), still, shown, costs)
    assert again is not None and again.how == "held" and np.all(again.frames == d.jump.target)
    # the same window from a source slower than the library (each frame repeated for the
    # steps until the next, as a 5 frames/s clip or a page dropping frames gives it)
    # reads motion as stillness: the jump is not landed and held there
    steps = still[::3].repeat(3, axis=0)[: m.n]
    assert sparse_window(steps) and not sparse_window(still)
    sparse = m.decide(at, steps, recent, costs)
    assert sparse is not None and sparse.how != "held" and sparse.jump is not None


def test_a_held_frame_that_fits_well_is_kept_unless_another_fits_clearly_better(
    setup, monkeypatch
) -> None:
    """Holding frame 150 already, against another frame to hold (one that plays into a
    jump's target) that fits 10% better: the avatar keeps its frame, which costs
    ``hold_keep`` (0.8) of itself; not holding it yet, or where it fits weakly (a pose
    model's guess), the better frame is taken, by a jump that lands there and holds."""
    lib, layer, bank = setup
    costs = JumpCosts(layer.graph, lib.clips, anywhere=True)
    m = Matcher(layer, bank)
    frame, target = 150, 200
    other = target - 2
    fits = {frame: 1.0, other: 0.9}
    monkeypatch.setattr(m.lander, "_held_cost", lambda f, q: (fits.get(f, 5.0), 0))
    jump = Jump(target, own_cost=3.0, blend=0.0)
    rival = Decision(
        np.array([frame, target]),
        np.array([JUMP]),
        np.zeros(0, np.int64),
        2.0,
        3.0,
        0,
        8,
        0.0,
        jump=jump,
    )
    queries = [np.zeros((m.n, bank.features.shape[2]))]
    kept = m.lander.held(frame, queries, rival, 3.0, costs, holding=True)
    assert kept is not None and kept.jump is None and np.all(kept.frames == frame)
    moved = m.lander.held(frame, queries, rival, 3.0, costs, holding=False)
    assert moved is not None and moved.jump is not None and moved.jump.target == other
    assert moved.frames[0] == frame and np.all(moved.frames[1:] == other)
    monkeypatch.setattr(m.lander, "fits_weakly", lambda cost, q: True)
    weak = m.lander.held(frame, queries, rival, 3.0, costs, holding=True)
    assert weak is not None and weak.jump is not None and weak.jump.target == other


def test_half_a_window_places_the_avatar_where_it_plays_on_in_its_action(setup) -> None:
    """Half a window in, the avatar starts at the end of the library window most like
    the performer's half and plays on from there until the first whole window. Placed
    at an action's last frames, it played on into the next action and the first
    decision took it back: a brief action the performer never did. It is placed only
    where the library plays on in the same action until then."""
    lib, layer, bank = setup
    m = Matcher(layer, bank)
    m.ready(lib.clips, 0.1)
    keys, runs = m.vote.actions, m.windows.runs
    assert keys is not None
    span = m.n // 2
    runway = m.n - span
    # the performer's half window: the library's own frames up to 2 frames before a
    # change of action inside a clip
    change = np.flatnonzero((keys[1:] != keys[:-1]) & (runs[1:] == runs[:-1])) + 1
    b = int(change[change > 3 * m.n][0])
    window = np.arange(b - 2 - span, b - 2)
    performer = bank.features[m.windows.to_bank[window], 0].astype(np.float64)
    queries = m.queries(performer)
    assert queries is not None
    start = m.windows.best(queries, 1, span, False)[0][0]
    end = start + span - 1
    assert start == window[0]  # unrestricted: the window itself,
    assert keys[end + runway] != keys[end]  # which plays into the next action
    placed = m.search(performer)
    assert placed
    end = placed[0][0] + span - 1
    assert runs[end + runway] == runs[end] and keys[end + runway] == keys[end]
