"""Vision speed: segmentation per camera frame, matcher latency, replay real-time factor;
and the choice of background subtractor, by measurement.

Usage: python -m benchmarks.bench_vision [LIBRARY_DIR] [--out FILE] [--variants]
       [--descriptor multigrid|grid|hu] [--page] [--socket]

- Subtractors (MOG2, KNN and opencv-contrib's bgsegm CNT, GSOC, LSBP, GMG, MOG) on a
  640x480 composite: the committed recording's silhouettes, filled with a textured
  "shirt", moving over a textured background with sensor noise and a slow illumination
  drift, after 30 frames without the performer. IoU with the true silhouette, and frames
  per second for segmentation + cleanup + features on one core. Target >= 60 frames/s.
- Matcher latency per decision (p50, p99) and candidate counts, on the playground and the
  all-shared libraries (default graph, 1 s window, 1.5 s look-ahead). Target p99 <= 5 ms
  on all-shared.
- The global window search (the avatar's start and relocation, once a second): time
  per search. ``--variants``: the matcher again on all-shared with the bank variants.
  ``--descriptor``: the banks' descriptor (default: the bank's default, multigrid).
- A 60 s silhouette recording (13_29, made here) replayed offline through `perform`:
  wall time and real-time factor.
- ``--page`` (alone; default out ``benchmarks/results/page.json``): the live page end to
  end, a headless Chromium's fake camera playing real clips into ``mimic perform
  --camera browser`` (``benchmarks/_page.py``): camera-to-avatar time, frames a second.
- ``--socket`` (alone; default out ``benchmarks/results/socket.json``): the WebSocket
  servers the page could use, a frame up and a pose down 30 times a second
  (``benchmarks/_socket.py``): round trip p50/p99 and CPU.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from benchmarks._page import page
from benchmarks._report import machine, save
from benchmarks._socket import sockets
from control.avatar import Avatar
from control.clusters import LayerSettings, cached_higher_layer
from control.graph import GraphOptions, build_graph
from control.kernels import one_thread
from control.motion import default_library_path, load_library
from silhouette_bank import (
    DEFAULT_DESCRIPTOR,
    DESCRIPTORS,
    BankSettings,
    cached_bank,
    robust_settings,
    silhouette_features,
)
from vision import (
    METHODS,
    Matcher,
    MatchSettings,
    PathSettings,
    PerformSettings,
    RecordSettings,
    Segmenter,
    VideoSource,
    perform,
    record_clip,
)

RECORDING = Path("recordings/13_29_first12s_160x120.mkv")


def composite_frames(n_empty: int = 30) -> tuple[list[np.ndarray], list[np.ndarray | None]]:
    cap = cv2.VideoCapture(str(RECORDING))
    masks = []
    while True:
        ok, img = cap.read()
        if not ok:
            break
        masks.append(cv2.resize(img[..., 0], (640, 480), interpolation=cv2.INTER_NEAREST) > 127)
    rng = np.random.default_rng(0)
    yy, xx = np.mgrid[0:480, 0:640]
    bg = np.stack(
        [
            90 + 40 * np.sin(xx / 37.0) + 20 * np.cos(yy / 23.0),
            110 + 30 * np.sin((xx + yy) / 51.0),
            100 + 25 * np.cos(xx / 13.0) * np.sin(yy / 17.0),
        ],
        axis=-1,
    )
    bg += rng.normal(0, 10, bg.shape)
    shirt = np.stack(
        [60 + 40 * np.sin(xx / 5.0), 60 + 30 * np.cos(yy / 7.0), 150 + 0 * xx], axis=-1
    )
    frames: list[np.ndarray] = []
    truth: list[np.ndarray | None] = []
    for i in range(n_empty + len(masks)):
        drift = 1.0 + 0.05 * np.sin(i / 40.0)
        img = bg * drift
        m = masks[i - n_empty] if i >= n_empty else None
        if m is not None:
            img = np.where(m[..., None], shirt, img)
        img = img + rng.normal(0, 4, img.shape)
        frames.append(np.clip(img, 0, 255).astype(np.uint8))
        truth.append(m)
    return frames, truth


def subtractors() -> dict[str, Any]:
    cv2.setNumThreads(1)
    frames, truth = composite_frames()
    out: dict[str, Any] = {}
    for method, adapt in [(m, 0.0) for m in METHODS] + [("mog2", 0.001), ("knn", 0.001)]:
        seg = Segmenter(method, learn_frames=30, adapt=adapt)
        ious = []
        t = time.perf_counter()
        for img, m in zip(frames, truth, strict=True):
            mask = seg.apply(img)
            if mask is not None:
                silhouette_features(mask.astype(np.uint8))
            if m is not None:
                ious.append(0.0 if mask is None else float((mask & m).sum() / (mask | m).sum()))
        fps = len(frames) / (time.perf_counter() - t)
        out[f"{method} adapt={adapt:g}"] = {
            "iou_mean": float(np.mean(ious)),
            "iou_p10": float(np.percentile(ious, 10)),
            "fps": fps,
        }
    cv2.setNumThreads(-1)
    return out


def matcher_latency(
    root: Path,
    patterns: list[str] | None,
    lookaheads: tuple[float, ...] = (1.5, 6.0),
    bank_settings: BankSettings | None = None,
) -> dict[str, Any]:
    lib = load_library(root, clips=patterns)
    g = build_graph(lib.clips, GraphOptions(coords="relative"))
    layer, _, _ = cached_higher_layer(g, lib.clips, LayerSettings(bound_seconds=2.0))
    bank, _, _ = cached_bank(lib.clips, bank_settings or BankSettings())
    src = VideoSource(RECORDING, silhouette=True)
    feats = []
    while (f := src.read()) is not None:
        if f.index % 2 == 0:
            mask = np.asarray(f.mask, dtype=np.uint8)
            feats.append(silhouette_features(mask, descriptor=bank.settings.descriptor))
    perf = np.array(feats)
    out: dict[str, Any] = {
        "frames": g.n_frames,
        "bank_views": bank.features.shape[1],
        "descriptor": bank.settings.descriptor,
        "forest": layer.forest.report,
    }
    for lookahead in lookaheads:
        matcher = Matcher(layer, bank, MatchSettings(paths=PathSettings(lookahead=lookahead)))
        rng = np.random.default_rng(0)
        lat, cands = [], []
        for f in rng.choice(np.flatnonzero(g.in_scc), 400):
            s = int(rng.integers(0, perf.shape[0] - matcher.n))
            matcher.decide(int(f), perf[s : s + matcher.n])  # warm the path cache, as a run does
            d = matcher.decide(int(f), perf[s : s + matcher.n])
            if d is not None:
                lat.append(d.latency_ms)
                cands.append(d.candidates)
        out[f"lookahead_{lookahead:g}s"] = {
            "decisions": len(lat),
            "latency_ms_p50": float(np.percentile(lat, 50)),
            "latency_ms_p99": float(np.percentile(lat, 99)),
            "candidates_median": float(np.median(cands)),
            "candidates_p99": float(np.percentile(cands, 99)),
        }
    # the brute-force global search (--no-jumps: start and relocation, once a second);
    # the fast index against it is benchmarks/bench_search.py
    clips = g.clips_of(lib.clips)
    matcher = Matcher(layer, bank, MatchSettings())
    ms = []
    for s in range(0, perf.shape[0] - matcher.n, 15):
        t0 = time.perf_counter()
        matcher.find_window(perf[s : s + matcher.n], exact=True)
        ms.append((time.perf_counter() - t0) * 1e3)
    out["global_search_ms_p50"] = float(np.median(ms))
    out["global_search_ms_max"] = float(np.max(ms))
    rng = np.random.default_rng(1)
    # whole decisions with jumps, from random avatar frames with a played-on history
    avatar = Avatar(g, lib.clips, seed=0, anywhere=True)
    # as perform does before its first frame: the frame features of jump costs, the index,
    # the vote (its classifier and each action's search) and the facing
    t0 = time.perf_counter()
    _ = avatar.jump_costs.features
    matcher.windows.index()
    # perform's throwaway decision, so that no timed one compiles a kernel (one takes
    # hundreds of milliseconds without numba's cache), then the vote
    matcher.warm_up(avatar.frame, avatar.recent(matcher.recent_frames), avatar.jump_costs)
    matcher.ready(clips, PerformSettings().decide_every)
    out["vote"] = matcher.vote.actions is not None
    out["decision_warm_up_s"] = round(time.perf_counter() - t0, 3)
    lat = []
    with one_thread():  # as perform's loop (control.kernels.one_thread)
        for _ in range(300):
            at = int(rng.integers(matcher.n, g.n_frames - matcher.n))
            if not matcher.plays[at - matcher.n : at].all():
                continue
            s = int(rng.integers(0, perf.shape[0] - matcher.n))
            recent = np.arange(at - matcher.n + 1, at + 1)
            d = matcher.decide(at, perf[s : s + matcher.n], recent, avatar.jump_costs)
            if d is not None:
                lat.append(d.latency_ms)
    out["decision_with_jumps_ms_p50"] = float(np.percentile(lat, 50))
    out["decision_with_jumps_ms_p99"] = float(np.percentile(lat, 99))
    out["decision_with_jumps_ms_max"] = float(np.max(lat))
    out["decisions_over_100ms"] = int(np.sum(np.array(lat) > 100))
    return out


def replay(root: Path, bank_settings: BankSettings) -> dict[str, Any]:
    lib = load_library(root, clips=["13_30"])
    g = build_graph(lib.clips, GraphOptions(coords="relative", threshold=0.03))
    layer, _, _ = cached_higher_layer(g, lib.clips, LayerSettings(bound_seconds=2.0))
    bank, _, _ = cached_bank(lib.clips, bank_settings)
    with tempfile.TemporaryDirectory() as tmp:
        clip = load_library(root, fps=30, clips=["13_29"]).clip("13_29")
        video = Path(tmp) / "60s.mkv"
        record_clip(
            clip, video, RecordSettings(width=320, height=240), 0, min(1800, clip.motion.n_frames)
        )
        t = time.perf_counter()
        r = perform(VideoSource(video, silhouette=True), layer, bank, lib.clips, PerformSettings())
        wall = time.perf_counter() - t
    return {
        "media_seconds": r.media_seconds,
        "wall_seconds": wall,
        "real_time_factor": r.media_seconds / wall,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", nargs="?", default=str(default_library_path()))
    ap.add_argument("--out", default="benchmarks/results/vision.json")
    ap.add_argument(
        "--variants",
        action="store_true",
        help="also time the matcher on all-shared with the bank variants (builds that bank)",
    )
    ap.add_argument(
        "--descriptor",
        default=DEFAULT_DESCRIPTOR,
        choices=[d for d in DESCRIPTORS if d != "pose"],  # it replays silhouettes
        help="the banks' silhouette descriptor (default multigrid)",
    )
    ap.add_argument("--page", action="store_true", help="only the live page, end to end")
    ap.add_argument("--socket", action="store_true", help="only the WebSocket servers")
    args = ap.parse_args()
    root = Path(args.root)
    if args.page or args.socket:
        name = "page" if args.page else "socket"
        out = args.out if args.out != ap.get_default("out") else f"benchmarks/results/{name}.json"
        got = page(root) if args.page else sockets()
        save({"machine": machine(), "date": time.strftime("%Y-%m-%d"), **got}, out)
        return
    base = BankSettings(descriptor=args.descriptor)
    result: dict[str, Any] = {
        "machine": machine(),
        "date": time.strftime("%Y-%m-%d"),
        "subtractors_640x480": subtractors(),
        "descriptor": args.descriptor,
        "matcher_playground": matcher_latency(root, ["01_*"], bank_settings=base),
        "matcher_all_shared": matcher_latency(root, None, bank_settings=base),
        "replay": replay(root, base),
    }
    if args.variants:
        result["matcher_all_shared_variants"] = matcher_latency(
            root, None, bank_settings=robust_settings(base)
        )
    save(result, args.out)


if __name__ == "__main__":
    main()
