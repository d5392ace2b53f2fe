"""The matcher and the performance loop on a small real library (13_30)."""

from __future__ import annotations

import dataclasses
import itertools
import json
import threading
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from control.motion import EMBEDDED_LIBRARY, load_library, read_bvh
from mimic.cli import main
from silhouette_bank import Bank, BankSettings, CameraRing, build_bank, silhouette_features
from tests.vision.conftest import RECORDING
from vision import (
    CameraSource,
    Frame,
    LandingSettings,
    MaskFolderSource,
    Matcher,
    MatchSettings,
    PathSettings,
    PerformSettings,
    VideoSource,
    perform,
)


@pytest.fixture(scope="module")
def banks(setup, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Bank]:
    """The default bank (outline) and banks of the other silhouette descriptors."""
    lib, _, bank = setup
    out = {bank.settings.descriptor: bank}
    for name in ("hu", "grid"):
        settings = BankSettings(descriptor=name)
        out[name] = build_bank(lib.clips, settings, tmp_path_factory.mktemp(name), workers=1)
    return out


@pytest.mark.parametrize("descriptor", ["hu", "grid", "outline"])
def test_matcher_finds_a_path_from_its_own_silhouettes(setup, banks, descriptor) -> None:
    _, layer, _ = setup
    bank = banks[descriptor]
    assert bank.settings.descriptor == descriptor
    matcher = Matcher(layer, bank, MatchSettings(window=1.0, paths=PathSettings(lookahead=1.5)))
    rng = np.random.default_rng(2)
    hits = 0
    trials = 0
    for f in rng.choice(np.flatnonzero(layer.graph.in_scc), 40, replace=False):
        cands = matcher.paths.candidates(int(f))
        if len(cands) < 2:
            continue
        trials += 1
        k = int(rng.integers(len(cands)))
        frames = matcher.paths.window_frames(cands[k][1])
        view = int(rng.integers(18))
        # the performer is exactly the avatar doing candidate k, seen from one ring view
        b = matcher.windows.to_bank[frames]
        feats = bank.features[b, view].astype(float)
        move = bank.root_motion[b, view].astype(float)
        centre = np.cumsum(move, axis=0) - move[0] + feats[:, -2:]
        performer = np.concatenate((feats[:, :-2], centre), axis=1)
        if k % 2:  # the performer as the mirror shows it: the same path
            performer = bank.settings.features.mirror(performer)
        d = matcher.decide(int(f), performer)
        assert d is not None and d.cost <= 1e-6 + d.runner_up
        same = np.array_equal(matcher.paths.window_frames(d.frames), frames)
        hits += same or d.cost < 1e-6
    assert trials >= 10 and hits == trials


@pytest.mark.parametrize("descriptor", ["hu", "grid", "outline"])
def test_locate_finds_the_window_the_performer_replays(setup, banks, descriptor) -> None:
    _, layer, _ = setup
    bank = banks[descriptor]
    assert bank.settings.descriptor == descriptor
    matcher = Matcher(layer, bank, MatchSettings(window=1.0))
    _, _, starts = matcher.windows.tables()
    rng = np.random.default_rng(5)
    for s in rng.choice(starts, 8, replace=False):
        frames = np.arange(s, s + matcher.n)
        view = int(rng.integers(18))
        b = matcher.windows.to_bank[frames]
        feats = bank.features[b, view].astype(float)
        move = bank.root_motion[b, view].astype(float)
        centre = np.cumsum(move, axis=0) - move[0] + feats[:, -2:]
        # the silhouette centre is image position: any offset must not matter
        performer = np.concatenate((feats[:, :-2], centre + np.array([0.3, -0.1])), axis=1)
        got = matcher.find_window(performer)
        assert got is not None and got[2] < 1e-5
        assert got[0] == s or abs(got[0] - s) <= 1  # a held pose may match a neighbour
    assert matcher.find_window(np.full((matcher.n, matcher.n_features), np.nan)) is None
    # features of the other descriptor are refused, with the way to make the right ones
    other = matcher.n_features + 1
    with pytest.raises(ValueError, match="silhouette_features"):
        matcher.find_window(np.zeros((matcher.n, other)))
    with pytest.raises(ValueError, match=f"{descriptor!r} descriptor"):
        matcher.decide(int(starts[0]), np.zeros((matcher.n, other)))


