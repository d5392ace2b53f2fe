"""Vision accuracy on performers the library has never seen (Lee et al. §5.3, issue 6).

Usage: python -m benchmarks.bench_accuracy [LIBRARY_DIR] [--out FILE] [--clips PATTERN]...
       [--coords relative|fixed] [--sigma-scale S] [--threshold T] [--contact RULE]
       [--folds 13_29,13_30] [--settings W:A,...] [--variants] [--descriptor D]
       [--stay S] [--views N] [--recordings base,side,high,thin] [--leave take|person]
       [--mirror auto|none|labelled|all]

Two folds on the labelled exercise clips: the performer is a recording of 13_29 (or
13_30) made by ``mimic record`` (another body, a camera off the ring, mask noise); the
library is every other clip (or every other clip of ``--clips``), with the mirrored
copies ``mimic perform`` adds (``--mirror auto``: of the labelled clips with
``--descriptor pose``; never the held-out take's). ``--recordings`` films each held-out
take more ways (``RECORDINGS``: a side camera, a high one, a thinner body with ragged
edges, other proportions: ``long_legs``, ``short_legs``; cameras behind, left, low and
far, a wider body: ``az140``, ``az-60``, ``low_far``, ``wide``; the take mirrored, a
performer using the other arm and leg: ``mirrored``; the take at 0.7, 0.5 and 1.3 times
its tempo: ``slow``, ``slower``, ``fast``; the take with a still pause of 2 s every 6 s:
``pauses``; the take done with 0.7 and 1.25 times its reach: ``small``, ``big``,
``benchmarks._takes``), each a run of its own: one recording a fold swings with a
setting. With ``--descriptor pose`` the performer is not the recording's silhouettes but
the landmarks a pose model would give of the same performer and camera
(``benchmarks._landmarks``: the take's joints on the recording's body, 3% noise), what a
camera with MediaPipe feeds the matcher. For each match setting (window, look-ahead) and
each lag (the avatar is compared with what the performer did ``lag`` seconds earlier):

- pose score: joint-angle error (weighted joints, squared half-angles as in the graph's
  distance) between the avatar's frame and the performer's true frame, normalised so
  that a random walk on the same graph scores 0 and the nearest library pose of every
  performer frame scores 1; beside it, ``score_either_side``: each avatar frame or its
  mirror image, whichever is nearer (a silhouette cannot tell a pose seen from the front
  from its mirror image seen from behind), and ``score_known_actions``: the score where
  the performer does an action the library has (another person's own actions leave the
  avatar no near pose);
- with ``pauses``, ``holds``: what the avatar does while the performer stands still
  (from 0.5 s into each pause): its jumps a minute, how far its joints turn a frame
  (the largest turn, beside it the same elsewhere) and its pose score there;
- label agreement: the fraction of decisions at which the avatar's frame carries the
  performer's action label (frames of unlabelled clips count as disagreement);
- recognition: the matcher's global window search alone (no avatar), the fraction of
  windows whose best library window has the performer's label: over the graph's
  component (what the avatar can reach), and over every window of the library's clips
  (``whole_take``: issue 9's baseline measure, 73%);
- the lag a viewer sees: how long after each change of the performer's action the avatar
  first shows the new one (``switch_followed_after_s``), counted from the label file's
  boundary (the performer's truth) and from where the motion changes, the take's
  cleaned labels (``switch_followed_after_motion_s``; the curve's agreement against them
  beside each lag): the label files' boundaries lie up to a second off the motion.

Targets (issue 6) at a lag of 1 s or less: score >= 0.7, agreement >= 80%.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import itertools
import re
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks._landmarks import LandmarkSource, simulated_landmarks
from benchmarks._oracle import pose_oracle
from benchmarks._report import machine, save
from benchmarks._takes import held_since, hold_figures, paused_clip, retimed_clip, styled_clip
from control.clusters import LayerSettings, cached_higher_layer
from control.dtw import dtw_best_window
from control.graph import (
    GraphOptions,
    build_graph,
    foot_slide,
    joint_jumps,
    lowest_foot,
    random_walk,
    select_clips,
    weighted_joints,
)
from control.motion import Clip, default_library_path, load_library, mirror, qconj, qlog, qmul
from mimic.args import mirror_copies
from mimic.run import voice_bank
from silhouette_bank import (
    DEFAULT_DESCRIPTOR,
    DESCRIPTORS,
    BankSettings,
    BodyShape,
    CameraRing,
    PoseDescriptor,
    cached_bank,
    get_descriptor,
    robust_settings,
    silhouette_features,
)
from vision import (
    Matcher,
    MatchSettings,
    PathSettings,
    PerformSettings,
    RecordSettings,
    VideoSource,
    brief_actions_per_minute,
    clean_mask,
    evaluation,
    on_the_floor,
    perform,
    performer_sequence,
    record_clip,
    switch_delays,
    truth_for,
)
from vision._truth import labels_at_source_frames

LAGS = (0.0, 0.5, 1.0, 1.5, 2.0, 3.0)
#: delays (s) from a frame to the avatar on screen, as a live camera has them
SHOWN_LATE = (0.1, 0.2)
SETTINGS = ((1.0, 1.5), (1.0, 3.0), (2.0, 3.0), (2.0, 5.0))


def with_values(settings: MatchSettings, values: dict[str, Any]) -> MatchSettings:
    """``settings`` with ``values`` set, each key a field of ``MatchSettings`` or, dotted,
    of one of its parts (``landing.jump_ratio``)."""
    for key, value in values.items():
        part, _, name = key.rpartition(".")
        if part:
            inner = dataclasses.replace(getattr(settings, part), **{name: value})
            settings = dataclasses.replace(settings, **{part: inner})
        else:
            settings = dataclasses.replace(settings, **{name: value})
    return settings


def _pose_dist(qa: np.ndarray, qb: np.ndarray) -> np.ndarray:
    """Sum over weighted joints of squared half-angles, rows of ``(N, K, 4)``."""
    return np.sum((np.linalg.norm(qlog(qmul(qconj(qb), qa)), axis=-1) / 2.0) ** 2, axis=-1)


def _score(err: float, random_err: float, nearest: float) -> float:
    """The pose score of a mean pose error ``err``: 1 at the library's nearest poses'
    error ``nearest``, 0 at a random walk's ``random_err``."""
    return float((random_err - err) / max(random_err - nearest, 1e-9))


