"""Real people on real video (issue 9): segmentation without a plate, and label agreement
on labelled footage.

Usage: python -m benchmarks.bench_real_video [--videos DIR] [--labels CSV]
       [--library DIR] [--clips PATTERN]... [--coords C] [--sigma-scale S] [--variants]
       [--descriptor auto|pose|outline|multigrid|grid|hu] [--recency R]
       [--perform-args "MORE FLAGS"] [--no-segmentation] [--out FILE]

- Segmentation, for every video in ``--videos`` (default ``../shared/video``), with a
  plate subtractor (MOG2 learning the first 30 frames, as a camera would: here the
  person is already in view) and both person segmenters (MediaPipe selfie and pose):
  time per frame at 640x480 on one core, the share of the frame each calls the person,
  and the overlap (IoU) of each with the selfie model's masks. Contact sheets of the
  masks (no picture pixels: the footage is not ours to copy) go to
  ``results/real_video_<name>.png``.
- Label agreement, for every row of ``--labels`` (a CSV ``file,start,end,label`` with
  times in seconds; ``file`` relative to ``--videos``; default
  ``benchmarks/videos/shared_labels.csv``, our own labels of the shared clips): each
  video is replayed through ``mimic evaluate``'s loop, prepared by the command line's
  own code (``mimic.run.prepare``, the flags given here passed on to it) against the
  library (default: every shared clip that stays on the floor, as ``mimic perform``
  takes it, with its defaults: the pose descriptor with MediaPipe), and at every
  decision the avatar's current frame's label is compared with the video's label
  ``lag`` seconds earlier. Agreement per video and overall, for lags 0-3 s, and the
  loop's frames per second with person segmentation: replayed (waiting for every global
  search, deterministic) and as a camera runs it (the search in a thread). Label names
  must be the library's (JumpJack, Squat, KneeRaise, ...; case does not matter).
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import os
import shlex
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from benchmarks._report import machine, save
from control.graph import GraphOptions
from control.motion import default_library_path
from mimic.cli import build_parser
from mimic.run import prepare
from mimic.run_args import run_settings, silhouette_flag
from silhouette_bank import (
    DESCRIPTORS,
)
from vision import (
    LAGS,
    LabelFileError,
    MatchSettings,
    PersonSegmenter,
    Segmenter,
    Truth,
    evaluation,
    open_source,
    perform,
)
from vision._truth import read_span_labels as read_labels

HERE = Path(__file__).resolve().parent


def _frames(path: Path, size: tuple[int, int] | None = None) -> list[np.ndarray]:
    cap = cv2.VideoCapture(str(path))
    out = []
    while True:
        ok, img = cap.read()
        if not ok:
            break
        out.append(cv2.resize(img, size) if size else img)
    cap.release()
    return out


def _sheet(rows: Sequence[Sequence[np.ndarray | None]], names: Sequence[str]) -> np.ndarray:
    """Masks as a grid: one row per backend, white on black, 160 px high, named."""
    out = []
    for name, masks in zip(names, rows, strict=True):
        tiles = []
        for m in masks:
            h, w = (160, 160) if m is None else (160, round(160 * m.shape[1] / m.shape[0]))
            tile = (
                np.zeros((h, w), np.uint8)
                if m is None
                else cv2.resize(m.astype(np.uint8) * 255, (w, h))
            )
            tiles.append(np.pad(tile, 2, constant_values=90))
        row = cv2.cvtColor(np.hstack(tiles), cv2.COLOR_GRAY2BGR)
        cv2.putText(row, name, (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 255), 1)
        out.append(row)
    width = max(r.shape[1] for r in out)
    return np.vstack([np.pad(r, ((0, 0), (0, width - r.shape[1]), (0, 0))) for r in out])


def _segmenters() -> list[Any]:
    """A plate subtractor (learning the first 30 frames) and both person segmenters."""
    return [Segmenter("mog2", learn_frames=30), PersonSegmenter("selfie"), PersonSegmenter("pose")]


def segmentation(videos: Path, results: Path) -> dict[str, Any]:
    out: dict[str, Any] = {}
    backends = ("mog2 (plate: first 30 frames)", "selfie", "pose")
    for path in sorted(videos.glob("*.mp4")):
        full = _frames(path)
        small = _frames(path, (640, 480))
        models = _segmenters()
        masks: list[list[np.ndarray | None]] = [[], [], []]
        ms: list[list[float]] = [[], [], []]
        for k, seg in enumerate(models):
            for img in small:  # timing at the camera size
                t0 = time.perf_counter()
                seg.apply(img)
                ms[k].append((time.perf_counter() - t0) * 1e3)
        models = _segmenters()
        for k, seg in enumerate(models):
            masks[k] = [seg.apply(img) for img in full]
        ref = masks[1]
        entry: dict[str, Any] = {
            "frames": len(full),
            "size": f"{full[0].shape[1]}x{full[0].shape[0]}",
        }
        for k, name in enumerate(backends):
            start = 30 if k == 0 else 0
            cover = [float(m.mean()) if m is not None else 0.0 for m in masks[k][start:]]
            ious = [
                float((m & r).sum() / (m | r).sum()) if m is not None else 0.0
                for m, r in zip(masks[k][start:], ref[start:], strict=True)
                if r is not None
            ]
            entry[name] = {
                "ms_per_frame_640x480_p50": round(float(np.median(ms[k])), 2),
                "frames_per_s": round(1e3 / float(np.median(ms[k])), 1),
                "person_share_mean": round(float(np.mean(cover)), 3),
                "empty_frames": int(sum(m is None for m in masks[k][start:])),
                "iou_with_selfie_median": round(float(np.median(ious)), 3) if ious else None,
            }
        pick = np.linspace(30, len(full) - 1, 6).round().astype(int)
        sheet = _sheet([[masks[k][i] for i in pick] for k in range(3)], backends)
        png = results / f"real_video_{path.stem}.png"
        cv2.imwrite(str(png), sheet)
        entry["contact_sheet"] = str(png)
        out[path.name] = entry
        print(path.name, {k: v for k, v in entry.items() if isinstance(v, dict)})
    return out


def _run_args(
    clips: Sequence[str] | None,
    options: GraphOptions,
    variants: bool,
    descriptor: str,
    recency: float,
    extra: Sequence[str] = (),
) -> list[str]:
    """This benchmark's options as ``mimic evaluate``'s flags (``extra``: any more)."""
    out = [f"--clips={c}" for c in clips or ()]
    out += [f"--coords={options.coords}", f"--sigma-scale={options.sigma_scale!r}"]
    out += ["--variants"] * variants + [f"--descriptor={descriptor}", f"--recency={recency!r}"]
    return [*out, *extra]


def agreement(
    videos: Path,
    labels: Path,
    root: Path,
    run_args: Sequence[str] = (),
) -> dict[str, Any]:
    """Each labelled video replayed through ``mimic evaluate``'s own preparation
    (``mimic.run.prepare``: the library, graph, higher layer, bank, descriptor and
    settings it chooses, with ``run_args``, its flags), so that these figures are what a
    user gets: a preparation of its own would drift apart from the command line's."""
    rows = read_labels(labels)
    names = sorted({r[0] for r in rows})
    per_video: dict[str, Any] = {}
    pooled: dict[float, list[tuple[float, int]]] = {lag: [] for lag in LAGS}
    ready = None
    for name in names:
        path = videos / name
        if not path.is_file():
            raise LabelFileError(f"{labels}: no video {path}")
        spans = [(a, b, lab.lower()) for f, a, b, lab in rows if f == name]
        argv = ["evaluate", str(path), "--labels", str(labels), "--json", os.devnull]
        args = build_parser().parse_args([*argv, "--library", str(root), *run_args])
        source = open_source(None, str(path), None, silhouette=silhouette_flag(args))
        ready = prepare(run_settings(args), source)
        # (mimic evaluate's own call: the silhouette decides where the landmarks fail)
        run = functools.partial(
            perform, start=ready.start, seed=args.seed, fallback=ready.fallback, voice=ready.voice
        )
        t0 = time.perf_counter()
        result = run(source, ready.layer, ready.bank, ready.clips, ready.settings)
        wall = time.perf_counter() - t0
        source.close()
        # the loop as a camera runs it: relocation's search in a thread (the agreement
        # above comes from the deterministic replay, which waits for every search)
        source = open_source(None, str(path), None, silhouette=silhouette_flag(args))
        live_settings = dataclasses.replace(ready.settings, background_search=True)
        t0 = time.perf_counter()
        live = run(source, ready.layer, ready.bank, ready.clips, live_settings)
        live_wall = time.perf_counter() - t0
        source.close()
        # mimic evaluate's figures (vision._evaluate) for this video
        truth = Truth(tuple(spans), str(labels))
        report = evaluation(result.decisions, ready.clips, truth, result.media_seconds, LAGS)
        curve = report["agreement_by_lag_s"]
        per_video[name] = {
            "agreement_by_lag_s": curve,
            "best_at_lag_le_1s": max(
                (v for k, v in curve.items() if float(k) <= 1.0 and v is not None), default=None
            ),
            "per_action_at_best_lag": report["per_action_at_best_lag"],
            "confusion_at_best_lag": report["confusion_at_best_lag"],
            "chance": report["chance"],
            "switches_per_minute": report["switches_per_minute"],
            "switch_followed_after_s": report["switch_followed_after_s"],
            "decisions": len(result.decisions),
            "loop_frames_per_s": round(result.frames_read / wall, 1),
            "loop_frames_per_s_search_in_thread": round(live.frames_read / live_wall, 1),
        }
        for lag in LAGS:
            k = f"{lag:g}"
            if curve[k] is not None:
                pooled[lag].append((curve[k], report["decisions_by_lag_s"][k]))
        print(name, per_video[name])
    if ready is None:
        raise LabelFileError(f"{labels}: no labelled video")
    overall = {
        f"{lag:g}": round(sum(r * n for r, n in h) / sum(n for _, n in h), 3) if h else None
        for lag, h in pooled.items()
    }
    graph = ready.graph
    return {
        "labels": str(labels),
        "mimic_evaluate_flags": list(run_args),
        "library": [c.name for c in ready.clips],
        "frames": graph.n_frames,
        "graph": {
            "coords": graph.options.coords,
            "sigma_scale": graph.options.sigma_scale,
            "edges": graph.n_edges,
            "scc_frames": int(graph.in_scc.sum()),
        },
        "bank_views": ready.bank.features.shape[1],
        "descriptor": ready.descriptor,
        "match": dataclasses.asdict(ready.settings.match),
        "per_video": per_video,
        "overall_by_lag_s": overall,
        "overall_best_at_lag_le_1s": max(
            (v for k, v in overall.items() if float(k) <= 1.0 and v is not None), default=None
        ),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    default_videos = default_library_path().parent / "video"
    ap.add_argument("--videos", default=str(default_videos), help="folder of videos")
    ap.add_argument("--labels", default=str(HERE / "videos" / "shared_labels.csv"))
    ap.add_argument("--library", default=str(default_library_path()))
    ap.add_argument("--clips", action="append", help="library clips to match against")
    ap.add_argument("--no-segmentation", action="store_true", help="skip the mask sheets")
    ap.add_argument("--coords", default="relative", choices=("fixed", "relative"))
    ap.add_argument(
        "--sigma-scale", type=float, default=GraphOptions.sigma_scale, help="graph sigma scale"
    )
    ap.add_argument("--variants", action="store_true", help="bank with other bodies, shadows")
    ap.add_argument(
        "--descriptor",
        default="auto",
        choices=("auto", *DESCRIPTORS),
        help="auto (default, as mimic perform): pose with MediaPipe, else outline",
    )
    ap.add_argument(
        "--recency",
        type=float,
        default=MatchSettings.recency,
        help="the matcher's weighing of the window's last frames (as mimic perform's)",
    )
    ap.add_argument(
        "--perform-args",
        default="",
        help="more of mimic evaluate's flags, as one string: --perform-args '--window 0.7'",
    )
    ap.add_argument("--out", default="benchmarks/results/real_video.json")
    args = ap.parse_args()
    videos = Path(args.videos)
    result: dict[str, Any] = {"machine": machine(), "date": time.strftime("%Y-%m-%d")}
    if not args.no_segmentation:
        result["segmentation"] = segmentation(videos, Path(args.out).parent)
    options = GraphOptions(coords=args.coords, sigma_scale=args.sigma_scale)
    flags = _run_args(
        args.clips,
        options,
        args.variants,
        args.descriptor,
        args.recency,
        shlex.split(args.perform_args),
    )
    result["agreement"] = agreement(videos, Path(args.labels), Path(args.library), flags)
    save(result, args.out)


if __name__ == "__main__":
    main()