def test_route_is_a_shortest_way_through_the_graph(setup) -> None:
    """Breadth-first routes against scipy's shortest paths on the same graph."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import shortest_path

    _, layer, bank = setup
    g = layer.graph
    matcher = Matcher(layer, bank, MatchSettings(paths=PathSettings(route_seconds=2.0)))
    scc = g.in_scc
    src = list(g.src[scc[g.src] & scc[g.dst]])
    dst = list(g.dst[scc[g.src] & scc[g.dst]])
    plays = np.flatnonzero(matcher.plays & scc & np.roll(scc, -1))
    src += list(plays)
    dst += list(plays + 1)
    adj = csr_matrix((np.ones(len(src)), (src, dst)), shape=(g.n_frames, g.n_frames))
    rng = np.random.default_rng(7)
    frames = rng.choice(np.flatnonzero(scc), 12, replace=False)
    dist = shortest_path(adj, unweighted=True, indices=frames)
    bound = round(2.0 * g.fps)
    found = 0
    for i, f in enumerate(frames):
        for t in rng.choice(np.flatnonzero(scc), 15, replace=False):
            way = matcher.paths.route(int(f), int(t))
            if dist[i, t] > bound:
                assert way is None
                continue
            found += 1
            assert way is not None and way[0].size - 1 == dist[i, t]
            assert way[0][0] == f and way[0][-1] == t
            for a, b, e in zip(way[0][:-1], way[0][1:], way[1], strict=True):
                assert (e < 0 and b == a + 1 and matcher.plays[a]) or (
                    g.src[e] == a and g.dst[e] == b
                )
    assert found >= 10


def _run(setup, source, **kw):
    lib, layer, bank = setup
    return perform(source, layer, bank, lib.clips, PerformSettings(**kw), seed=3)


def test_replaying_a_recording_is_deterministic(setup) -> None:
    a = _run(setup, VideoSource(RECORDING, silhouette=True))
    b = _run(setup, VideoSource(RECORDING, silhouette=True))
    strip = [{k: v for k, v in d.items() if k != "latency_ms"} for d in a.decisions]
    assert strip == [{k: v for k, v in d.items() if k != "latency_ms"} for d in b.decisions]
    made = [d for d in a.decisions if d.get("decision") is not None or d.get("en_route")]
    assert len(made) > 0.8 * len(a.decisions)
    # the avatar starts where the first half second was located (t = 0.5 s, the fifth
    # decision, half a window in): 11.5 s of motion
    assert [i for i, d in enumerate(a.decisions) if "located" in d] == [4]
    assert a.decisions[4]["t"] == pytest.approx(0.5)
    assert a.avatar.n_frames == pytest.approx(11.5 * 15, abs=2)
    assert a.avatar.history()[0][0] == a.decisions[4]["frame"]


def test_the_loop_holds_the_numeric_libraries_to_one_thread(setup) -> None:
    """A decision's small matrix products spread over BLAS threads waited on one another
    (decision p99 2.1-6.1 ms alone, 1.3-2.6 ms on one thread): the loop
    runs with BLAS, OpenMP and numba on one thread each, and leaves the limits as it found
    them."""
    import numba
    from threadpoolctl import threadpool_info, threadpool_limits

    def threads(api: str | None = None) -> dict[str, int]:
        got = [p for p in threadpool_info() if api in (None, p["user_api"])]
        if api:  # (a BLAS on OpenMP's threads follows faiss's setting, below)
            got = [p for p in got if p.get("threading_layer") != "openmp"]
        return {p["filepath"]: p["num_threads"] for p in got}

    seen: list[dict[str, int]] = []
    lib, layer, bank = setup
    with threadpool_limits(limits=2):  # as on a machine of two cores or more
        before, pools = threads("blas"), threads()
        source = VideoSource(RECORDING, silhouette=True)
        on_frame = lambda *_: seen.append({**threads(), "numba": numba.get_num_threads()})  # noqa: E731
        perform(source, layer, bank, lib.clips, PerformSettings(seconds=1.0), on_frame=on_frame)
        after = threads("blas")
    # (OpenMP stays at 1 after: the faiss index sets it so, vision._index; a library
    # first loaded during the loop, as numba's OpenMP layer, is not limited: numba's
    # own limit covers its kernels)
    assert before and set(before.values()) == {2}  # (numpy's BLAS at least)
    assert {k: after[k] for k in before} == before
    known = set(pools) | {"numba"}
    assert seen and all({v for k, v in s.items() if k in known} == {1} for s in seen), seen[0]
    assert numba.get_num_threads() == numba.config.NUMBA_NUM_THREADS


def test_a_clip_of_another_skeleton_in_the_library_leaves_the_vote_on(
    setup, mocap: Path, tmp_path: Path, capsys, monkeypatch
) -> None:
    """The shared library holds a BVH of another skeleton (09_01), which the graph leaves
    out. Given to the loop beside the graph's clips, it put the vote's per-frame actions
    (and the facing's headings) out of line with the graph's frames, and both went off
    without a word."""
    from vision._perform import Performance

    lib, layer, bank = setup
    other = load_library(mocap, clips=["09_01"]).clips[0]
    assert other.motion.skeleton.names != lib.clips[0].motion.skeleton.names
    settings = PerformSettings(seconds=4.0)
    alone = perform(VideoSource(RECORDING, silhouette=True), layer, bank, lib.clips, settings)
    source = VideoSource(RECORDING, silhouette=True)
    run = Performance(source, layer, bank, [other, *lib.clips], settings, None, 0)
    actions = run.matcher.vote.actions
    assert actions is not None and actions.size == layer.graph.n_frames
    assert run.matcher.windows.facing is not None  # (the facing's per-frame headings too)
    got = run.run()
    strip = lambda r: [{k: v for k, v in d.items() if k != "latency_ms"} for d in r.decisions]  # noqa: E731
    assert strip(got) == strip(alone)
    # the command line says which clips it left out, at every run, and builds its banks
    # (the silhouette's, and the pose bank of the landmarks read from the silhouettes)
    # of the graph's clips only
    argv = ["perform", "--video", str(RECORDING), str(mocap), "--clips", "13_30"]
    argv += ["--clips", "09_01", "--k", "12", "--seconds", "1", "--out", str(tmp_path / "a.bvh")]
    import mimic.run

    banked: list[list[str]] = []
    real = mimic.run.cached_bank
    monkeypatch.setattr(
        mimic.run,
        "cached_bank",
        lambda c, *a, **k: banked.append([x.name for x in c]) or real(c, *a, **k),
    )
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert "left out 1 clip of another skeleton" in err and "joints): 09_01" in err
    assert banked == [["13_30"], ["13_30"]]


class _TwoPeople:
    """A silhouette source with a second person beside the performer: each mask beside
    a copy of itself a little smaller (``share`` of its height and width)."""

    def __init__(self, share: float) -> None:
        self.inner = VideoSource(RECORDING, silhouette=True)
        self.fps, self.name, self.share = self.inner.fps, "two people", share

    def read(self) -> Frame | None:
        f = self.inner.read()
        if f is None or f.mask is None:
            return f
        h, w = f.mask.shape
        small = cv2.resize(f.mask.astype(np.uint8), None, fx=self.share, fy=self.share)
        other = np.zeros((h, w), dtype=np.uint8)
        other[h - small.shape[0] :, : small.shape[1]] = small
        return dataclasses.replace(f, mask=np.hstack([f.mask, other > 0]))

    def close(self) -> None:
        self.inner.close()


def test_another_person_in_view_is_said_and_the_largest_followed(setup) -> None:
    """Two people in a silhouette video: the avatar follows the larger, as it follows
    one person alone, and the log says at each decision that more than one was in view;
    someone much smaller (less than half the area) is not counted."""
    lib, layer, bank = setup
    settings = PerformSettings(seconds=6.0)
    alone = perform(VideoSource(RECORDING, silhouette=True), layer, bank, lib.clips, settings)
    two = perform(_TwoPeople(0.9), layer, bank, lib.clips, settings)
    made = [d for d in two.decisions if d.get("decision") is not None]
    assert made and all(d.get("people_in_view") == 2 for d in made)
    assert not any("people_in_view" in d for d in alone.decisions)
    far = perform(_TwoPeople(0.6), layer, bank, lib.clips, settings)  # 0.36 of the area
    assert not any("people_in_view" in d for d in far.decisions)
    # the larger is the performer: the avatar does what it does alone, decision for decision
    same = sum(
        a.get("frame") == b.get("frame")
        for a, b in zip(alone.decisions, two.decisions, strict=True)
    )
    assert same == len(alone.decisions), same  # (its silhouette is the same: all 60)


def test_a_library_too_large_to_search_by_brute_force_waits_for_a_whole_window(
    setup, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("vision._search.EARLY_WINDOWS", 0)
    r = _run(setup, VideoSource(RECORDING, silhouette=True), seconds=3.0)
    assert [i for i, d in enumerate(r.decisions) if "located" in d] == [9]  # t = 1.0 s


def test_the_avatar_does_what_the_performer_does(setup) -> None:
    lib, layer, bank = setup
    r = perform(VideoSource(RECORDING, silhouette=True), layer, bank, lib.clips, seed=3)
    made = [d for d in r.decisions if d["decision"] is not None or d.get("en_route")]
    assert len(made) > 0.8 * len(r.decisions) and r.avatar.n_frames == pytest.approx(
        11.5 * 15, abs=2
    )
    # the avatar does what the performer did (13_29 against 13_30's labels) at a lag of
    # 1 s, with the default descriptor (multigrid): measured 0.31 on this one recording
    # (0.10 with the grid, 0.16 with Hu moments; descriptors are compared on folds of
    # many recordings by benchmarks/bench_recognition.py, not here)
    side = json.loads(Path(f"{RECORDING}.json").read_text())
    truth = lib.clip("13_30")
    agree = []
    for d in r.decisions:
        k = round((d["t"] - 1.0) * side["fps"])
        if 0 <= k < len(side["labels"]) and side["labels"][k]:
            agree.append(truth.label_at(d["frame"]) == side["labels"][k])
    assert len(agree) > 100
    assert np.mean(agree) > 0.25


def test_a_relocation_is_followed_to_its_window(setup) -> None:
    # relocate whenever the whole component has a better window than the candidates
    match = MatchSettings(
        paths=PathSettings(relocate_ratio=1.0), landing=LandingSettings(jumps=False)
    )
    a = _run(setup, VideoSource(RECORDING, silhouette=True), match=match)
    # the decisions on the way leave it alone
    hist = a.avatar.history()[0]
    moves = [i for i, d in enumerate(a.decisions) if "relocated" in d]
    assert moves
    for i in moves:
        target = a.decisions[i]["relocated"]
        k = round(a.decisions[i]["t"] * 15) - a.decisions[9]["t"] * 15
        after = a.decisions[i + 1 :]
        if all(d.get("en_route") for d in after):
            continue  # the recording ended on the way
        assert target in hist[int(k) :]
        assert a.decisions[i + 1].get("en_route") or target == a.decisions[i + 1]["frame"]


def test_no_silhouette_stretch_keeps_the_avatar_moving(setup, tmp_path: Path) -> None:
    cap = cv2.VideoCapture(str(RECORDING))
    for i in range(180):  # 6 s; frames 60-119 are empty (nobody in view)
        ok, img = cap.read()
        assert ok
        mask = img[..., 0] if not 60 <= i < 120 else np.zeros(img.shape[:2], dtype=np.uint8)
        cv2.imwrite(str(tmp_path / f"{i:04d}.png"), mask)
    # (without relocation, whose way the avatar may still be following in the gap)
    r = _run(
        setup,
        MaskFolderSource(tmp_path, fps=30),
        match=MatchSettings(paths=PathSettings(relocate_every=0)),
    )
    assert r.avatar.n_frames == pytest.approx(5.5 * 15, abs=2)  # from the first half second
    # decisions go on while half the 1 s window still has silhouettes, then stop
    gap = [d for d in r.decisions if 2.6 <= d["t"] <= 3.9]
    assert gap and all(d["decision"] is None and d["reason"] == "no silhouette" for d in gap)
    after = [d for d in r.decisions if d["t"] >= 5.2]
    assert any(d["decision"] is not None for d in after)  # back as soon as the buffer refills


class _Stalled:
    """The recording, with its media clock jumping 1.2 s ahead after 2 s: a camera that
    froze and came back."""

    def __init__(self) -> None:
        self.inner = VideoSource(RECORDING, silhouette=True)
        self.name = "stalled"

    def read(self):  # type: ignore[no-untyped-def]
        frame = self.inner.read()
        if frame is not None and frame.t > 2.0:
            frame = dataclasses.replace(frame, t=frame.t + 1.2)
        return frame

    def close(self) -> None:
        self.inner.close()


def test_decisions_after_a_stall_are_skipped_not_bunched(setup) -> None:
    r = _run(
        setup, _Stalled(), seconds=5.0, match=MatchSettings(paths=PathSettings(relocate_every=0))
    )
    times = [d["t"] for d in r.decisions]
    assert all(b > a for a, b in itertools.pairwise(times))  # never two on one frame
    skipped = [d for d in r.decisions if "skipped" in d]
    assert len(skipped) == 1 and 2.0 < skipped[0]["t"] < 3.4
    assert skipped[0]["skipped"] == 11  # the 1.2 s missed, less the one made
    assert len(r.decisions) + 11 == pytest.approx(50, abs=1)
    # the avatar kept its clock across the stall: it is as long as the media from where
    # the performer was first located
    start = next(d["t"] for d in r.decisions if "located" in d)
    assert r.avatar.n_frames == pytest.approx((r.media_seconds - start) * 15, abs=3)


class _DyingCapture:
    """Serves the recording, then dies for good after 15 frames (half a second)."""

    def __init__(self) -> None:
        self.cap = cv2.VideoCapture(str(RECORDING))
        self.n = 0

    def isOpened(self) -> bool:
        return True

    def read(self) -> tuple[bool, np.ndarray | None]:
        self.n += 1
        return (False, None) if self.n > 15 else self.cap.read()

    def release(self) -> None:
        pass


def test_a_camera_that_fails_mid_run_does_not_stop_the_avatar(setup) -> None:
    opened = {"n": 0}

    def opener() -> object:
        opened["n"] += 1
        return _DyingCapture() if opened["n"] == 1 else None

    cam = CameraSource(0, fps=30.0, opener=opener, min_backoff=0.05, max_backoff=0.2)
    r = _run(setup, cam, seconds=1.25)  # 0.75 s after the camera died
    # the avatar played on at 15 frames a second (7.5 of them before the camera died)
    assert r.media_seconds >= 1.2 and r.avatar.n_frames >= 17
    assert opened["n"] >= 2 and cam.reconnects == 1


@pytest.mark.slow
def test_cli_perform_writes_bvh_log_and_video(mocap: Path, tmp_path: Path, capsys) -> None:
    # outputs into folders that do not exist yet
    out, log, video = tmp_path / "a" / "a.bvh", tmp_path / "b" / "d.jsonl", tmp_path / "c" / "v.mp4"
    argv = [
        "perform",
        "--video",
        str(RECORDING),
        str(mocap),
        "--clips",
        "13_30",
        "--k",
        "12",
        "--seconds",
        "4",
        "--out",
        str(out),
        "--log",
        str(log),
        "--video-out",
        str(video),
    ]
    assert main(argv) == 0
    lines = [json.loads(x) for x in log.read_text().splitlines()]
    assert len(lines) == 40 and {"t", "frame", "decision"} <= set(lines[-1])
    assert read_bvh(out).n_frames >= 40
    cap = cv2.VideoCapture(str(video))
    assert cap.isOpened() and int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) >= 40
    assert (cap.get(cv2.CAP_PROP_FRAME_WIDTH), cap.get(cv2.CAP_PROP_FRAME_HEIGHT)) == (1280, 480)
    frames = []
    while (got := cap.read())[0]:
        frames.append(got[1])
    cap.release()
    last = frames[-1].astype(int)
    assert (last[:, :640] > 200).all(axis=2).mean() > 0.01  # the performer's silhouette
    right = last[60:, 640:]
    floor = np.abs(right - (52, 44, 40)).sum(axis=2) < 12  # the floor...
    assert floor.mean() > 0.3
    assert (np.abs(right - (96, 88, 82)).sum(axis=2) < 30).mean() > 0.005  # ...its grid
    body = (right > 110).all(axis=2) & ~floor
    assert body.mean() > 0.01  # and the avatar on it
    said = capsys.readouterr().out
    # the recording's sidecar is its truth: the summary says what the avatar did, and how
    # well it agreed
    assert "the avatar did: " in said and "agreement with " in said
    assert (
        main(["perform", "--video", str(tmp_path / "none.mp4"), str(mocap), "--clips", "13_30"])
        == 2
    )
    assert "no such video file" in capsys.readouterr().err
    labels = tmp_path / "l.csv"
    labels.write_text("file,start,end,label\nother.mp4,0,1,Squat\n")
    argv = ["perform", "--video", str(RECORDING), str(mocap), "--labels", str(labels)]
    assert main(argv) == 2
    assert "l.csv: no labelled spans for 13_29_first12s_160x120.mkv" in capsys.readouterr().err


def test_a_bank_with_variants_reports_ring_views(setup, tmp_path: Path) -> None:
    lib, layer, _ = setup
    # (no metric: views are the point; a ring of 6, for speed)
    settings = BankSettings(CameraRing(n_views=6), shadow=True, metric=0)
    bank = build_bank(lib.clips, settings, tmp_path / "bank", workers=1)
    assert bank.features.shape[1] == 12
    matcher = Matcher(layer, bank, MatchSettings(window=1.0))
    _, _, starts = matcher.windows.tables()
    s = int(starts[len(starts) // 2])
    b = matcher.windows.to_bank[np.arange(s, s + matcher.n)]
    view = 6 + 5  # the shadowed variant of ring view 5
    feats = bank.features[b, view].astype(float)
    move = bank.root_motion[b, view].astype(float)
    centre = np.cumsum(move, axis=0) - move[0] + feats[:, -2:]
    got = matcher.find_window(np.concatenate((feats[:, :-2], centre), axis=1))
    assert got is not None and got[1] == 5 and got[2] < 1e-5
    d = matcher.decide(s, np.concatenate((feats[:, :-2], centre), axis=1))
    assert d is not None and 0 <= d.view < 6


def test_the_keep_clip_bonus_keeps_the_action_unless_another_fits_clearly_better(setup) -> None:
    _, layer, bank = setup
    plain = Matcher(layer, bank, MatchSettings(window=1.0, paths=PathSettings(lookahead=1.5)))
    keen = Matcher(
        layer,
        bank,
        MatchSettings(window=1.0, paths=PathSettings(lookahead=1.5, keep_clip_bonus=0.5)),
    )
    rng = np.random.default_rng(4)
    kept = changed = 0
    for f in rng.choice(np.flatnonzero(layer.graph.in_scc), 30, replace=False):
        cands = plain.paths.candidates(int(f))
        on = [c for c in cands if not (c[2][: plain.n - 1] >= 0).any()]
        if len(cands) < 2 or not on:
            continue
        # a performer between playing on and another candidate, nearer the other
        other = next(c for c in cands if (c[2][: plain.n - 1] >= 0).any())

        def seen(frames: np.ndarray) -> np.ndarray:
            b = plain.windows.to_bank[plain.paths.window_frames(frames)]
            feats = bank.features[b, 3].astype(float)
            move = bank.root_motion[b, 3].astype(float)
            centre = np.cumsum(move, axis=0) - move[0] + feats[:, -2:]
            return np.concatenate((feats[:, :-2], centre), axis=1)

        performer = 0.65 * seen(other[1]) + 0.35 * seen(on[0][1])
        a, k = plain.decide(int(f), performer), keen.decide(int(f), performer)
        assert a is not None and k is not None
        a_on = not (a.edges[: plain.n - 1] >= 0).any()
        k_on = not (k.edges[: plain.n - 1] >= 0).any()
        kept += k_on and not a_on
        changed += a_on and not k_on  # the prior never pushes away from playing on
    assert kept > 0 and changed == 0
    with pytest.raises(ValueError, match="keep_clip_bonus"):
        MatchSettings(paths=PathSettings(keep_clip_bonus=1.0))


def test_a_live_source_searches_in_the_background(setup) -> None:
    sync = _run(setup, VideoSource(RECORDING, silhouette=True), seconds=8.0)
    match = MatchSettings(
        paths=PathSettings(relocate_ratio=1.0), landing=LandingSettings(jumps=False)
    )  # relocate whenever it finds better
    source = VideoSource(RECORDING, silhouette=True)
    bg = _run(setup, source, background_search=True, match=match, seconds=8.0)
    # the same decision points; the search's answers come at later ones, so the avatar
    # may differ, but it is matched and relocated all the same
    assert [d["t"] for d in bg.decisions] == [d["t"] for d in sync.decisions]
    acted = [d for d in bg.decisions if d["decision"] is not None or d.get("en_route")]
    assert len(acted) > 0.8 * len(bg.decisions)
    assert any("relocated" in d or "relocation_unreachable" in d for d in bg.decisions)
    for _ in range(100):  # the search thread ends once its last search is done
        if not any(t.name.startswith("mimic-search") for t in threading.enumerate()):
            break
        time.sleep(0.05)
    else:
        raise AssertionError("the search thread outlived the run")
    # a paced file is live: the search goes to the background unless told otherwise
    assert VideoSource(RECORDING, silhouette=True, realtime=True).realtime


def test_garbage_is_rejected_and_the_log_says_why(setup) -> None:
    """Masks no person makes (noise) match nothing: the matcher gives no window and says
    why; the performer's own windows are not rejected."""
    _, layer, bank = setup
    matcher = Matcher(layer, bank, MatchSettings(window=1.0))
    rng = np.random.default_rng(4)
    cap = cv2.VideoCapture(str(RECORDING))
    real = []
    for _ in range(matcher.n * 2):
        ok, img = cap.read()
        assert ok
        real.append(silhouette_features(img[..., 0] > 127, descriptor=matcher.desc))
    cap.release()
    got = matcher.find_window(np.array(real[::2]))
    assert got is not None and matcher.why == ""
    noise = []
    for _ in range(matcher.n):
        m = (rng.random((120, 160)) < 0.5).astype(np.uint8)
        m[:10] = 0
        noise.append(silhouette_features(m, descriptor=matcher.desc))
    assert matcher.find_window(np.array(noise)) is None
    assert matcher.why.startswith("no match (cost")


def test_the_pose_descriptor_finds_a_skeletons_own_frame_and_view(setup, tmp_path: Path) -> None:
    """The avatar's joints projected by a ring camera, as landmarks: locate finds that
    frame and view (read as seen, the default; with ``mirror``, mirrored too, and with
    left and right swapped, as a detector may give them); the same landmarks upside down
    match nothing."""
    from silhouette_bank import CameraRing, get_descriptor
    from silhouette_bank._pose import joint_points

    lib, layer, _ = setup
    bank = build_bank(lib.clips, BankSettings(descriptor="pose"), tmp_path / "pose", workers=1)
    matcher = Matcher(layer, bank, MatchSettings(window=1.0))
    every = Matcher(layer, bank, MatchSettings(window=1.0, mirror=True))  # four readings
    desc = get_descriptor("pose")
    _, _, starts = matcher.windows.tables()
    # windows inside the graph's component (the sample this test was written with)
    starts = np.array([s for s in starts if layer.graph.in_scc[s : s + matcher.n].all()])
    clip = lib.clip("13_30")
    ring = CameraRing()
    rng = np.random.default_rng(11)
    for s in rng.choice(starts, 6, replace=False):
        frames = np.arange(s, s + matcher.n)
        view = int(rng.integers(18))
        pts = joint_points(clip.motion, frames)
        # a static camera where the ring's view stood at the window's first frame
        pose = ring.poses(clip.motion.root_pos[frames[0]])[view]
        px = ring.project(ring.to_camera(pts, np.broadcast_to(pose, (frames.size, 4, 4))))
        x = desc.from_points(px)  # the image corner as origin, as on the live side
        got = matcher.find_window(x)
        assert got is not None and abs(got[0] - s) <= 1
        assert got[1] == view and matcher.per_frame(got[2], x) < 0.5
        for reading in (x, desc.swap(x), desc.mirror(x)):
            got = every.find_window(reading)
            assert got is not None and abs(got[0] - s) <= 1
        upside = x.copy()
        upside[:, 1 : desc.n_shape : 2] *= -1.0
        assert matcher.find_window(upside) is None and "no match" in matcher.why


def test_perform_with_landmarks_logs_why_a_frame_has_no_pose(
    setup, mocap: Path, tmp_path: Path
) -> None:
    """Colour footage with the pose descriptor: decisions from MediaPipe's landmarks;
    a stretch with nobody in view makes none, and the log says why."""
    from vision import person_segmentation_available

    if not person_segmentation_available():
        pytest.fail("MediaPipe is needed here (see the README's install line)")
    lib, layer, _ = setup
    bank = build_bank(lib.clips, BankSettings(descriptor="pose"), tmp_path / "pose", workers=1)
    cap = cv2.VideoCapture(str(mocap.parent / "video" / "pose_squats.mp4"))
    frames = []
    while len(frames) < 40:
        ok, img = cap.read()
        assert ok
        frames.append(img)
    cap.release()
    h, w = frames[0].shape[:2]
    frames[20:30] = [np.full((h, w, 3), 90, np.uint8)] * 10  # 2 s with nobody in view
    path = tmp_path / "squats.avi"
    out = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"MJPG"), 5.0, (w, h))
    for img in frames:
        out.write(img)
    out.release()
    r = perform(VideoSource(path), layer, bank, lib.clips, seed=1)
    made = [d for d in r.decisions if d.get("decision") is not None]
    assert len(made) > 20
    gone = [d for d in r.decisions if 4.6 <= d["t"] <= 5.8]
    assert gone and all(d["decision"] is None for d in gone)
    assert {d["reason"] for d in gone} <= {"nobody in view", "no pose", "en route"}
    assert any(d["reason"] == "nobody in view" for d in gone)
    # a silhouette video cannot feed landmarks: a clear error naming it
    with pytest.raises(ValueError, match="pose descriptor needs colour frames"):
        perform(VideoSource(RECORDING, silhouette=True), layer, bank, lib.clips)