def _silhouette_rows(
    video: Path, descriptor: str, perf_labels: list[str | None], fps: float
) -> tuple[np.ndarray, list[str | None]]:
    """The recording's silhouette features and labels at the library's rate ``fps``."""
    src = VideoSource(video, silhouette=True)
    feats: list[np.ndarray] = []
    labels: list[str | None] = []
    step = src.fps / fps
    i = 0
    while (frame := src.read()) is not None:
        if i == round(len(feats) * step):
            mask = clean_mask(frame.mask) if frame.mask is not None else None
            feats.append(
                silhouette_features(mask, descriptor=descriptor)
                if mask is not None
                else np.full(get_descriptor(descriptor).size, np.nan)
            )
            labels.append(perf_labels[i] if i < len(perf_labels) else None)
        i += 1
    src.close()
    return np.array(feats), labels


def _landmark_rows(
    vectors: np.ndarray, perf_labels: list[str | None], rate: float, fps: float
) -> tuple[np.ndarray, list[str | None]]:
    """Pose vectors and labels at the library's rate ``fps`` of pose vectors at ``rate``."""
    keep = np.round(np.arange(0, vectors.shape[0], rate / fps)).astype(int)
    keep = keep[keep < vectors.shape[0]]
    labels = [perf_labels[i] if i < len(perf_labels) else None for i in keep]
    return vectors[keep], labels


def _recognition(
    layer: Any,
    bank: Any,
    x: np.ndarray,
    labels: list[str | None],
    lib_labels: np.ndarray,
    known: set[str],
) -> dict[str, Any]:
    """The matcher's global search alone (no graph, no avatar): for windows of 1, 2 and
    3 s ending every 0.5 s, the label of the library window most like the performer's
    (every window of the component, every view) against the performer's label at the
    window's end; over all labelled windows and over those whose action the library
    has. ``x`` ``(F, features)`` and ``labels`` are the performer's at the library's
    rate."""
    fps = layer.graph.fps
    g = layer.graph
    clip_of = np.searchsorted(g.clip_start, np.arange(g.n_frames), side="right")
    out: dict[str, Any] = {}
    for seconds in (1.0, 2.0, 3.0):
        m = Matcher(layer, bank, MatchSettings(window=seconds))
        shape, centre, _ = m.windows.tables()
        # every window inside one clip: the whole reference take, as issue 9's baseline
        ends = np.arange(g.n_frames) + m.n - 1
        take = np.flatnonzero(ends < g.n_frames)
        take = take[clip_of[take] == clip_of[ends[take]]].astype(np.int64)
        hits: list[tuple[bool, bool, bool]] = []
        for end in range(m.n, len(x) + 1, max(1, round(0.5 * fps))):
            truth = labels[end - 1]
            got = m.find_window(x[end - m.n : end])
            if truth is None or got is None:
                continue
            rows = x[end - m.n : end]
            rows = rows[np.isfinite(rows).all(axis=1)]  # as locate does
            query = performer_sequence(
                rows, m.windows.mean, m.windows.proj, m.settings.centre_weight, m.desc
            )
            st = m.settings
            s, _, _ = dtw_best_window(query, shape, centre, take, m.n, st.band, st.recency)
            hits.append(
                (
                    lib_labels[got[0] + m.n - 1] == truth,
                    lib_labels[s + m.n - 1] == truth,
                    truth in known,
                )
            )
        h = np.array(hits, dtype=bool).reshape(-1, 3)
        k = h[:, 2]
        out[f"{seconds:g}s"] = {
            "windows": int(h.shape[0]),
            "right": round(float(h[:, 0].mean()), 3) if h.size else None,
            "right_known_actions": round(float(h[k, 0].mean()), 3) if k.any() else None,
            "whole_take_right": round(float(h[:, 1].mean()), 3) if h.size else None,
            "whole_take_right_known_actions": round(float(h[k, 1].mean()), 3) if k.any() else None,
        }
    return out


