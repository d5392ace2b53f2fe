"""``mimic record``: a clip rendered as a performer's silhouette video with its ground
truth (another body, a camera off the ring, mask noise)."""

from __future__ import annotations

import argparse
from pathlib import Path

from control.motion import load_library
from silhouette_bank import (
    BodyShape,
)
from vision import (
    RECORDING_FOURCC,
    RecordSettings,
    record_clip,
)

from .args import MOST_SECONDS, add_library_dir, library_dir, number
from .outputs import check_outputs

__all__ = ["add_record_command"]


def add_record_command(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    r = sub.add_parser(
        "record",
        help="render a clip as a performer's silhouette (or colour) video with ground truth",
        description="Another body than the avatar's, a camera off the bank's ring, mask "
        "noise (or, with --colour, the shaded body with a face, for a pose model); FFV1 "
        "video plus a JSON sidecar (source frame and label per video frame).",
    )
    r.add_argument("clip", help="clip name, e.g. 13_29")
    add_library_dir(r)
    r.add_argument("--out", required=True, help="video to write (.mkv)")
    r.add_argument(
        "--from",
        dest="start",
        type=number(float, 0, MOST_SECONDS),
        default=0.0,
        help="start, seconds",
    )
    r.add_argument(
        "--to",
        dest="stop",
        type=number(float, 0, MOST_SECONDS, above=True),
        help="end, seconds (default: clip end)",
    )
    _add_filming_args(r)
    r.add_argument("--seed", type=number(int, 0, 2**32 - 1), default=0)
    r.set_defaults(func=_record)


def _add_filming_args(r: argparse.ArgumentParser) -> None:
    """The video, the performer's body and the camera (``RecordSettings``'s defaults)."""
    d = RecordSettings()
    r.add_argument("--fps", type=number(float, 0, 240, above=True), default=30.0)
    r.add_argument("--size", default=f"{d.width}x{d.height}", help="WIDTHxHEIGHT")
    r.add_argument("--body-width", type=number(float, 0, 10, above=True), default=d.body.width)
    r.add_argument("--body-height", type=number(float, 0, 10, above=True), default=d.body.height)
    r.add_argument(
        "--legs",
        type=number(float, 0.5, 2),
        default=d.body.legs,
        help="leg bones' length factor (0.5-2)",
    )
    r.add_argument(
        "--arms",
        type=number(float, 0.5, 2),
        default=d.body.arms,
        help="arm bones' length factor (0.5-2)",
    )
    r.add_argument(
        "--azimuth",
        type=number(float, -3600, 3600),
        default=d.azimuth,
        help="camera azimuth, degrees",
    )
    r.add_argument(
        "--turn",
        type=number(float, -3600, 3600),
        default=d.turn,
        help="degrees the camera moves round the performer over the recording (90: a "
        "performer who turns from facing it to showing it their side)",
    )
    r.add_argument("--camera-height", type=number(float, -100, 100), default=d.camera_height)
    r.add_argument("--distance", type=number(float, 0, 1000, above=True), default=d.distance)
    r.add_argument("--no-noise", action="store_true", help="clean masks")
    r.add_argument(
        "--colour",
        action="store_true",
        help="a colour video of the shaded body (for the pose model's landmarks) instead "
        "of silhouettes",
    )


def _record(args: argparse.Namespace) -> int:
    check_outputs(
        args,
        ["--out"],
        also=[("--out's sidecar", f"{args.out}.json")],
        # (a name without a suffix is written as Matroska: ``record_clip``)
        videos={"--out": RECORDING_FOURCC} if Path(args.out).suffix else None,
    )
    try:
        w, h = (int(v) for v in args.size.lower().split("x"))
    except ValueError as exc:
        raise ValueError(f"--size must be WIDTHxHEIGHT, not {args.size!r}") from exc
    # the sidecar is a ground truth: the label file's own boundaries
    library = load_library(library_dir(args), fps=args.fps, clips=[args.clip], clean_labels=False)
    clip = library.clip(args.clip)
    start = round(args.start * args.fps)
    stop = clip.motion.n_frames if args.stop is None else round(args.stop * args.fps)
    settings = RecordSettings(
        body=BodyShape(args.body_width, args.body_height, args.legs, args.arms),
        azimuth=args.azimuth,
        camera_height=args.camera_height,
        distance=args.distance,
        width=w,
        height=h,
        edge_noise=0.0 if args.no_noise else RecordSettings().edge_noise,
        holes=0 if args.no_noise else RecordSettings().holes,
        shadow=not args.no_noise,
        seed=args.seed,
        colour=args.colour,
        turn=args.turn,
    )
    side = record_clip(clip, args.out, settings, start, stop)
    print(f"wrote {args.out} and {args.out}.json: {len(side['frames'])} frames of {args.clip}")
    return 0