def test_the_default_descriptor_follows_the_source(mocap: Path) -> None:
    from mimic.run import choose_descriptor

    silhouettes = VideoSource(RECORDING, silhouette=True)
    colour = VideoSource(mocap.parent / "video" / "pose_1.mp4")
    assert choose_descriptor("auto", silhouettes) == "outline"
    assert choose_descriptor("auto", colour) == "pose"  # MediaPipe is installed in CI
    assert choose_descriptor("hu", colour) == "hu"
    with pytest.raises(SystemExit, match="pose descriptor needs colour frames"):
        choose_descriptor("pose", silhouettes)
    silhouettes.close()
    colour.close()


@pytest.mark.slow
def test_the_demo_runs_on_the_embedded_library_where_no_other_exists(
    mocap: Path, monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys
) -> None:
    """No $MIMIC_MOCAP and no ../shared/mocap: the README's main job (the squats video)
    runs on the embedded library, and says so. (Two of its clips here; ``.ci/run`` runs
    it on all nine.)"""
    from control.motion import _library

    monkeypatch.delenv("MIMIC_MOCAP", raising=False)
    monkeypatch.setattr(_library, "shared_library_candidates", lambda: (tmp_path / "none",))
    out = tmp_path / "a.bvh"
    video = mocap.parent / "video" / "pose_squats.mp4"
    argv = ["perform", "--video", str(video), "--seconds", "3", "--out", str(out)]
    assert main([*argv, "--clips", "02_0[12]"]) == 0
    said = capsys.readouterr()
    assert f"motion library: the embedded default library ({EMBEDDED_LIBRARY})" in said.err
    assert "library: 2 clips" in said.err and "descriptor: pose" in said.err
    assert read_bvh(out).n_frames >= 30
    assert len(load_library(EMBEDDED_LIBRARY).clips) == 9
    # named by $MIMIC_MOCAP, it is a library like any other: nothing to say
    monkeypatch.setenv("MIMIC_MOCAP", str(EMBEDDED_LIBRARY))
    argv[argv.index("--seconds") + 1] = "1"  # (a second is enough to say it or not)
    assert main([*argv, "--clips", "02_0[12]"]) == 0
    assert "the embedded default library" not in capsys.readouterr().err