def _switches_per_minute(labels: list[str], seconds: float) -> float:
    return sum(a != b for a, b in itertools.pairwise(labels)) / max(seconds / 60.0, 1e-9)


def _run_figures(
    r: Any,
    window: float,
    lookahead: float,
    fps: float,
    perf_labels: list[str | None],
    lib_labels: np.ndarray,
    lib_q: np.ndarray,
    truth_q: np.ndarray,
    known: set[str],
    random_err: float,
    nearest: float,
    walk_frames: np.ndarray,
    train: list[Any],
    lib_q_mirror: np.ndarray | None = None,
    holds: np.ndarray | None = None,
    motion_labels: list[str | None] | None = None,
) -> dict[str, Any]:
    """Agreement, pose score, coherence, latency and physical checks of one perform run.
    With ``lib_q_mirror`` (the library's rotations, each clip mirrored), also the pose
    score with each avatar frame counted on whichever side is nearer the performer's: what
    a silhouette cannot tell (seen from the front, a pose; from behind, its mirror image)."""
    frames = np.array([d["frame"] for d in r.decisions])
    times = np.array([d["t"] for d in r.decisions])
    made = [d for d in r.decisions if d["decision"] is not None]
    curve = []
    for lag in LAGS:
        k = np.round((times - lag) * fps).astype(int)
        ok = (k >= 0) & (k < truth_q.shape[0])
        each = _pose_dist(lib_q[frames[ok]], truth_q[k[ok]])
        err = each.mean()
        score = _score(err, random_err, nearest)
        either = None
        if lib_q_mirror is not None:
            other = _pose_dist(lib_q_mirror[frames[ok]], truth_q[k[ok]])
            either = _score(np.minimum(each, other).mean(), random_err, nearest)
        lab = [perf_labels[i] for i in k[ok]]
        got = [str(lib_labels[f]) for f in frames[ok]]
        # the pose where the performer does an action the library has: what is left of
        # the score once no library pose can be near (another person's own actions)
        has = np.array([t in known for t in lab], dtype=bool)
        in_known = _score(each[has].mean(), random_err, nearest) if has.any() else None
        pairs = [(g, t) for g, t in zip(got, lab, strict=True) if t is not None]
        # a random walk's chance of showing the performer's action: the share of its
        # frames with that label
        walk_labels = lib_labels[walk_frames]
        share = {t: float(np.mean(walk_labels == t)) for t in known}
        per_action: dict[str, float] = {}
        for action in sorted({t for _, t in pairs}):
            hit = [g == t for g, t in pairs if t == action]
            per_action[action] = round(float(np.mean(hit)), 3)
        kn = [g == t for g, t in pairs if t in known]
        # the same against where the performer's motion changes action (cleaned labels)
        moved = None
        if motion_labels is not None:
            at = [motion_labels[i] for i in k[ok]]
            hits = [g == t for g, t in zip(got, at, strict=True) if t in known]
            moved = float(np.mean(hits)) if hits else None
        curve.append(
            {
                "lag": lag,
                "pose_error": float(err),
                "score": float(score),
                "score_either_side": None if either is None else float(either),
                "score_known_actions": in_known,
                "label_agreement": float(np.mean([g == t for g, t in pairs])) if pairs else None,
                "label_agreement_known_actions": float(np.mean(kn)) if kn else None,
                "label_agreement_known_actions_from_motion": moved,
                "random_walk_agreement_known_actions": float(
                    np.mean([share[t] for _, t in pairs if t in known])
                )
                if kn
                else None,
                "per_action": per_action,
            }
        )
    # what a viewer of a live camera sees, the avatar shown a moment after the frame it
    # answers: its pose against the performer's that much later
    late = {}
    for delay in SHOWN_LATE:
        k = np.round((times + delay) * fps).astype(int)
        ok = (k >= 0) & (k < truth_q.shape[0])
        err = _pose_dist(lib_q[frames[ok]], truth_q[k[ok]]).mean()
        late[f"{delay:g}"] = round(_score(err, random_err, nearest), 3)
    # coherence: action switches a minute, the avatar's against the performer's
    k = np.clip(np.round(times * fps).astype(int), 0, len(perf_labels) - 1)
    seconds = float(times[-1] - times[0]) if times.size > 1 else 0.0
    avatar_labels = [str(lib_labels[f]) for f in frames]
    performer_labels = [perf_labels[i] or "" for i in k]
    moving = None if motion_labels is None else [motion_labels[i] for i in k]
    lat = np.array([d["latency_ms"] for d in made]) if made else np.zeros(1)
    motion = r.avatar.motion().motion
    low = lowest_foot(motion)
    lib_low = np.concatenate([lowest_foot(c.motion) for c in train])
    lib_root = np.concatenate([c.motion.root_pos[:, 1] for c in train])
    syn_jumps = joint_jumps(motion)
    shown, jumps_at, _ = r.avatar.history()
    # sole speed where a foot is planted: the avatar's (its frames' contacts) and the library's
    states = np.concatenate([c.contacts.states for c in train])
    slide = foot_slide(motion, states[shown[: motion.n_frames]])
    lib_slide = np.concatenate([foot_slide(c.motion, c.contacts.states) for c in train])
    lib_jj = np.concatenate([joint_jumps(c.motion) for c in train])
    at = jumps_at[(jumps_at >= 1) & (jumps_at <= syn_jumps.size)] - 1
    still = None
    if holds is not None:  # what the avatar does while the performer stands still
        begun = held_since(holds, fps)
        still = hold_figures(begun, fps, times, motion, r.avatar_start_s, jumps_at)
        b = begun[np.clip(np.round(times * fps).astype(int), 0, holds.size - 1)]
        err = _pose_dist(lib_q[frames[b]], truth_q[np.round(times[b] * fps).astype(int)])
        still["pose_score"] = round(_score(err.mean(), random_err, nearest), 3)
    return {
        "window": window,
        "lookahead": lookahead,
        "decisions": len(r.decisions),
        "decisions_made": len(made),
        "direct_jumps": sum("jump" in d for d in made),
        "curve": curve,
        "pose_score_shown_late": late,
        # the performer's action and the avatar's at each decision point (for a plot a
        # person would look at: benchmarks/plot_timelines.py)
        "timeline": {
            "t": [round(float(x), 3) for x in times],
            "performer": [x or None for x in performer_labels],
            # where the performer's motion changes action (the take's cleaned labels)
            **({} if moving is None else {"motion": [x or None for x in moving]}),
            "avatar": [x or None for x in avatar_labels],
        },
        "switches_per_minute": {
            "avatar": round(_switches_per_minute(avatar_labels, seconds), 2),
            "performer": round(_switches_per_minute(performer_labels, seconds), 2),
            # flicker: actions the avatar shows for under 0.5 s (an unlabelled stretch
            # counts as an action, as in the switches)
            "avatar_brief_actions_under_0.5s": brief_actions_per_minute(
                [x or "(none)" for x in avatar_labels], times.tolist(), seconds
            ),
        },
        # the lag as a viewer sees it: how long after each of the performer's switches
        # the avatar took the new action up
        "switch_followed_after_s": switch_delays(
            avatar_labels, [x or None for x in performer_labels], times.tolist(), known
        ),
        # the same from where the performer's motion changes action (the take's cleaned
        # labels: the label files' boundaries lie up to a second off it either way)
        "switch_followed_after_motion_s": None
        if moving is None
        else switch_delays(avatar_labels, moving, times.tolist(), known),
        "latency_ms": {
            "p50": float(np.percentile(lat, 50)),
            "p99": float(np.percentile(lat, 99)),
            "max": float(lat.max()),
            "over_100ms": int((lat > 100).sum()),
        },
        "floor": {
            "lowest_foot_max_m": float(low.max()),
            "frames_both_feet_over_0.25m": float((low > 0.25).mean()),
            "pelvis_max_m": float(motion.root_pos[:, 1].max()),
            "library_lowest_foot_max_m": float(lib_low.max()),
            "library_pelvis_max_m": float(lib_root.max()),
            "foot_slide_m_per_s": float(slide.mean()) if slide.size else None,
            "library_foot_slide_m_per_s": float(lib_slide.mean()),
        },
        "junctions": {
            "count": int(at.size),
            "joint_change_p99_deg": float(np.percentile(syn_jumps[at], 99)) if at.size else None,
            "library_joint_change_p99_deg": float(np.percentile(lib_jj, 99)),
        },
        "holds": still,
    }


