"""Recognition on performers the library has not seen (issue 16): which library motion
looks like what the performer just did, by the global window search alone (no graph, no
avatar), for each descriptor.

Usage: python -m benchmarks.bench_recognition [LIBRARY_DIR] [--takes 13_29,13_30,13_31]
       [--descriptors outline,multigrid,grid,hu,pose] [--window 1.0] [--variants]
       [--videos DIR] [--labels CSV] [--no-video] [--out FILE]

**Folds.** Leave one take out over the labelled takes: the library is the other takes,
the performer the left-out one, filmed as ``mimic record`` films (``performer_masks``:
another body, a static camera off the ring, mask noise, a shadow) under variations:

- ``base``: ``RecordSettings()`` (body 1.15 wide, 0.97 tall; camera 1.0 m high, 10 deg
  off the ring);
- ``faster`` / ``slower``: the take retimed by +25% / -25%;
- ``mirrored``: the take mirrored left/right (the other arm, the other leg);
- ``side``: the camera at 100 deg (a side view);
- ``high``: the camera 1.7 m high at 40 deg;
- ``thin``: a thinner, taller body (0.9, 1.05), the camera at -30 deg, 2 px ragged edges.
- ``long_legs`` / ``short_legs``: another person's proportions, legs 1.12 / 0.88 and arms
  0.9 / 1.1 times the subject's against the torso, the camera at 25 / -15 deg.

For every 1 s window ending every 0.5 s whose last frame is labelled, the window search
(every library window inside a take, every view, the performer as seen and mirrored)
names a library window; it is right when that window's last frame carries the
performer's label. Per fold, variation and action, with chance beside it (a random
library window: the sum over actions of the performer's share times the library's).

**The pose descriptor** on the same folds: the performer's 12 joints projected by the same
cameras, with landmark noise (3% of the torso length, about what MediaPipe shows), and on
the shared real clips (``--videos``, labels ``--labels``: our own, as in
``bench_real_video``): MediaPipe Pose's landmarks against a pose bank of all the takes.

**Rejection.** Per-frame costs (``Matcher.per_frame``) of every window's best match, and of
garbage: the performer upside down, and random blobs. The JSON gives their quantiles; the
descriptors' ``reject`` thresholds are set from them (README).
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from benchmarks._landmarks import landmark_points
from benchmarks._report import machine, save
from benchmarks.bench_real_video import read_labels
from control.motion import (
    Clip,
    Motion,
    action_keys,
    default_library_path,
    load_library,
    mirror,
    resample,
)
from silhouette_bank import (
    BankSettings,
    BodyShape,
    PoseDescriptor,
    cached_bank,
    get_descriptor,
    robust_settings,
    silhouette_features,
)
from vision import (
    ActionClassifier,
    MatchSettings,
    PersonSegmenter,
    PoseReader,
    RecordSettings,
    best_window,
    choose_action,
    per_frame_cost,
    performer_masks,
    performer_queries,
    shape_stats,
    window_tables,
)

HERE = Path(__file__).resolve().parent
CENTRE_WEIGHT = 3.0
BAND = 4
#: the matcher's weighing of the window's last frames (``MatchSettings.recency``)
RECENCY = MatchSettings().recency

VARIATIONS: dict[str, dict[str, Any]] = {
    "base": {"rs": RecordSettings()},
    "faster": {"rs": RecordSettings(), "tempo": 1.25},
    "slower": {"rs": RecordSettings(), "tempo": 0.75},
    "mirrored": {"rs": RecordSettings(), "mirrored": True},
    "side": {"rs": RecordSettings(azimuth=100.0)},
    "high": {"rs": RecordSettings(camera_height=1.7, azimuth=40.0)},
    "thin": {
        "rs": RecordSettings(body=BodyShape(width=0.9, height=1.05), azimuth=-30.0, edge_noise=2.0)
    },
    "long_legs": {
        "rs": RecordSettings(body=BodyShape(width=1.05, legs=1.12, arms=0.9), azimuth=25.0)
    },
    "short_legs": {
        "rs": RecordSettings(body=BodyShape(width=1.1, legs=0.88, arms=1.1), azimuth=-15.0)
    },
}


def _labels(clip: Clip) -> NDArray[np.str_]:
    return np.array([clip.label_at(i) or "" for i in range(clip.motion.n_frames)])


def performer(clip: Clip, tempo: float = 1.0, mirrored: bool = False) -> tuple[Motion, np.ndarray]:
    """The take as the performer does it (retimed by ``tempo``, mirrored) at the
    library's rate, and the label of each frame."""
    m = mirror(clip.motion) if mirrored else clip.motion
    lab = _labels(clip)
    if tempo != 1.0:
        m = resample(dataclasses.replace(m, fps=m.fps * tempo), clip.motion.fps)
        src = np.round(np.arange(m.n_frames) * tempo).astype(int)
        lab = lab[np.clip(src, 0, lab.size - 1)]
    return m, lab


