"""The fast whole-library window search against brute force."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest

from benchmarks._landmarks import landmark_points
from control.dtw import dtw, dtw_windows
from control.motion import action_keys
from silhouette_bank import silhouette_features
from tests.vision.conftest import RECORDING
from vision import (
    ActionVote,
    Matcher,
    MatchSettings,
    RecordSettings,
    VideoSource,
    WindowIndex,
    best_window,
    cached_window_index,
)
from vision import _index as index_module
from vision import _tables as tables_module
from vision._index import best_of
from vision._summaries import _bounds, _run_summaries, _summaries


def _performer(bank) -> np.ndarray:
    """Features of the committed recording (13_29: another take than the library's)."""
    src = VideoSource(RECORDING, silhouette=True)
    out = []
    while (f := src.read()) is not None:
        if f.index % 2 == 0:  # 30 -> 15 frames/s
            out.append(
                silhouette_features(
                    np.asarray(f.mask, np.uint8), descriptor=bank.settings.descriptor
                )
            )
    src.close()
    return np.array(out)


def _inverted_file(setup) -> tuple[Matcher, WindowIndex, np.ndarray]:
    """The matcher of the test library, an inverted-file index of its windows, and the
    action of each of its frames."""
    lib, layer, bank = setup
    m = Matcher(layer, bank, MatchSettings())
    index = WindowIndex(*m.windows.tables(), m.n, flat_below=0)
    keys = action_keys(lib.clips)
    assert keys is not None
    return m, index, keys


def test_dtw_windows_is_dtw_of_each_window(setup, rng) -> None:
    _, layer, bank = setup
    m = Matcher(layer, bank)
    shape, centre, starts = m.windows.tables()
    s = rng.choice(starts, 20)
    v = rng.integers(0, shape.shape[1], 20)
    q = rng.normal(size=(m.n - 3, shape.shape[2] + 2))
    got = dtw_windows(q, shape, centre, s, v, m.n, 4)
    for k in range(20):
        w = np.concatenate(
            (shape[s[k] : s[k] + m.n, v[k]], centre[s[k] : s[k] + m.n, v[k]] - centre[s[k], v[k]]),
            axis=1,
        )
        assert got[k] == pytest.approx(dtw(q, w, 4), rel=1e-12)
    with pytest.raises(ValueError, match="inside"):
        dtw_windows(q, shape, centre, np.array([shape.shape[0]]), np.array([0]), m.n, 4)


def test_index_finds_the_brute_force_best(setup) -> None:
    """A flat scan (``flat_below`` above the index's size) and an inverted file (0), each
    against the one brute force."""
    _, layer, bank = setup
    m = Matcher(layer, bank, MatchSettings())
    shape, centre, starts = m.windows.tables()
    indexes = [WindowIndex(shape, centre, starts, m.n, flat_below=f) for f in (100_000, 0)]
    for index, flat_below in zip(indexes, (100_000, 0), strict=True):
        assert index.size == starts.size * shape.shape[1]
        assert (index.nprobe == 0) == (flat_below > index.size)
    perf = _performer(bank)
    rng = np.random.default_rng(5)
    hits = [0, 0]
    total = 0
    for end in range(m.n, perf.shape[0] + 1, 2):
        window = perf[end - m.n : end].copy()
        if end % 6 == 0:  # some frames without a silhouette: a shorter query
            window[rng.choice(m.n, 4, replace=False)] = np.nan
        queries = m.queries(window)
        assert queries is not None
        b = best_window(queries, shape, centre, starts, m.n, m.settings.band, m.settings.recency)
        total += 1
        for k, index in enumerate(indexes):
            c = index.search(queries, m.settings.band, recency=m.settings.recency)[0][2]
            hits[k] += c <= b[2] + 1e-9
            assert c >= b[2] - 1e-9  # never better than the exact best: the cost is exact DTW
    assert total >= 80 and min(hits) >= 0.99 * total, hits


@pytest.mark.parametrize(("mirror", "readings"), [(None, 1), (True, 4)])
def test_the_pose_descriptors_readings_find_the_brute_force_best(
    setup, mocap, tmp_path, mirror, readings
) -> None:
    """Landmarks read as seen (the default), or four ways (as seen, left and right
    swapped, both mirrored: they share the short list two readings get): the exact best
    window in >= 99% of searches (13_29's joints on another body, another camera, 3%
    noise; the library 13_30)."""
    from control.motion import load_library
    from silhouette_bank import BankSettings, build_bank

    lib, layer, _ = setup
    bank = build_bank(lib.clips, BankSettings(descriptor="pose"), tmp_path / "pose", workers=1)
    m = Matcher(layer, bank, MatchSettings(mirror=mirror))
    shape, centre, starts = m.windows.tables()
    index = WindowIndex(shape, centre, starts, m.n, flat_below=0)
    clip = load_library(mocap, fps=layer.graph.fps, clips=["13_29"]).clip("13_29")
    rng = np.random.default_rng(2)
    px = landmark_points(clip.motion, RecordSettings(), rng, frames=np.arange(0, 300))  # 20 s
    perf = m.desc.from_points(px)
    hits = total = 0
    for end in range(m.n, perf.shape[0] + 1, 2):
        queries = m.queries(perf[end - m.n : end])
        assert queries is not None and len(queries) == readings
        b = best_window(queries, shape, centre, starts, m.n, m.settings.band, m.settings.recency)
        total += 1
        hits += (
            index.search(queries, m.settings.band, recency=m.settings.recency)[0][2] <= b[2] + 1e-9
        )
    assert total >= 100 and hits >= 0.99 * total, (hits, total)


def test_index_top_windows_are_distinct_and_sorted(setup) -> None:
    _, layer, bank = setup
    m = Matcher(layer, bank)
    perf = _performer(bank)
    got = m.search(perf[:15], top=6)
    assert 1 <= len(got) <= 6
    assert len({g[0] for g in got}) == len(got)
    assert [g[2] for g in got] == sorted(g[2] for g in got)
    assert m.find_window(perf[:15]) == (got[0][0], got[0][1] % 18, got[0][2])


@pytest.mark.parametrize("flat_below", [100_000, 0])  # a flat scan; an inverted file
def test_a_stored_index_is_the_built_one(setup, tmp_path, caplog, flat_below) -> None:
    _, layer, bank = setup
    m = Matcher(layer, bank, MatchSettings())
    shape, centre, starts = m.windows.tables()
    built = cached_window_index(shape, centre, starts, m.n, tmp_path, flat_below=flat_below)
    (stored,) = tmp_path.glob("index-*.npz")
    loaded = cached_window_index(shape, centre, starts, m.n, tmp_path, flat_below=flat_below)
    assert loaded.size == built.size and loaded.nprobe == built.nprobe
    for q in m.queries(_performer(bank)[:30]) or []:  # the matcher's own queries
        assert loaded.search([q], 4, top=5) == built.search([q], 4, top=5)
    # other tables, or other options: another file
    cached_window_index(shape, centre, starts[1:], m.n, tmp_path, flat_below=flat_below)
    assert len(list(tmp_path.glob("index-*.npz"))) == 2
    # a damaged file is built again, with a warning naming it
    data = bytearray(stored.read_bytes())
    data[len(data) // 2] ^= 0xFF
    stored.write_bytes(bytes(data))
    with caplog.at_level(logging.WARNING):
        again = cached_window_index(shape, centre, starts, m.n, tmp_path, flat_below=flat_below)
    assert str(stored) in caplog.text and again.size == built.size
    # a folder that cannot be written (here a file's name: even root cannot): built, not
    # stored, no error
    blocked = tmp_path / "a-file"
    blocked.write_text("")
    assert cached_window_index(shape, centre, starts, m.n, blocked).size == built.size


def test_indexes_go_with_their_tables_and_the_least_used_first(setup, tmp_path) -> None:
    import os

    _, layer, bank = setup
    m = Matcher(layer, bank, MatchSettings())
    shape, centre, starts = m.windows.tables()
    old, new = "a" * 40, "b" * 40  # two sets of window tables' keys
    (tmp_path / f"windows-{old[:24]}.json").write_text("{}")
    keep = tables_module.KEEP_INDEXES

    def stored(key: str) -> set[Path]:
        return set(tmp_path.glob(f"index-{key[:24]}-*.npz"))

    def build(key: str, i: int) -> Path:
        """The file of the index of ``key``'s tables less their first ``i`` windows."""
        before = stored(key)
        cached_window_index(shape, centre, starts[i:], m.n, tmp_path, key=key)
        return (stored(key) - before).pop() if stored(key) - before else Path()

    files = [build(old, i) for i in range(keep)]
    for n, f in enumerate(files):  # used in this order (a clock tick may hold them all)
        os.utime(f, ns=(n * 10**9, n * 10**9))
    assert build(old, 0) == Path()  # read, not built: now the most recently used
    kept = build(old, keep)  # one more than kept: the least recently used goes
    assert stored(old) == {files[0], *files[2:], kept}
    # the tables go: their indexes and a stopped build's parts go with them at the next
    # index stored, and so does an older version's index (no tables' key in its name)
    parts = tmp_path / f"index-{old[:24]}-{'c' * 24}.parts"
    parts.mkdir()
    (parts / "job-0.npz").write_bytes(b"x")
    legacy = tmp_path / f"index-{'d' * 24}.npz"
    legacy.write_bytes(b"x")
    (tmp_path / f"windows-{old[:24]}.json").unlink()
    (tmp_path / f"windows-{new[:24]}.json").write_text("{}")
    build(new, 0)
    assert stored(old) == set() and not parts.exists() and not legacy.exists()
    assert len(stored(new)) == 1


def test_the_principal_axes_are_the_svds(rng) -> None:
    from vision._index import _principal_axes

    # rows of distinct variances along 12 random directions, plus noise
    q, _ = np.linalg.qr(rng.standard_normal((40, 40)))
    x = (rng.standard_normal((3000, 12)) * np.linspace(9.0, 2.0, 12)) @ q[:12]
    x += 0.1 * rng.standard_normal(x.shape)
    x -= x.mean(axis=0)
    axes = _principal_axes(x, 8)
    _, _, vt = np.linalg.svd(x, full_matrices=False)
    assert axes.shape == (40, 8) and axes.dtype == np.float32
    # the same axes, in the same order, up to each one's sign; the sign is fixed
    np.testing.assert_allclose(np.abs(np.sum(axes * vt[:8].T, axis=0)), 1.0, atol=1e-5)
    top = np.abs(axes).argmax(axis=0)
    assert np.all(axes[top, np.arange(8)] > 0)
    np.testing.assert_array_equal(_principal_axes(-x, 8), axes)


@pytest.mark.parametrize(
    ("flat_below", "subset_flat"),
    # a flat scan; an inverted file, the flagged windows in a flat index of their own;
    # an inverted file searched with a bitmap of them
    [(100_000, 20_000), (0, 20_000), (0, 0)],
)
def test_a_search_within_flagged_starts_finds_their_brute_force_best(
    setup, flat_below, subset_flat, monkeypatch
) -> None:
    """``only``: the windows after which the library shows one action (the vote's gate),
    against brute force over just those."""
    monkeypatch.setattr(index_module, "SUBSET_FLAT", subset_flat)
    lib, layer, bank = setup
    m = Matcher(layer, bank, MatchSettings())
    shape, centre, starts = m.windows.tables()
    index = WindowIndex(shape, centre, starts, m.n, flat_below=flat_below)
    keys = action_keys(lib.clips)
    assert keys is not None
    clip = lib.clips[0]
    squat = next(f for f in range(clip.motion.n_frames) if clip.label_at(f) == "Squat")
    vote = ActionVote(1, m.n // 2)
    vote.actions = keys
    vote.cast(np.array([squat + m.n]))
    only = vote.starts(m.n)
    allowed = starts[only[starts]]
    assert 0 < allowed.size < starts.size / 3
    hits = total = 0
    perf = _performer(bank)
    for end in range(m.n, perf.shape[0] + 1, 4):
        queries = m.queries(perf[end - m.n : end])
        assert queries is not None
        got = index.search(queries, m.settings.band, top=4, only=only, recency=m.settings.recency)
        assert got and all(only[g[0]] for g in got)
        b = best_window(queries, shape, centre, allowed, m.n, m.settings.band, m.settings.recency)
        total += 1
        hits += got[0][2] <= b[2] + 1e-9
    assert total >= 40 and hits >= 0.95 * total, (hits, total)
    assert bool(index._flat) == (flat_below == 0 and subset_flat > 0)
    with pytest.raises(ValueError, match="each of the"):
        index.search(queries, m.settings.band, only=only[:-1])


def test_summaries_of_runs_of_starts_are_the_summaries(setup, rng) -> None:
    """``_run_summaries`` (prefix sums over each run of starts) gives what ``_summaries``
    (a gather a frame) gives, in every view, runs broken anywhere."""
    _, layer, bank = setup
    m = Matcher(layer, bank, MatchSettings())
    shape, centre, starts = m.windows.tables()
    bounds = _bounds(m.n, 5)
    pick = np.sort(rng.choice(starts, 40, replace=False))
    pick = np.unique(np.concatenate((pick, starts[10:30])))  # one long run too
    want = _summaries(shape, centre, pick, m.n, bounds)
    np.testing.assert_allclose(_run_summaries(shape, centre, pick, m.n, bounds), want, atol=1e-5)


def test_each_action_s_search_is_made_ready_at_once(setup, monkeypatch) -> None:
    """``ActionVote.window_actions`` names the action each window start counts for, as
    ``starts`` flags them for the voted one; ``WindowIndex.prepare`` makes each action's
    search ready before a decision asks for it, within ``FLAT_ROWS``, and the search a
    decision then makes is the one made."""
    m, index, keys = _inverted_file(setup)
    bank, (shape, centre, starts) = setup[2], m.windows.tables()
    vote = ActionVote(1, m.n // 2)
    vote.actions = keys
    each = vote.window_actions(m.n)
    for action in np.unique(keys):
        vote.voted = int(action)
        np.testing.assert_array_equal(vote.starts(m.n), each == action)
    index.prepare(each)
    present = np.unique(each[starts][each[starts] >= 0])
    assert len(present) >= 5 and len(index._flat) == len(present)  # one flat index each
    made = dict(index._flat)
    vote.voted = int(present[0])
    perf = _performer(bank)
    queries = m.queries(perf[: m.n])
    assert queries is not None
    index.search(queries, m.settings.band, only=vote.starts(m.n))
    assert index._flat == made and not index._selected  # (the one made, not another)
    # past the budget, nothing more is made beforehand (the bitmap search, when asked)
    small = WindowIndex(shape, centre, starts, m.n, flat_below=0)
    monkeypatch.setattr(index_module, "FLAT_ROWS", 0)
    small.prepare(each)
    assert not small._flat and not small._selected


def test_the_best_flagged_windows_of_a_search_s_short_lists(setup) -> None:
    """``ranked`` keeps every short-listed window's exact DTW cost; ``best_of`` ranks them
    again, all (the search's own answer) or only the flagged ones (what the vote looks for
    before searching its action's windows alone): the cheapest flagged windows there,
    one per start, cheapest first."""
    m, index, keys = _inverted_file(setup)
    bank = setup[2]
    perf = _performer(bank)
    queries = m.queries(perf[: m.n])
    assert queries is not None
    ranked: list = []
    got = index.search(queries, m.settings.band, top=8, ranked=ranked, recency=m.settings.recency)
    assert len(ranked) == len(queries) and best_of(ranked, 8) == got
    only = np.zeros(keys.size, dtype=bool)
    only[np.unique(np.concatenate([s for s, _, _ in ranked]))[1::3]] = True  # a third
    flagged = best_of(ranked, 5, only)
    assert len(flagged) == 5 and all(only[s] for s, _, _ in flagged)
    assert len({s for s, _, _ in flagged}) == 5
    want = sorted(
        min((float(c[k]), int(s[k])) for s, _, c in ranked for k in np.flatnonzero(s == st))
        for st in np.flatnonzero(only)
    )[:5]
    assert [(c, s) for s, _, c in flagged] == [(c, s) for c, s in want]
    assert best_of(ranked, 5, np.zeros_like(only)) == []


@pytest.mark.parametrize("flat_below", [100_000, 0])  # a flat scan; an inverted file
def test_an_index_filled_in_small_chunks_is_the_one_filled_at_once(
    setup, monkeypatch, flat_below
) -> None:
    """The index is filled a chunk of starts at a time (its inverted file's training rows
    picked out on the way, the summaries kept as parts and encoded in jobs): in chunks
    of 7 starts, it is the index trained and filled from every window's summary at once
    by faiss's own ``add``, answer for answer and, an inverted file, byte for byte."""
    import faiss

    from vision import _index

    _, layer, bank = setup
    m = Matcher(layer, bank)
    shape, centre, starts = m.windows.tables()
    monkeypatch.setattr(_index, "_CHUNK", 7)
    chunked = WindowIndex(shape, centre, starts, m.n, flat_below=flat_below)
    z = np.vstack(list(chunked._projected_chunks()))  # every summary (mean and axes: chunked's)
    assert z.shape[0] == chunked.size == starts.size * m.windows.ring_views
    rng = np.random.default_rng(0)  # (the build's seed, drawn as the build draws)
    rng.choice(z.shape[0], min(z.shape[0], 50_000), replace=False)  # (the PCA's sample)
    if flat_below:
        assert chunked.nprobe == 0
        at_once = faiss.IndexFlatL2(z.shape[1])
    else:
        nlist = int(chunked.index.nlist)
        at_once = faiss.IndexIVFScalarQuantizer(
            faiss.IndexFlatL2(z.shape[1]), z.shape[1], nlist, faiss.ScalarQuantizer.QT_8bit
        )
        at_once.cp.seed = 0
        at_once.train(z[rng.choice(z.shape[0], min(z.shape[0], 64 * nlist), replace=False)])
        at_once.nprobe = chunked.nprobe
    at_once.add(z)
    if not flat_below:  # (the encoding jobs' codes are faiss's own)
        assert np.array_equal(faiss.serialize_index(at_once), faiss.serialize_index(chunked.index))
    for s in np.random.default_rng(3).choice(starts, 20, replace=False):
        q = np.concatenate((shape[s : s + m.n, 2], centre[s : s + m.n, 2]), axis=1)
        x = chunked.summary(q)
        for k in (1, 10, 96):
            np.testing.assert_array_equal(at_once.search(x, k)[1], chunked.index.search(x, k)[1])


@pytest.mark.parametrize("flat_below", [100_000, 0])  # a flat scan; an inverted file
def test_an_index_being_made_says_how_far_it_is(setup, tmp_path, monkeypatch, flat_below) -> None:
    """``progress(done, total)`` counts windows: the flat index's as each chunk is
    added, the inverted file's half a window as each job's are summarised and half as
    they are added; nothing when the index is read. The index is the one made without."""
    from vision import _index
    from vision import _summaries as summaries_module

    _, layer, bank = setup
    m = Matcher(layer, bank)
    shape, centre, starts = m.windows.tables()
    monkeypatch.setattr(_index, "_CHUNK", 50)
    monkeypatch.setattr(summaries_module, "JOB_STARTS", 50)
    calls: list[tuple[int, int]] = []

    def cached() -> WindowIndex:
        return cached_window_index(
            shape,
            centre,
            starts,
            m.n,
            tmp_path,
            progress=lambda *c: calls.append(c),
            flat_below=flat_below,
        )

    made = cached()
    rows = made.size
    chunks = -(-starts.size // 50)
    assert len(calls) == chunks * (1 if flat_below else 2)
    assert calls[-1] == (rows, rows) and {t for _, t in calls} == {rows}
    assert [d for d, _ in calls] == sorted(d for d, _ in calls)
    if not flat_below:  # every summary taken: half way
        assert calls[chunks - 1][0] == rows // 2
    plain = WindowIndex(shape, centre, starts, m.n, flat_below=flat_below)
    for s in np.random.default_rng(3).choice(starts, 10, replace=False):
        q = np.concatenate((shape[s : s + m.n, 2], centre[s : s + m.n, 2]), axis=1)
        assert made.search([q], 4, top=5) == plain.search([q], 4, top=5)
    calls.clear()
    cached()  # (read: nothing made)
    assert calls == []


def test_a_search_opened_with_bars_shows_its_tables_and_index_being_made(setup) -> None:
    """``WindowSearch.open(bars)``: a bar for the tables (frames) and one for the index
    (windows) where they are made (a bank in memory: nothing stored to read)."""
    import dataclasses

    _, layer, bank = setup
    in_memory = dataclasses.replace(bank, path="")
    m = Matcher(layer, in_memory)
    seen: dict[str, list[tuple[int, int]]] = {}

    def bars(label: str, unit: str):
        return lambda done, total: seen.setdefault(f"{label} ({unit})", []).append((done, total))

    index = m.windows.open(bars, "search")
    n = layer.graph.n_frames
    assert seen["search: window tables (frames)"][-1] == (n, n)
    assert seen["search: window index (windows)"][-1] == (index.size, index.size)
    assert m.windows.index() is index  # (opened once)


def test_a_stopped_index_build_resumes_from_the_jobs_it_finished(
    setup, tmp_path, monkeypatch, caplog
) -> None:
    """The inverted file's summaries are taken in jobs, each kept as a part beside the
    index's file: a build stopped after 2 of its jobs runs only the others when it runs
    again (a damaged part is said and run again), and gives the index of one build,
    list for list; the parts are gone once the index is stored."""
    import faiss

    from vision import _summaries as summaries_module

    _, layer, bank = setup
    m = Matcher(layer, bank)
    shape, centre, starts = m.windows.tables()
    monkeypatch.setattr(summaries_module, "JOB_STARTS", 40)
    n_jobs = -(-starts.size // 40)
    assert n_jobs >= 4
    whole = WindowIndex(shape, centre, starts, m.n, flat_below=0)
    real, ran, stop_after = summaries_module._summary_job, [], [2]

    def job(shared, j):
        if len(ran) == stop_after[0]:
            raise KeyboardInterrupt
        ran.append(int(j[2][0]))
        return real(shared, j)

    monkeypatch.setattr(summaries_module, "_summary_job", job)
    with pytest.raises(KeyboardInterrupt):
        cached_window_index(shape, centre, starts, m.n, tmp_path, flat_below=0)
    (parts,) = tmp_path.glob("index-*.parts")
    kept = sorted(parts.glob("part-*.npz"))
    assert len(kept) == 2 and not list(tmp_path.glob("index-*.npz"))
    data = bytearray(kept[0].read_bytes())
    data[len(data) // 2] ^= 0xFF
    kept[0].write_bytes(bytes(data))
    ran.clear()
    stop_after[0] = -1
    with caplog.at_level(logging.WARNING):
        resumed = cached_window_index(shape, centre, starts, m.n, tmp_path, flat_below=0)
    assert len(ran) == n_jobs - 1 and str(kept[0]) in caplog.text
    assert resumed.seconds["resumed"] == 1 and whole.seconds["resumed"] == 0
    assert np.array_equal(faiss.serialize_index(resumed.index), faiss.serialize_index(whole.index))
    assert not list(tmp_path.glob("index-*.parts")) and list(tmp_path.glob("index-*.npz"))


def test_a_build_stopped_while_encoding_resumes_from_the_codes_it_kept(
    setup, tmp_path, monkeypatch
) -> None:
    """The second pass (each part's summaries encoded for the trained lists) keeps its
    codes as parts too: a build stopped after 2 encoding jobs runs no summary job and
    only the other encoding jobs when it runs again, and gives the index of one build,
    byte for byte."""
    import faiss

    from vision import _summaries as summaries_module

    _, layer, bank = setup
    m = Matcher(layer, bank)
    shape, centre, starts = m.windows.tables()
    monkeypatch.setattr(summaries_module, "JOB_STARTS", 40)
    n_jobs = -(-starts.size // 40)
    whole = WindowIndex(shape, centre, starts, m.n, flat_below=0)
    summary, code = summaries_module._summary_job, summaries_module._code_job
    ran: dict[str, int] = {"summary": 0, "code": 0}
    stop_after = [2]

    def summary_job(shared, job):
        ran["summary"] += 1
        return summary(shared, job)

    def code_job(shared, z):
        if ran["code"] == stop_after[0]:
            raise KeyboardInterrupt
        ran["code"] += 1
        return code(shared, z)

    monkeypatch.setattr(summaries_module, "_summary_job", summary_job)
    monkeypatch.setattr(summaries_module, "_code_job", code_job)
    with pytest.raises(KeyboardInterrupt):
        cached_window_index(shape, centre, starts, m.n, tmp_path, flat_below=0)
    assert ran == {"summary": n_jobs, "code": 2}
    (parts,) = tmp_path.glob("index-*.parts")
    assert len(list((parts / "codes").glob("part-*.npz"))) == 2
    ran.update(summary=0, code=0)
    stop_after[0] = -1
    resumed = cached_window_index(shape, centre, starts, m.n, tmp_path, flat_below=0)
    assert ran == {"summary": 0, "code": n_jobs - 2}
    assert np.array_equal(faiss.serialize_index(resumed.index), faiss.serialize_index(whole.index))
    assert not list(tmp_path.glob("index-*.parts"))


@pytest.mark.slow  # (a local cluster starts in a few seconds)
def test_an_index_built_on_a_two_worker_cluster_is_the_local_build(setup, monkeypatch) -> None:
    """Each first-pass job carries its slice of the tables to a worker and brings its
    summaries back, each second-pass job its summaries and brings their codes back: the
    index is the local build's, byte for byte."""
    import faiss

    from vision import _summaries as summaries_module

    _, layer, bank = setup
    m = Matcher(layer, bank)
    shape, centre, starts = m.windows.tables()
    monkeypatch.setattr(summaries_module, "JOB_STARTS", 60)
    here = WindowIndex(shape, centre, starts, m.n, flat_below=0)
    there = WindowIndex(shape, centre, starts, m.n, flat_below=0, cluster="local:2")
    assert np.array_equal(faiss.serialize_index(here.index), faiss.serialize_index(there.index))