#: how the held-out take is filmed (``--recordings``): ``mimic record``'s defaults
#: (another body, a camera 10 deg off the ring), and the recognition benchmark's camera
#: and body variations (``bench_recognition.VARIATIONS``)
RECORDINGS = {
    "base": RecordSettings(),
    "side": RecordSettings(azimuth=100.0),
    "high": RecordSettings(camera_height=1.7, azimuth=40.0),
    "thin": RecordSettings(body=BodyShape(width=0.9, height=1.05), azimuth=-30.0, edge_noise=2.0),
    # another person's proportions (not among the bodies that teach the bank's metric)
    "long_legs": RecordSettings(body=BodyShape(width=1.05, legs=1.12, arms=0.9), azimuth=25.0),
    "short_legs": RecordSettings(body=BodyShape(width=1.1, legs=0.88, arms=1.1), azimuth=-15.0),
    # checks of settings chosen on the four recordings above (issue 17's vote)
    "az140": RecordSettings(azimuth=140.0, seed=2),
    "az-60": RecordSettings(azimuth=-60.0, seed=3),
    "low_far": RecordSettings(camera_height=0.6, distance=5.0, azimuth=-20.0, seed=4),
    "wide": RecordSettings(body=BodyShape(width=1.3, height=0.95), azimuth=-100.0, seed=5),
    # the take mirrored: a performer who uses the other arm and leg (``MIRRORED``)
    "mirrored": RecordSettings(seed=6),
    # the take with a still pause of 2 s every 6 s, as real performers stop (``PAUSED``)
    "pauses": RecordSettings(seed=7),
    # the take at another tempo (``TEMPO``; the shared squat clip's are 0.45 of the
    # library's)
    "slow": RecordSettings(seed=8),
    "slower": RecordSettings(seed=10),
    "fast": RecordSettings(seed=9),
    # the take done with less or more reach: every joint turns 0.7 or 1.25 times as far
    # from its mean (``REACH``)
    "small": RecordSettings(seed=11),
    "big": RecordSettings(seed=12),
}
#: recordings of the held-out take mirrored left for right (the library is not)
MIRRORED = frozenset({"mirrored"})
#: recordings of the held-out take with pauses (``benchmarks._takes``)
PAUSED = frozenset({"pauses"})
#: recordings of the held-out take at another tempo (``benchmarks._takes``)
TEMPO = {"slow": 0.7, "slower": 0.5, "fast": 1.3}
#: recordings of the held-out take with another reach (``benchmarks._takes``)
REACH = {"small": 0.7, "big": 1.25}


