"""``mimic library info``, ``mimic library labels`` and ``mimic library embed``."""

from __future__ import annotations

import argparse
import csv
import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from control.artifacts import atomic_write
from control.estimate import cold_build_seconds
from control.graph import select_clips
from control.motion import (
    EMBEDDED_CLIPS,
    EMBEDDED_LIBRARY,
    EMBEDDED_MAX_BYTES,
    Library,
    clean_labels,
    default_library_path,
    embed_library,
    load_library,
    source_label_rows,
)
from silhouette_bank import BankSettings, render_rate
from vision import on_the_floor

from .args import add_library_dir, library_dir, number

__all__ = ["add_library_commands", "library_summary"]


def add_library_commands(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """``mimic library``: ``info``, ``labels`` and ``embed``."""
    lib = sub.add_parser("library", help="inspect a motion library")
    lib_sub = lib.add_subparsers(dest="library_command", required=True)
    _add_info(lib_sub)
    _add_labels(lib_sub)
    _add_embed(lib_sub)


def _add_info(lib_sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    info = lib_sub.add_parser(
        "info",
        help="clips, frames, duration, rate, joints and contact statistics",
        description="Load a motion library (ASF/AMC and/or BVH) and summarise it.",
    )
    add_library_dir(info)
    info.add_argument(
        "--fps",
        type=number(float, 0, 240, above=True),
        default=15.0,
        help="resample to this rate (default 15)",
    )
    info.add_argument("--mirror", action="store_true", help="add mirrored copies of every clip")
    info.add_argument(
        "--prefer",
        choices=("amc", "bvh"),
        default="amc",
        help="format to use for takes present in both (default amc)",
    )
    info.add_argument("--no-cache", action="store_true", help="neither read nor write the cache")
    info.add_argument("--json", action="store_true", help="print the summary as JSON")
    info.add_argument(
        "--workers",
        type=number(int, 1, 4096),
        default=None,
        help="workers the bank would render on, for the cold build's estimate (default: "
        "this machine's cores, at most 4, as a bank build takes them)",
    )
    info.set_defaults(func=_info)


def _add_labels(lib_sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    labels = lib_sub.add_parser(
        "labels",
        help="write the library's cleaned action labels (boundaries where the motion changes)",
        description=(
            "Move each boundary between two labelled actions of a clip to where the motion "
            "changes (the cycle of one action gives way to the next's), as every command "
            "does when it loads the library, and write the cleaned label files (the same "
            "CSV format, source frames) to a folder of their own: the source labels stay."
        ),
    )
    add_library_dir(labels)
    labels.add_argument("--out", required=True, help="folder for the cleaned <clip>.csv files")
    labels.add_argument(
        "--fps",
        type=number(float, 0, 240, above=True),
        default=15.0,
        help="the rate the boundaries are found at (default 15, the library's)",
    )
    labels.set_defaults(func=_labels)


def _add_embed(lib_sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    embed = lib_sub.add_parser(
        "embed",
        help="convert a few clips into the package's embedded default library",
        description=(
            "Convert clips of a full library into compact motion arrays at 30 frames/s, "
            "with their labels and the CMU acknowledgement: the library used when neither "
            "$MIMIC_MOCAP nor ../shared/mocap exists."
        ),
    )
    embed.add_argument("dir", help="the full library folder (e.g. ../shared/mocap)")
    embed.add_argument(
        "--out", default=str(EMBEDDED_LIBRARY), help=f"output folder (default {EMBEDDED_LIBRARY})"
    )
    embed.add_argument(
        "--clips",
        default=",".join(EMBEDDED_CLIPS),
        help=f"comma-separated clip names (default {','.join(EMBEDDED_CLIPS)})",
    )
    embed.set_defaults(func=_embed)


def _embed(args: argparse.Namespace) -> int:
    sizes = embed_library(args.dir, args.out, [c for c in args.clips.split(",") if c])
    total = sum(sizes.values())
    print(f"wrote {len(sizes)} files to {args.out}: {total / 1e6:.2f} MB")
    if total > EMBEDDED_MAX_BYTES:
        print(f"warning: over the {EMBEDDED_MAX_BYTES / 1e6:g} MB the embedded library may use")
    return 0


def _labels(args: argparse.Namespace) -> int:
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out}: is a file, not a folder")
    given = library_dir(args)
    root = Path(given if given is not None else default_library_path()).resolve()
    if out.resolve() == root or root in out.resolve().parents:
        # (checked before the library loads; any labels/<clip>.csv under the library is
        # read as its labels)
        raise ValueError(
            f"--out {out}: inside the library {root}, whose label files would be "
            "replaced or read as its labels; the source labels stay, so write elsewhere"
        )
    library = load_library(root, fps=args.fps, clean_labels=False)
    written = 0
    for clip in library.clips:
        if clip.mirrored or not (clip.labels >= 0).any():
            continue
        cleaned, moves = clean_labels(clip.motion.quats, clip.labels, args.fps)
        length = int(np.ceil(clip.source_frames[-1])) + 1
        rows = source_label_rows(cleaned, clip.label_names, clip.source_frames, length)
        with atomic_write(out / f"{clip.name}.csv") as fh:
            w = csv.writer(fh, lineterminator="\n")
            w.writerow(("first_frame", "last_frame", "action"))
            w.writerows(rows)
        written += 1
        for m in moves:
            at = clip.source_frames  # (seconds of the source, as the label file counts)
            rate = clip.motion.fps * (at[-1] - at[0]) / max(clip.motion.n_frames - 1, 1)
            t = [float(at[k]) / rate for k in (m.source, m.transition_start, m.cleaned)]
            span = f"{t[1]:.2f}-{t[2]:.2f} s" if m.cleaned > m.transition_start else "none"
            print(
                f"{clip.name}: {clip.label_names[m.before]} -> {clip.label_names[m.after]} "
                f"at {t[0]:.2f} s, moved {t[2] - t[0]:+.2f} s (transition {span})"
            )
    print(f"wrote {written} label files to {out}")
    return 0


def library_summary(library: Library) -> dict[str, Any]:
    """Per-clip and total figures of a loaded library, as plain JSON-able values."""
    clips = []
    for c in library.clips:
        st = c.contacts.states
        events = c.contacts.events()
        minutes = max(c.motion.n_frames / c.motion.fps / 60.0, 1e-9)
        clips.append(
            {
                "clip": c.name,
                "frames": c.motion.n_frames,
                "seconds": round(c.motion.n_frames / c.motion.fps, 2),
                "fps": c.motion.fps,
                "joints": c.motion.skeleton.n_joints,
                "contact_left": round(float(st[:, 0].mean()), 3),
                "contact_right": round(float(st[:, 1].mean()), 3),
                "airborne": round(float((~st.any(axis=1)).mean()), 3),
                "contact_changes_per_min": round(len(events) / minutes, 1),
                "labels": list(c.label_names),
                "description": c.description,
            }
        )
    all_states = np.concatenate([c.contacts.states for c in library.clips])
    return {
        "root": library.root,
        "clips": len(library.clips),
        "frames": library.n_frames,
        "seconds": round(library.duration, 1),
        "fps": library.fps,
        "skeletons": [s.n_joints for s in library.skeletons()],
        "contact_fraction": {
            "left": round(float(all_states[:, 0].mean()), 3),
            "right": round(float(all_states[:, 1].mean()), 3),
            "both": round(float(all_states.all(axis=1).mean()), 3),
            "none": round(float((~all_states.any(axis=1)).mean()), 3),
        },
        "contact_changes": int(sum(len(c.contacts.events()) for c in library.clips)),
        "per_clip": clips,
    }


def _info(args: argparse.Namespace) -> int:
    library = load_library(
        library_dir(args),
        fps=args.fps,
        mirror=args.mirror,
        prefer=args.prefer,
        use_cache=not args.no_cache,
    )
    summary = library_summary(library)
    summary["cold_build_estimate"] = _cold_build(library, args.workers)
    if args.json:
        print(json.dumps(summary, indent=2))
        return 0
    print(
        f"{'clip':<14}{'frames':>7}{'sec':>8}{'fps':>6}{'joints':>7}"
        f"{'L cont':>7}{'R cont':>7}{'air':>6}{'chg/min':>8}  description"
    )
    for row in summary["per_clip"]:
        print(
            f"{row['clip']:<14}{row['frames']:>7}{row['seconds']:>8.1f}{row['fps']:>6g}"
            f"{row['joints']:>7}{row['contact_left']:>7.2f}{row['contact_right']:>7.2f}"
            f"{row['airborne']:>6.2f}{row['contact_changes_per_min']:>8.1f}  {row['description']}"
        )
    cf = summary["contact_fraction"]
    print(
        f"\nlibrary {summary['root']}: {summary['clips']} clips, {summary['frames']} frames, "
        f"{summary['seconds']:.1f} s at {summary['fps'] or 'native'} frames/s, skeletons with "
        f"{', '.join(map(str, summary['skeletons']))} joints; feet in contact: left "
        f"{cf['left']:.0%}, right {cf['right']:.0%}, both {cf['both']:.0%}, neither "
        f"{cf['none']:.0%}; {summary['contact_changes']} contact changes"
    )
    est = summary["cold_build_estimate"]
    if est is not None:
        steps = ", ".join(
            f"{name} {_duration(est[name])}"
            for name in ("graph", "higher layer", "bank", "search index")
        )
        print(
            f"a cold build here (mimic perform from an empty cache, {est['frames']} frames of "
            f"clips on the floor): about {_duration(est['total'])}: {steps} (the bank on "
            f"{est['workers']} workers; "
            f"estimated from {est['render_rate']:,.0f} silhouettes/s rendered just now and "
            "bench_scale's growth on the development machine)"
        )
    return 0


def _cold_build(library: Library, workers: int | None) -> dict[str, Any] | None:
    """``control.estimate.cold_build_seconds`` on this machine for the clips of ``library``
    that ``mimic perform`` builds from (the graph's skeleton group, on the floor), its
    render rate measured on the longest; with the frames, the rate and the workers;
    ``None`` without a clip to build."""
    # in perform's order: the clips on the floor (of the whole library's floor), then the
    # graph's skeleton group among them
    clips, _ = on_the_floor(library.clips) if library.clips else ([], {})
    clips, _ = select_clips(clips) if clips else ([], [])
    if not clips:
        return None
    frames = sum(c.motion.n_frames for c in clips)
    settings = BankSettings()
    rate = render_rate(max(clips, key=lambda c: c.motion.n_frames), settings)
    n = workers or min(4, os.cpu_count() or 1)
    est = cold_build_seconds(frames, settings.n_views, rate, n)
    rounded = {k: round(v, 1) for k, v in est.items()}
    return {**rounded, "frames": frames, "render_rate": round(rate), "workers": n}


def _duration(seconds: float) -> str:
    """``40 s``, ``12 min``, ``2.5 h``."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    return f"{seconds / 60:.0f} min" if seconds < 5400 else f"{seconds / 3600:.1f} h"