def _windows(labels: np.ndarray, n: int, step: int) -> list[int]:
    return [end for end in range(n, labels.size + 1, step) if labels[end - 1]]


class Search:
    """The window search over a whole bank: every window inside a take, every view. With
    ``actions`` (``control.motion.action_keys`` of the bank's clips) the decision is the
    matcher's vote: each action's best window and the library's action classifier
    (``vision._classify``); ``nearest`` keeps the best window's label alone."""

    def __init__(
        self,
        bank: Any,
        n: int,
        lib_labels: np.ndarray,
        actions: np.ndarray | None = None,
        recency: float = RECENCY,
    ) -> None:
        self.bank = bank
        self.recency = recency
        self.desc = bank.settings.features
        self.n = n
        self.mean, self.proj = shape_stats(bank)
        frames = np.arange(bank.n_frames)
        self.shape, self.centre = window_tables(
            bank, frames, bank.clip_start, self.mean, self.proj, CENTRE_WEIGHT
        )
        cs = bank.clip_start
        self.starts = np.concatenate(
            [np.arange(a, b - n + 1) for a, b in itertools.pairwise(cs)]
        ).astype(np.int64)
        self.lib_labels = lib_labels
        self.actions = actions
        self.classifier = None
        if actions is not None:
            self.classifier = ActionClassifier.learn(
                self.shape, self.centre, self.starts, n, actions
            )
            end = actions[self.starts + n - 1]
            self.by_action = [self.starts[end == a] for a in range(int(actions.max()) + 1)]
            ids, first = np.unique(actions, return_index=True)  # each action's first frame
            self.names = [""] * len(self.by_action)
            for a, f in zip(ids, first, strict=True):
                self.names[a] = str(lib_labels[f])
        #: the label of the last call's best window (the nearest alone)
        self.nearest = ""

    def __call__(self, feats: np.ndarray) -> tuple[str, float] | None:
        """The label the decision names for performer features ``(n, F)`` (the vote's
        action, or the best window's label), and the best window's per-frame cost;
        ``None`` with fewer than half the frames usable."""
        ok = np.isfinite(feats).all(axis=1)
        if ok.sum() < max(2, self.n // 2):  # as the matcher
            return None
        qs = performer_queries(feats[ok], self.desc, self.mean, self.proj, CENTRE_WEIGHT)
        r = self.recency
        s, _, cost = best_window(qs, self.shape, self.centre, self.starts, self.n, BAND, r)
        self.nearest = str(self.lib_labels[s + self.n - 1])
        label = self.nearest
        if self.classifier is not None:
            costs = np.array(
                [
                    best_window(qs, self.shape, self.centre, st, self.n, BAND, r)[2]
                    if st.size
                    else np.inf
                    for st in self.by_action
                ]
            )
            a = choose_action(costs, self.classifier.log_proba(qs, costs.size))
            label = self.names[a]
        return label, per_frame_cost(cost, qs[0].shape[0])

    def chance(self, labels: list[str]) -> float:
        ends = self.lib_labels[self.starts + self.n - 1]
        u, c = np.unique(labels, return_counts=True)
        return float(sum(k / len(labels) * np.mean(ends == a) for a, k in zip(u, c, strict=True)))


def _score(search: Search, feats: np.ndarray, labels: np.ndarray, step: int) -> dict[str, Any]:
    hits: dict[str, list[bool]] = {}
    nearest = []
    costs = []
    truth = []
    for end in _windows(labels, search.n, step):
        got = search(feats[end - search.n : end])
        if got is None:
            continue
        t = str(labels[end - 1])
        truth.append(t)
        hits.setdefault(t, []).append(got[0] == t)
        nearest.append(search.nearest == t)
        costs.append(got[1])
    every = [h for v in hits.values() for h in v]
    return {
        "windows": len(every),
        "right": round(float(np.mean(every)), 3) if every else None,
        "right_nearest_window": round(float(np.mean(nearest)), 3) if nearest else None,
        "per_action": {a: round(float(np.mean(v)), 3) for a, v in sorted(hits.items())},
        "chance": round(search.chance(truth), 3) if truth else None,
        "costs": costs,
    }


def _pose_points(motion: Motion, rs: RecordSettings, rng: np.random.Generator) -> np.ndarray:
    """Pose vectors ``(F, 26)`` of the performer's joints seen by ``rs``'s camera, with
    landmark noise of 3% of the torso length."""
    desc = get_descriptor("pose")
    assert isinstance(desc, PoseDescriptor)
    return desc.from_points(landmark_points(motion, rs, rng))


def _garbage(masks: np.ndarray, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Masks no real pose matches: the performer upside down, and random blobs."""
    blobs = np.zeros_like(masks)
    for i in range(masks.shape[0]):
        for _ in range(6):
            c = (
                int(rng.integers(20, masks.shape[2] - 20)),
                int(rng.integers(20, masks.shape[1] - 20)),
            )
            cv2.circle(blobs[i], c, int(rng.integers(4, 18)), 1, -1)
    return {"upside_down": np.ascontiguousarray(masks[:, ::-1]), "blobs": blobs}


def _over(x: list[float], limit: float) -> float | None:
    """The share of per-frame costs ``x`` over ``limit`` (what the matcher rejects)."""
    return round(float(np.mean(np.asarray(x) > limit)), 3) if x else None


def _quantiles(x: list[float]) -> dict[str, float] | None:
    if not x:
        return None
    q = np.quantile(np.asarray(x), [0.5, 0.9, 0.99])
    return {
        "p50": round(float(q[0]), 3),
        "p90": round(float(q[1]), 3),
        "p99": round(float(q[2]), 3),
    }


def folds(
    root: Path,
    takes: list[str],
    descriptors: list[str],
    window: float,
    variants: bool,
    classify: bool = True,
    recency: float = RECENCY,
) -> dict[str, Any]:
    lib = load_library(root, clips=takes)
    rate = float(lib.fps or 15.0)
    out: dict[str, Any] = {}
    rng = np.random.default_rng(0)
    for name in descriptors:
        desc = get_descriptor(name)
        per_fold: dict[str, Any] = {}
        true_costs: list[float] = []
        junk: dict[str, list[float]] = {}
        for test in takes:
            train = [c for c in lib.clips if c.name in takes and c.name != test]
            base = BankSettings(descriptor=name)
            settings = robust_settings(base) if variants and desc.kind == "silhouette" else base
            t0 = time.perf_counter()
            bank, _, _ = cached_bank(train, settings)
            lib_labels = np.concatenate([_labels(c) for c in train])
            n = max(2, round(window * rate))
            keys = action_keys(train) if classify else None
            search = Search(bank, n, lib_labels, keys, recency)
            step = max(1, round(0.5 * rate))
            rows: dict[str, Any] = {}
            for var, kw in VARIATIONS.items():
                motion, labels = performer(
                    lib.clip(test), kw.get("tempo", 1.0), kw.get("mirrored", False)
                )
                bad: dict[str, np.ndarray] = {}
                if desc.kind == "pose":
                    feats = _pose_points(motion, kw["rs"], rng)
                    if var == "base":  # upside down, and landmarks strewn at random
                        flip = feats.copy()
                        flip[:, 1 : desc.n_shape : 2] *= -1.0
                        strewn = feats.copy()
                        strewn[:, : desc.n_shape] = rng.uniform(
                            -2, 2, (feats.shape[0], desc.n_shape)
                        )
                        bad = {"upside_down": flip, "random": strewn}
                else:
                    masks = performer_masks(motion, kw["rs"])
                    feats = np.array([silhouette_features(m, descriptor=name) for m in masks])
                    if var == "base":
                        bad = {
                            what: np.array(
                                [silhouette_features(m, descriptor=name) for m in junk_masks]
                            )
                            for what, junk_masks in _garbage(masks, rng).items()
                        }
                for what, bf in bad.items():
                    for end in range(n, bf.shape[0] + 1, 4 * step):
                        got = search(bf[end - n : end])
                        if got is not None:
                            junk.setdefault(what, []).append(got[1])
                r = _score(search, feats, labels, step)
                true_costs += r.pop("costs")
                rows[var] = r
            rights = [r["right"] for r in rows.values() if r["right"] is not None]
            per_fold[test] = {
                "library": [c.name for c in train],
                "mean_right": round(float(np.mean(rights)), 3),
                "seconds": round(time.perf_counter() - t0, 1),
                "variations": rows,
            }
            print(
                f"{name} {test}: {per_fold[test]['mean_right']} "
                f"{ {k: v['right'] for k, v in rows.items()} }",
                flush=True,
            )
        actions: dict[str, list[float]] = {}
        for f in per_fold.values():
            for r in f["variations"].values():
                for a, v in r["per_action"].items():
                    actions.setdefault(a, []).append(v)
        out[name] = {
            "mean_right": round(float(np.mean([f["mean_right"] for f in per_fold.values()])), 3),
            "min_fold": round(float(min(f["mean_right"] for f in per_fold.values())), 3),
            "mean_chance": round(
                float(
                    np.mean(
                        [r["chance"] for f in per_fold.values() for r in f["variations"].values()]
                    )
                ),
                3,
            ),
            "per_action": {a: round(float(np.mean(v)), 3) for a, v in sorted(actions.items())},
            "folds": per_fold,
            "cost_true": _quantiles(true_costs),
            "cost_garbage": {k: _quantiles(v) for k, v in junk.items()},
            "reject": desc.reject,
            "rejected_true": _over(true_costs, desc.reject),
            "rejected_garbage": {k: _over(v, desc.reject) for k, v in junk.items()},
        }
    return out


def real_clips(
    root: Path,
    takes: list[str],
    videos: Path,
    labels: Path,
    window: float,
    classify: bool = True,
    recency: float = RECENCY,
) -> dict[str, Any]:
    """The pose descriptor on the shared real clips: MediaPipe landmarks, a pose bank of
    all the takes, the label of the best window against ours; beside it the default
    silhouette descriptor on the pose model's person masks."""
    lib = load_library(root, clips=takes)
    rate = float(lib.fps or 15.0)
    bank, _, _ = cached_bank(list(lib.clips), BankSettings(descriptor="pose"))
    sil_bank, _, _ = cached_bank(list(lib.clips), BankSettings())
    lib_labels = np.concatenate([_labels(c) for c in lib.clips])
    n = max(2, round(window * rate))
    actions = action_keys(list(lib.clips)) if classify else None
    search = Search(bank, n, lib_labels, actions, recency)
    sil_search = Search(sil_bank, n, lib_labels, actions, recency)
    names = {a.lower(): a for a in set(lib_labels) - {""}}
    out: dict[str, Any] = {}
    spans: dict[str, list[tuple[float, float, str]]] = {}
    for file, start, end, label in read_labels(labels):  # a file may have several spans
        spans.setdefault(file, []).append((start, end, label))
    for file, labelled in spans.items():
        cap = cv2.VideoCapture(str(videos / file))
        fps = cap.get(cv2.CAP_PROP_FPS) or 30.0
        model, reader = PersonSegmenter("pose"), PoseReader()
        vecs, why, sil = [], [], []
        blank = np.full(sil_bank.settings.features.size, np.nan)
        while True:
            ok, img = cap.read()
            if not ok:
                break
            mask = model.apply(np.asarray(img, dtype=np.uint8))
            sil.append(blank if mask is None else silhouette_features(mask))
            vecs.append(reader.read(model.landmarks, (img.shape[1], img.shape[0])))
            why.append(reader.why)
        cap.release()
        model.close()
        # the library-rate buffer: the latest video frame at each library tick
        t = np.arange(0.0, len(vecs) / fps, 1.0 / rate)
        idx = np.minimum((t * fps + 1e-9).astype(int), len(vecs) - 1)
        feats = np.array(vecs)[idx]
        sil_feats = np.array(sil)[idx]
        hits = []
        sil_hits = []
        costs = []
        truths = []
        for e in range(n, idx.size + 1, max(1, round(0.5 * rate))):
            te = t[e - 1]
            inside = [lab for a, b, lab in labelled if a <= te <= b]
            if not inside:
                continue
            truth = names.get(inside[0].lower())
            got = search(feats[e - n : e])
            if got is None:
                continue
            hits.append(got[0] == truth)
            truths.append(str(truth))
            costs.append(got[1])
            sil_got = sil_search(sil_feats[e - n : e])
            sil_hits.append(sil_got is not None and sil_got[0] == truth)
        # garbage: the same landmarks upside down
        flip = feats.copy()
        k = get_descriptor("pose").n_shape
        flip[:, 1:k:2] *= -1.0
        bad = [
            g[1] for e in range(n, idx.size + 1, n) if (g := search(flip[e - n : e])) is not None
        ]
        out[file] = {
            "labels": sorted({lab for _, _, lab in labelled}),
            "spans": [[a, b] for a, b, _ in labelled],
            "frames": len(vecs),
            "fps": fps,
            "frames_without_pose": int(sum(1 for w in why if w)),
            "windows": len(hits),
            "right": round(float(np.mean(hits)), 3) if hits else None,
            "chance": round(search.chance(truths), 3) if hits else None,
            "silhouette_descriptor": sil_bank.settings.descriptor,
            "right_silhouette_masks": round(float(np.mean(sil_hits)), 3) if sil_hits else None,
            "cost_true": _quantiles(costs),
            "cost_upside_down": _quantiles(bad),
            "rejected_true": _over(costs, search.desc.reject),
            "rejected_upside_down": _over(bad, search.desc.reject),
        }
        print(f"pose on {file}: {out[file]['right']} of {len(hits)} windows", flush=True)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", nargs="?", default=str(default_library_path()))
    ap.add_argument("--takes", default="13_29,13_30,13_31")
    ap.add_argument("--descriptors", default="outline,multigrid,grid,hu,pose")
    ap.add_argument("--window", type=float, default=1.0, help="seconds per window")
    ap.add_argument("--variants", action="store_true", help="silhouette banks with body variants")
    ap.add_argument("--videos", default=str(HERE.parents[1] / "shared" / "video"))
    ap.add_argument("--labels", default=str(HERE / "videos" / "shared_labels.csv"))
    ap.add_argument("--no-video", action="store_true", help="skip the real clips")
    ap.add_argument(
        "--nearest",
        action="store_true",
        help="the best window's label alone, without the action classifier",
    )
    ap.add_argument(
        "--recency",
        type=float,
        default=RECENCY,
        help="DTW's weighing of the window's last frames (the matcher's --recency)",
    )
    ap.add_argument("--out", default="benchmarks/results/recognition.json")
    args = ap.parse_args()
    root = Path(args.root)
    takes = args.takes.split(",")
    result: dict[str, Any] = {
        "machine": machine(),
        "date": time.strftime("%Y-%m-%d"),
        "takes": takes,
        "window": args.window,
        "variants": args.variants,
        "variations": {
            k: {**v["rs"].to_dict(), **{a: b for a, b in v.items() if a != "rs"}}
            for k, v in VARIATIONS.items()
        },
        "classifier": not args.nearest,
        "descriptors": folds(
            root,
            takes,
            [d for d in args.descriptors.split(",") if d],
            args.window,
            args.variants,
            not args.nearest,
            args.recency,
        ),
        "recency": args.recency,
    }
    if not args.no_video:
        result["real_clips_pose"] = real_clips(
            root,
            takes,
            Path(args.videos),
            Path(args.labels),
            args.window,
            not args.nearest,
            args.recency,
        )
    save(result, args.out)


if __name__ == "__main__":
    main()