def fold(
    root: Path,
    test: str,
    options: GraphOptions,
    settings: tuple[tuple[float, float], ...] = SETTINGS,
    clips: list[str] | None = None,
    variants: bool = False,
    descriptor: str = DEFAULT_DESCRIPTOR,
    stay: float = 0.0,
    views: int = 18,
    match: dict[str, Any] | None = None,
    off_floor: bool = False,
    store: str = "float32",
    recordings: tuple[str, ...] = ("base",),
    leave: str = "take",
    copies: str = "auto",
) -> dict[str, Any]:
    mirrors = mirror_copies(copies, descriptor)  # (as mimic perform's --mirror)
    everything = load_library(root, clips=list(clips) if clips else None, mirror=mirrors)
    # leave the take (and its mirror image) out, or every take of its subject (CMU names:
    # subject_take)
    subject = test.split("_")[0]
    train = [
        c
        for c in everything.clips
        if c.name not in (test, f"{test}_mirror")
        and not (leave == "person" and c.name.split("_")[0] == subject)
    ]
    dropped: dict[str, float] = {}
    if not off_floor:  # as mimic perform does by default
        train, dropped = on_the_floor(train)
    train = select_clips(train)[0]  # the clips of the skeleton the graph joins, as perform
    g = build_graph(train, options)
    # trees need reach no further than the longest look-ahead (dense graphs make 15 s
    # trees slow to build)
    t0 = time.perf_counter()
    layer, _, _ = cached_higher_layer(
        g, train, LayerSettings(bound_seconds=max(2.0, max(a for _, a in settings) + 0.5))
    )
    took = time.perf_counter() - t0
    print(f"{test}: graph {g.n_edges} edges, layer built in {took:.0f} s", flush=True)
    base = BankSettings(CameraRing(n_views=views), descriptor=descriptor)
    bank, _, _ = cached_bank(train, robust_settings(base) if variants else base)
    if store != "float32":  # (issue 21: the precision a bank need store its numbers at)
        bank = dataclasses.replace(
            bank,
            features=bank.features.astype(store).astype(np.float32),
            root_motion=bank.root_motion.astype(store).astype(np.float32),
        )
    joints = weighted_joints(train[0].motion.skeleton)
    lib_q = np.concatenate([c.motion.quats for c in train])[:, joints]
    lib_qm = np.concatenate([mirror(c.motion).quats for c in train])[:, joints]
    lib_labels = np.concatenate(
        [np.array([c.label_at(i) or "" for i in range(c.motion.n_frames)]) for c in train]
    )
    assert g.clip_names == tuple(c.name for c in train)  # the graph's frames are train's
    # the take, and mirrored for the recordings that film it so (``MIRRORED``)
    # (the performer's truth: the label file's own boundaries)
    takes = load_library(
        root, fps=30, clips=[test], mirror=bool(MIRRORED & set(recordings)), clean_labels=False
    )
    perf_clip = takes.clip(test)
    other_side = next((c for c in takes.clips if c.mirrored), None)
    # where the performer's motion changes action: the take's cleaned labels
    # (``control.motion.clean_labels``), for the lag counted from the motion
    cleaned = load_library(root, fps=30, clips=[test]).clip(test)
    truth_q = perf_clip.motion.quats[:, joints]
    # nearest library pose of every performer frame (the best any avatar could do)
    nearest = np.array(
        [_pose_dist(lib_q, q[None].repeat(lib_q.shape[0], 0)).min() for q in truth_q[::3]]
    )
    walk_frames, _, _ = random_walk(g, 4000, seed=1)
    rw = lib_q[walk_frames]
    random_err = float(
        np.mean([_pose_dist(rw, q[None].repeat(rw.shape[0], 0)).mean() for q in truth_q[::15]])
    )
    out: dict[str, Any] = {
        "test": test,
        "train_frames": g.n_frames,
        "graph": {
            "coords": options.coords,
            "threshold": options.threshold,
            "sigma_scale": options.sigma_scale,
            "contact": options.contact,
            "edges": g.n_edges,
            "scc_frames": int(g.in_scc.sum()),
        },
        "clusters": layer.clustering.k,
        "bank_views": bank.features.shape[1],
        "left_out_off_floor": sorted(dropped),
        "nearest_error": float(nearest.mean()),
        "random_error": random_err,
        "runs": [],
    }
    # the ceiling of following by pose: the nearest windows by the true 3D pose
    actions = np.concatenate(
        [[c.label_at(i) or f"clip {c.name}" for i in range(c.motion.n_frames)] for c in train]
    )
    at_lib = load_library(root, fps=g.fps, clips=[test], clean_labels=False).clip(test)
    at_motion = load_library(root, fps=g.fps, clips=[test]).clip(test)
    out["pose_oracle"] = pose_oracle(
        lib_q,
        actions,
        g.clip_start,
        at_lib.motion.quats[:, joints],
        [at_lib.label_at(i) for i in range(at_lib.motion.n_frames)],
        g.fps,
        _pose_dist,
        with_values(MatchSettings(), match or {}).action.vote or 15,
        motion_labels=[at_motion.label_at(i) for i in range(at_motion.motion.n_frames)],
    )
    # its windows' last frames shown at once, as a pose score (the avatar's ceiling)
    out["pose_oracle"]["pose_score"] = round(
        _score(out["pose_oracle"]["pose_error"], random_err, float(nearest.mean())), 3
    )
    print(f"{test}: following by the true pose {out['pose_oracle']}", flush=True)
    out["recordings"] = {}
    for rec in recordings:
        ctx = (perf_clip, layer, bank, train, lib_labels, lib_q, truth_q, walk_frames, lib_qm)
        # another performer than the take as it is (its pose score keeps the take's scale:
        # random walk, nearest)
        other, holds = None, None
        if rec in MIRRORED:
            other = other_side
            assert other is not None
        elif rec in PAUSED:
            other, holds = paused_clip(perf_clip)
        elif rec in TEMPO:
            other = retimed_clip(perf_clip, TEMPO[rec])
        elif rec in REACH:
            other = styled_clip(perf_clip, REACH[rec])
        if other is not None:
            q = other.motion.quats[:, joints]
            ctx = (other, layer, bank, train, lib_labels, lib_q, q, walk_frames, lib_qm)
        recognition, ceiling, runs = _recorded_runs(
            rec, ctx, settings, stay, match, random_err, float(nearest.mean()), holds, cleaned
        )
        out["recordings"][rec] = {"settings": RECORDINGS[rec].to_dict(), "recognition": recognition}
        out.setdefault("recognition", recognition)  # the first recording's
        out["label_ceiling"] = ceiling
        out["runs"] += runs
    return out