def test_the_avatar_blends_over_the_blend_asked_for(setup) -> None:
    lib, layer, bank = setup
    settings = PerformSettings(seconds=1.5, blend=0.4)
    r = perform(VideoSource(RECORDING, silhouette=True), layer, bank, lib.clips, settings)
    assert r.avatar.blend_settings.seconds == 0.4
    assert r.avatar.motion().motion.n_frames == r.avatar.n_frames


@pytest.mark.slow
def test_perform_uses_a_bank_built_with_other_settings(mocap: Path, tmp_path: Path, capsys) -> None:
    folder = tmp_path / "bank12"
    build = [
        "bank",
        "build",
        str(mocap),
        "--clips",
        "13_30",
        "--views",
        "12",
        "--descriptor",  # (Hu moments: no metric to learn, a quick build)
        "hu",
        "--bank",
        str(folder),
    ]
    assert main(build) == 0
    log = tmp_path / "d.jsonl"
    run = ["perform", "--video", str(RECORDING), str(mocap), "--k", "12", "--seconds", "3"]
    assert main([*run, "--clips", "13_30", "--bank", str(folder), "--log", str(log)]) == 0
    assert f"descriptor: hu (the bank's, {folder})" in capsys.readouterr().err
    views = {json.loads(x).get("view") for x in log.read_text().splitlines()} - {None}
    assert views and max(views) < 12  # the 12-view bank's cameras, not the default 18
    # another library than the bank's is a clear error naming the folder
    assert main([*run, "--clips", "13_29", "--bank", str(folder)]) == 2
    err = capsys.readouterr().err
    assert str(folder) in err and "built from another motion library" in err


def test_a_large_librarys_unreachable_clips_are_counted_not_all_named(capsys) -> None:
    """A library of a thousand clips, 300 of them mostly outside the graph's component:
    the note names 8 and counts the rest (it listed every one, screens of names)."""
    from types import SimpleNamespace

    from mimic.run import _say_unreachable

    starts = np.arange(0, 1001 * 10, 10)
    in_scc = np.ones(starts[-1], dtype=bool)
    for i in range(0, 900, 3):  # every third clip of the first 900: 300 clips
        in_scc[starts[i] : starts[i] + 8] = False
    graph = SimpleNamespace(
        clip_names=[f"clip{i}" for i in range(1000)], clip_start=starts, in_scc=in_scc
    )
    _say_unreachable(graph, no_jumps=False)  # type: ignore[arg-type]
    err = capsys.readouterr().err
    assert err.startswith("note: 300 of 1000 clips are mostly outside")
    assert "clip0 (20% reachable), clip3 (20% reachable)" in err
    assert err.count("reachable)") == 8 and "... and 292 more" in err
    _say_unreachable(graph, no_jumps=True)  # type: ignore[arg-type]
    assert capsys.readouterr().err.startswith("warning: 300 of 1000 clips")