#: the second bank of the fold being run (the silhouette beside simulated landmarks, or
#: the pose bank of the landmarks read from silhouettes), loaded once for its recordings
_SECOND: dict[tuple[str, tuple[str, ...]], Any] = {}


def _fold_bank(kind: str, train: list[Any], load: Callable[[], Any]) -> Any:
    """``load()``'s bank of ``kind`` for the library ``train``, loaded at its first
    recording and kept for the others (only the last fold's is kept)."""
    key = (kind, tuple(c.name for c in train))
    if key not in _SECOND:
        _SECOND.clear()
        _SECOND[key] = load()
    return _SECOND[key]


def _masks(video: Path) -> tuple[list[np.ndarray], float]:
    """Every mask of a silhouette recording, and its frame rate."""
    src = VideoSource(video, silhouette=True)
    out = []
    while (f := src.read()) is not None:
        out.append(np.asarray(f.mask, dtype=bool))
    src.close()
    return out, src.fps


def _recorded_runs(
    rec: str,
    ctx: tuple[Any, ...],
    settings: tuple[tuple[float, float], ...],
    stay: float,
    match: dict[str, Any] | None,
    random_err: float,
    nearest: float,
    holds: np.ndarray | None = None,
    cleaned: Clip | None = None,
) -> tuple[dict[str, Any], float, list[dict[str, Any]]]:
    """The held-out take filmed as recording ``rec`` (``RECORDINGS``): recognition alone,
    the label ceiling, and a run of ``perform`` per match setting. ``cleaned``: the take
    with its cleaned labels, for the lag counted from where the motion changes."""
    perf_clip, layer, bank, train, lib_labels, lib_q, truth_q, walk_frames, lib_qm = ctx
    runs = []
    fallback = voice = None
    with tempfile.TemporaryDirectory() as tmp:
        video = Path(tmp) / f"{perf_clip.name}_{rec}.mkv"
        side = record_clip(perf_clip, video, RECORDINGS[rec])
        perf_labels = side["labels"]
        motion_labels = (
            None
            if cleaned is None
            else labels_at_source_frames(cleaned, side["source_frames"], side["labels"])
        )
        known = set(lib_labels) - {""}
        labelled = [lab_i for lab_i in perf_labels if lab_i is not None]
        # actions the library lacks can never agree: the best any avatar could do
        ceiling = float(np.mean([lab_i in known for lab_i in labelled]))
        fps = layer.graph.fps
        if get_descriptor(bank.settings.descriptor).kind == "pose":
            # the performer's landmarks, as a pose model would give them (the video
            # serves for its truth sidecar only)
            rng = np.random.default_rng(RECORDINGS[rec].seed)
            points, vis = simulated_landmarks(perf_clip.motion, RECORDINGS[rec], rng)
            rate = perf_clip.motion.fps
            desc = get_descriptor("pose")
            assert isinstance(desc, PoseDescriptor)
            rows = _landmark_rows(desc.from_points(points), perf_labels, rate, fps)

            # with the fused ballot (the default; ``--match action.fuse=False``: off), the
            # recording's masks beside the landmarks, as the pose model gives both,
            # matched on a silhouette bank of the library
            fuse = with_values(MatchSettings(), match or {}).action.fuse
            masks, mask_fps = _masks(video) if fuse else ([], 0.0)
            if masks:
                fallback = _fold_bank("silhouette", train, lambda: cached_bank(train)[0])

            def source() -> Any:
                name = f"{video.stem} landmarks"
                return LandmarkSource(points, rate, name, vis, masks, mask_fps)

        else:
            rows = _silhouette_rows(video, bank.settings.descriptor, perf_labels, fps)
            # with the fused ballot (the default), the landmarks the pose model reads from
            # each silhouette weigh in where the silhouette's ballot is unsure, as
            # ``mimic perform`` weighs them for a silhouette video
            voice = _fold_bank(
                "voice", train, lambda: voice_bank(train, with_values(MatchSettings(), match or {}))
            )

            def source() -> Any:
                return VideoSource(video, silhouette=True)

        recognition = _recognition(layer, bank, *rows, lib_labels, known)
        for window, lookahead in settings:
            ms = with_values(
                MatchSettings(
                    window=window,
                    paths=PathSettings(lookahead=lookahead, keep_clip_bonus=stay),
                ),
                match or {},
            )
            st = PerformSettings(match=ms)
            r = perform(source(), layer, bank, train, st, fallback=fallback, voice=voice)
            # mimic evaluate's figures of the same run (the confusion matrix among them)
            truth = truth_for(video)
            assert truth is not None  # the recording's sidecar
            judged = evaluation(r.decisions, train, truth, r.media_seconds)
            fig = _run_figures(
                r,
                window,
                lookahead,
                perf_clip.motion.fps,
                perf_labels,
                lib_labels,
                lib_q,
                truth_q,
                known,
                random_err,
                nearest,
                walk_frames,
                train,
                lib_qm,
                holds,
                motion_labels,
            )
            fig["recording"] = rec
            fig["evaluate"] = {
                k: judged[k]
                for k in (
                    "best_at_lag_le_1s",
                    "best_lag_s",
                    "per_action_at_best_lag",
                    "confusion_at_best_lag",
                    "chance",
                )
            }
            runs.append(fig)
            best = max(c["label_agreement_known_actions"] for c in fig["curve"] if c["lag"] <= 1.0)
            print(
                f"{perf_clip.name} {rec} {window}:{lookahead}: agreement {best:.3f} at lag <= 1 s "
                f"(recognition alone {recognition['1s']['right']})",
                flush=True,
            )
    return recognition, ceiling, runs


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", nargs="?", default=str(default_library_path()))
    ap.add_argument("--out", default="benchmarks/results/accuracy.json")
    ap.add_argument(
        "--threshold", type=float, default=GraphOptions.threshold, help="graph likelihood threshold"
    )
    ap.add_argument("--contact", default="loose", choices=("loose", "strict", "none"))
    ap.add_argument(
        "--sigma-scale", type=float, default=GraphOptions.sigma_scale, help="graph sigma scale"
    )
    ap.add_argument("--coords", default="relative", choices=("fixed", "relative"))
    ap.add_argument(
        "--clips", action="append", help="library clips (patterns; default: every clip)"
    )
    ap.add_argument("--folds", default="13_29,13_30")
    ap.add_argument(
        "--leave",
        default="take",
        choices=("take", "person"),
        help="leave out of the library the held-out take, or every take of its person "
        "(its subject: 14_20 against subject 13's takes, 13_29 against 14_20)",
    )
    ap.add_argument(
        "--recordings",
        default="base",
        help=f"how each held-out take is filmed, comma-separated ({', '.join(RECORDINGS)})",
    )
    ap.add_argument(
        "--variants", action="store_true", help="bank with other bodies and shadows too"
    )
    ap.add_argument(
        "--descriptor",
        default=DEFAULT_DESCRIPTOR,
        choices=list(DESCRIPTORS),
        help="the performer's features: silhouette shape, or pose (the performer's "
        "landmarks as a pose model gives them: joints seen by the recording's camera, 3%% "
        "noise)",
    )
    ap.add_argument(
        "--stay", type=float, default=0.0, help="temporal prior (PathSettings.keep_clip_bonus)"
    )
    ap.add_argument("--views", type=int, default=18, help="cameras on the bank's ring")
    ap.add_argument(
        "--match",
        default="",
        help="more MatchSettings, dotted below the top, e.g. "
        "landing.jumps=False,landing.jump_ratio=0.9,recency=0.5 (Python literals)",
    )
    ap.add_argument(
        "--off-floor",
        action="store_true",
        help="keep clips that leave the floor (perform's --off-floor)",
    )
    ap.add_argument(
        "--store",
        default="float32",
        choices=("float32", "float16"),
        help="round the bank's features (and root motion) to this precision before matching "
        "(default float32: as the bank holds them; since bank version 6 it holds its features "
        "at float16, so float16 only rounds the root motion too)",
    )
    ap.add_argument(
        "--mirror",
        default="auto",
        choices=("auto", "none", "labelled", "all"),
        help="the library's mirrored copies, as mimic perform's --mirror (default auto: the "
        "labelled clips' with --descriptor pose)",
    )
    ap.add_argument(
        "--settings",
        default=",".join(f"{w}:{a}" for w, a in SETTINGS),
        help="window:lookahead pairs in seconds, comma separated",
    )
    args = ap.parse_args()
    root = Path(args.root)
    options = GraphOptions(
        coords=args.coords,
        threshold=args.threshold,
        contact=args.contact,
        sigma_scale=args.sigma_scale,
    )
    settings = tuple(
        (float(w), float(a)) for w, a in (s.split(":") for s in args.settings.split(","))
    )
    match: dict[str, Any] = {}
    for item in filter(None, re.split(r",(?![^()]*\))", args.match)):  # (not in tuples)
        key, _, value = item.partition("=")
        match[key.strip()] = ast.literal_eval(value.strip())
    try:
        with_values(MatchSettings(), match)
    except (AttributeError, TypeError, ValueError) as e:
        ap.error(f"--match: {e}")
    recordings = tuple(r for r in args.recordings.split(",") if r)
    unknown = [r for r in recordings if r not in RECORDINGS]
    if unknown or not recordings:
        ap.error(f"--recordings: choose from {', '.join(RECORDINGS)}, not {unknown}")
    result = {
        "machine": machine(),
        "date": time.strftime("%Y-%m-%d"),
        "library_clips": args.clips or "all",
        "variants": args.variants,
        "descriptor": args.descriptor,
        "stay": args.stay,
        "views": args.views,
        "match": match,
        "off_floor": args.off_floor,
        "store": args.store,
        "recordings": list(recordings),
        "leave": args.leave,
        "mirror": args.mirror,
        "folds": [
            fold(
                root,
                t,
                options,
                settings,
                args.clips,
                args.variants,
                args.descriptor,
                args.stay,
                args.views,
                match,
                args.off_floor,
                args.store,
                recordings,
                args.leave,
                args.mirror,
            )
            for t in args.folds.split(",")
        ],
    }
    save(result, args.out)


if __name__ == "__main__":
    main()
