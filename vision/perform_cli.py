"""``mimic perform`` and ``mimic record``."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import fnmatch
import itertools
import json
import os
import signal
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from control.cli import (
    _add_graph_args,
    _add_library_args,
    _options,
    add_library_dir,
    blend_seconds,
    library_dir,
    start_frame,
)
from control.clusters import cached_higher_layer
from control.graph import cached_graph
from control.motion import atomic_write, load_library, write_bvh
from control.progress import bar, step
from silhouette_bank import (
    DEFAULT_DESCRIPTOR,
    DESCRIPTORS,
    BankSettings,
    BodyShape,
    StaleBankError,
    ensure_bank,
    load_bank,
    robust_settings,
)

from ._evaluate import evaluation, plot_evaluation
from ._library import FLOOR_ABOVE, FLOOR_SECONDS, VISION_COORDS, on_the_floor
from ._live import LivePainter, LiveView
from ._matcher import MatchSettings
from ._perform import PerformSettings, perform
from ._person import INSTALL, PERSON_METHODS, person_segmentation_available
from ._record import RecordSettings, record_clip
from ._segment import METHODS
from ._sources import MaskFolderSource, SourceError, open_source
from ._truth import Truth, action_runs, agreement, library_actions, truth_for
from ._video import MaskTape, write_video

__all__ = ["add_perform_commands"]


def _add_run_args(p: argparse.ArgumentParser) -> None:
    """The options of a performance that ``perform`` and ``evaluate`` share: the library,
    its graph, the matcher, the segmentation and the descriptor."""
    _add_library_args(p)
    p.add_argument(
        "--leave-out",
        action="append",
        default=[],
        metavar="PATTERN",
        help="leave out clips whose name matches (shell pattern, repeatable): the "
        "performer's own take, to measure an unseen performer",
    )
    _add_graph_args(p)
    # the vision interface's graph: relative coordinates, so that takes recorded in
    # different places reach each other
    p.set_defaults(coords=VISION_COORDS)
    p.add_argument(
        "--off-floor",
        action="store_true",
        help=f"keep clips whose feet leave the floor (over {FLOOR_ABOVE:g} m for more than "
        f"{FLOOR_SECONDS:g} s: climbing, sitting on things); by default they are left out, "
        "as the avatar would float",
    )
    p.add_argument(
        "--no-jumps",
        action="store_true",
        help="only the paper's cluster paths (and a relocation through the graph once a "
        "second), no direct blended jumps into the best-matching windows",
    )
    p.add_argument("--seconds", type=float, help="stop after this much media time")
    p.add_argument("--window", type=float, default=1.0, help="seconds of performer matched")
    p.add_argument("--lookahead", type=float, default=1.5, help="candidate actions within, s")
    p.add_argument(
        "--segmentation",
        choices=("auto", *PERSON_METHODS, *METHODS),
        default="auto",
        help="auto (default): a camera learns the empty scene first (mog2); a video file has "
        "no such plate, so a person segmenter (pose, needs MediaPipe) is used; the pose "
        "descriptor always uses the pose model; the rest are OpenCV background subtractors",
    )
    p.add_argument("--learn-frames", type=int, default=30, help="frames to learn the background")
    p.add_argument(
        "--variants",
        action="store_true",
        help="match against a bank with other bodies (0.9-1.25 wide) and shadows at the "
        "feet too: more robust to performers who are not the avatar, 8x the bank",
    )
    p.add_argument(
        "--descriptor",
        choices=("auto", *DESCRIPTORS),
        default="auto",
        help="what each frame is reduced to. auto (default): pose (MediaPipe's body "
        "landmarks against the avatar's projected joints) for colour video and cameras "
        "when MediaPipe is installed, else multigrid (how full each cell of 16x8, 8x4 and "
        "4x2 grids over the silhouette is); grid, hu (7 Hu moments): see the README's "
        "recognition figures",
    )
    p.add_argument(
        "--silhouette-video",
        choices=("auto", "yes", "no"),
        default="auto",
        help="whether --video holds binary silhouettes (white on black) rather than "
        "colour footage; auto (default): yes when each of its first 30 frames that is not "
        "all black is black and white only",
    )
    p.add_argument(
        "--bank",
        help="a bank folder built by mimic bank build (any render settings and descriptor; "
        "from the same clips) instead of the cached default bank",
    )
    p.add_argument("--k", type=int, help="number of clusters (default: BIC)")
    p.add_argument("--start", help="avatar starts at CLIP:FRAME")
    p.add_argument("--seed", type=int, default=0)


def add_perform_commands(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "perform",
        help="the avatar follows a performer: camera, video, or masks in; BVH, MP4, log out",
        description="Every 0.1 s of media time the performer's last silhouettes are matched "
        "against the avatar's possible next actions (the silhouette bank); the best is taken.",
    )
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--camera", type=int, help="webcam index")
    src.add_argument("--video", help="a video file (colour, or a silhouette video)")
    src.add_argument("--masks", help="a folder of mask images")
    _add_run_args(p)
    p.add_argument("--realtime", action="store_true", help="pace a file like a camera")
    p.add_argument("--out", help="BVH of the avatar's motion")
    p.add_argument("--video-out", help="MP4: performer silhouette beside the avatar")
    p.add_argument("--log", help="JSON-lines decision log")
    p.add_argument(
        "--labels",
        help="a labels CSV (file,start,end,label; times in seconds) with the performer's "
        "actions in --video: the summary then gives the avatar's agreement with them "
        "(a recording's own sidecar is used without it)",
    )
    p.add_argument(
        "--live-port",
        type=int,
        default=8765,
        help="with --camera or --realtime, a live view at http://127.0.0.1:PORT/ (0: none)",
    )
    p.set_defaults(func=_perform)

    e = sub.add_parser(
        "evaluate",
        help="how often the avatar does the performer's action: a labelled video in, "
        "agreement by lag, confusion matrix, JSON and a plot out",
        description="Replay a labelled performance (a recording with its sidecar, or any "
        "video with a labels CSV) through mimic perform's loop, with its defaults, and "
        "compare the avatar's action at every decision with the performer's, at lags of "
        "0-3 s (the avatar follows, so it may be late).",
    )
    e.add_argument("video", help="a recording (with its .json sidecar) or any video file")
    e.add_argument(
        "--labels", help="labels CSV (file,start,end,label) when the video has no sidecar"
    )
    _add_run_args(e)
    e.add_argument("--json", required=True, help="the report (JSON) to write")
    e.add_argument("--png", help="a plot of agreement against lag and the confusion matrix")
    e.set_defaults(func=_evaluate)

    r = sub.add_parser(
        "record",
        help="render a clip as a performer's silhouette video with ground truth",
        description="Another body than the avatar's, a camera off the bank's ring, mask "
        "noise; FFV1 video plus a JSON sidecar (source frame and label per video frame).",
    )
    r.add_argument("clip", help="clip name, e.g. 13_29")
    add_library_dir(r)
    r.add_argument("--out", required=True, help="video to write (.mkv)")
    r.add_argument("--from", dest="start", type=float, default=0.0, help="start, seconds")
    r.add_argument("--to", dest="stop", type=float, help="end, seconds (default: clip end)")
    d = RecordSettings()
    r.add_argument("--fps", type=float, default=30.0)
    r.add_argument("--size", default=f"{d.width}x{d.height}", help="WIDTHxHEIGHT")
    r.add_argument("--body-width", type=float, default=d.body.width)
    r.add_argument("--body-height", type=float, default=d.body.height)
    r.add_argument("--azimuth", type=float, default=d.azimuth, help="camera azimuth, degrees")
    r.add_argument("--camera-height", type=float, default=d.camera_height)
    r.add_argument("--distance", type=float, default=d.distance)
    r.add_argument("--no-noise", action="store_true", help="clean masks")
    r.add_argument("--seed", type=int, default=0)
    r.set_defaults(func=_record)


def _record(args: argparse.Namespace) -> int:
    try:
        w, h = (int(v) for v in args.size.lower().split("x"))
    except ValueError as exc:
        raise ValueError(f"--size must be WIDTHxHEIGHT, not {args.size!r}") from exc
    library = load_library(library_dir(args), fps=args.fps, clips=[args.clip])
    clip = library.clip(args.clip)
    start = round(args.start * args.fps)
    stop = clip.motion.n_frames if args.stop is None else round(args.stop * args.fps)
    settings = RecordSettings(
        body=BodyShape(args.body_width, args.body_height),
        azimuth=args.azimuth,
        camera_height=args.camera_height,
        distance=args.distance,
        width=w,
        height=h,
        edge_noise=0.0 if args.no_noise else RecordSettings().edge_noise,
        holes=0 if args.no_noise else RecordSettings().holes,
        shadow=not args.no_noise,
        seed=args.seed,
    )
    side = record_clip(clip, args.out, settings, start, stop)
    print(f"wrote {args.out} and {args.out}.json: {len(side['frames'])} frames of {args.clip}")
    return 0


def choose_descriptor(name: str, source: Any) -> str:
    """``"auto"`` made concrete for ``source``: ``pose`` where there are colour frames
    (a camera, a colour video) and MediaPipe is installed (it recognised far better than
    any silhouette descriptor: ``benchmarks/bench_recognition.py``), else the bank's
    default silhouette descriptor. A pose descriptor for a silhouette source is an
    error."""
    colour = not (isinstance(source, MaskFolderSource) or getattr(source, "silhouette", False))
    if name == "auto":
        return "pose" if colour and person_segmentation_available() else DEFAULT_DESCRIPTOR
    if name == "pose" and not colour:
        raise SystemExit(
            f"mimic perform: {source.name} holds silhouettes, and the pose descriptor needs "
            "colour frames (use --descriptor multigrid, or auto)"
        )
    if name == "pose" and not person_segmentation_available():
        raise SystemExit(
            f"mimic perform: the pose descriptor needs MediaPipe; install it with: {INSTALL}"
        )
    return name


@dataclass
class Prepared:
    """What a performance runs on, made from ``mimic perform``'s (or ``evaluate``'s)
    arguments."""

    descriptor: str
    clips: list[Any]
    graph: Any
    layer: Any
    bank: Any
    bank_built: bool
    settings: PerformSettings
    start: int | None


_SIGNALS = {"SIGINT": 2, "SIGHUP": 1, "SIGTERM": 15}


class StopOnSignal:
    """While in use, Ctrl-C (SIGINT), SIGTERM and SIGHUP ask the performance to stop at
    its next frame (``__call__`` says which came) instead of killing it, so that what was
    performed is still written. A second Ctrl-C interrupts at once."""

    def __init__(self) -> None:
        self.got = ""
        self._old: dict[int, Any] = {}

    def __call__(self) -> str:
        return self.got

    def _handle(self, signum: int, frame: Any) -> None:
        name = signal.Signals(signum).name
        if self.got == "SIGINT" and name == "SIGINT":
            raise KeyboardInterrupt
        if not self.got:
            self.got = name
            print(f"\n{name}: stopping after this frame (Ctrl-C again to abort)", file=sys.stderr)

    def __enter__(self) -> StopOnSignal:
        if threading.current_thread() is threading.main_thread():
            for name in _SIGNALS:
                sig = getattr(signal, name, None)
                if sig is not None:
                    self._old[sig] = signal.signal(sig, self._handle)
        return self

    def __exit__(self, *exc: object) -> None:
        for sig, old in self._old.items():
            signal.signal(sig, old)


class DecisionLog:
    """The JSON-lines decision log, written line by line (each line flushed) to a
    temporary file beside ``path`` and moved onto ``path`` when the run ends, stopped or
    not: an old log is replaced only by a run that logged something, never destroyed by
    a run that failed to start."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
        self._fh = open(self._tmp, "w", buffering=1, encoding="utf-8")  # noqa: SIM115
        self.lines = 0

    def write(self, text: str) -> int:
        n = self._fh.write(text)
        self._fh.flush()
        self.lines += text.count("\n")
        return n

    def __enter__(self) -> DecisionLog:
        return self

    def __exit__(self, *exc: object) -> None:
        self._fh.close()
        if self.lines:
            os.replace(self._tmp, self.path)
        else:
            self._tmp.unlink(missing_ok=True)


def prepare(args: argparse.Namespace, source: Any) -> Prepared:
    """The library (the clips on the floor unless ``--off-floor``), its graph, higher
    layer and bank for ``source`` with the defaults of the vision interface, saying on
    stderr what was chosen and what was left out."""
    if args.fps is None or args.fps <= 0:
        raise ValueError("--fps must be positive")
    with step("motion library"):
        library = load_library(
            library_dir(args), fps=args.fps, mirror=args.mirror, clips=args.clips
        )
    clips = [
        c for c in library.clips if not any(fnmatch.fnmatchcase(c.name, p) for p in args.leave_out)
    ]
    if args.leave_out:
        gone = sorted({c.name for c in library.clips} - {c.name for c in clips})
        print(f"left out as asked: {', '.join(gone) or 'nothing matched'}", file=sys.stderr)
    if not clips:
        raise ValueError(f"{library.root}: --leave-out leaves no clip")
    if not args.off_floor:
        clips, dropped = on_the_floor(clips)
        if dropped:
            print(
                f"left out {len(dropped)} clips whose feet leave the floor (--off-floor "
                f"keeps them): {', '.join(sorted(dropped))}",
                file=sys.stderr,
            )
        if not clips:
            raise SystemExit("mimic perform: every clip leaves the floor (use --off-floor)")
    t0 = time.perf_counter()
    with step("motion graph"):
        graph, _, _ = cached_graph(clips, _options(args), rebuild=args.rebuild)
    unreachable = [
        f"{name} ({graph.in_scc[a:b].mean():.0%} reachable)"
        for name, a, b in zip(
            graph.clip_names, graph.clip_start[:-1], graph.clip_start[1:], strict=True
        )
        if graph.in_scc[a:b].mean() < 0.5
    ]
    if unreachable and args.no_jumps:
        print(
            "warning: these clips are mostly outside the graph's connected component, and "
            f"without jumps the avatar cannot reach them: {', '.join(unreachable)}",
            file=sys.stderr,
        )
    elif unreachable:
        print(
            "note: these clips are mostly outside the graph's connected component; the "
            f"avatar reaches them by direct jumps only: {', '.join(unreachable)}",
            file=sys.stderr,
        )
    # the matcher looks no further ahead than the look-ahead: trees that reach that far
    # (the paper's 15 s trees of a dense graph are truncated, and slow to build)
    bound = max(2.0, args.lookahead + 0.5)
    with step("higher layer (clusters and trees)"):
        layer, _, layer_built = cached_higher_layer(graph, clips, k=args.k, bound_seconds=bound)
    print(
        f"library: {len(graph.clip_names)} clips, {graph.n_frames} frames "
        f"({int(graph.in_scc.sum())} reachable); graph coords {graph.options.coords}; "
        f"{layer.clustering.k} clusters ({'built' if layer_built else 'cached'}); "
        f"{time.perf_counter() - t0:.1f} s",
        file=sys.stderr,
    )
    if args.bank:  # a bank built by mimic bank build, with its own settings
        try:
            bank, built = load_bank(args.bank, clips), False
        except StaleBankError as exc:
            problem = str(exc)[len(exc.path) + 2 :]  # the message without its path
            raise StaleBankError(
                exc.path,
                f"{problem}; perform matches against {len(clips)} clips ({clips[0].name}"
                f"..{clips[-1].name}, the clips off the floor left out unless --off-floor): "
                "build the bank from the same clips",
            ) from None
        descriptor = choose_descriptor(bank.settings.descriptor, source)
        print(f"descriptor: {descriptor} (the bank's, {args.bank})", file=sys.stderr)
    else:
        descriptor = choose_descriptor(args.descriptor, source)
        print(f"descriptor: {descriptor}", file=sys.stderr)
        base = BankSettings(descriptor=descriptor)
        if args.variants and descriptor == "pose":
            print("--variants: body variants do not apply to the pose descriptor", file=sys.stderr)
        bank_settings = robust_settings(base) if args.variants and descriptor != "pose" else base
        bank, built = ensure_bank(clips, bank_settings, progress=bar("silhouette bank", "shards"))
    settings = PerformSettings(
        segmentation=args.segmentation,
        learn_frames=args.learn_frames,
        match=MatchSettings(window=args.window, lookahead=args.lookahead, jumps=not args.no_jumps),
        seconds=args.seconds,
        blend=blend_seconds(args),
    )
    return Prepared(
        descriptor, clips, graph, layer, bank, built, settings, start_frame(graph, args.start)
    )


def _write_timing(out: str, result: Any, frames: int, fps: float, source: str) -> Path:
    """``OUT.json`` beside the BVH: where its frames lie in the input's media time (a BVH
    has no field for it), so that the avatar lines up with the input after a late start."""
    path = Path(out).expanduser()
    path = path.with_name(path.name + ".json")
    timing = {
        "bvh": Path(out).name,
        "source": source,
        "media_start_s": round(float(result.avatar_start_s), 4),
        "fps": fps,
        "frames": frames,
        "media_end_s": round(float(result.avatar_start_s) + frames / fps, 4),
        "stopped": result.stopped or None,
    }
    with atomic_write(path) as fh:
        json.dump(timing, fh, indent=1)
        fh.write("\n")
    return path


def _perform(args: argparse.Namespace) -> int:
    if args.labels and not args.video:
        raise ValueError("--labels needs --video (the labels name its file)")
    truth = truth_for(args.video, args.labels) if args.video else None  # bad: LabelFileError
    for name in ("out", "video_out", "log"):  # outputs into a missing folder work alike
        if getattr(args, name):
            Path(getattr(args, name)).expanduser().parent.mkdir(parents=True, exist_ok=True)
    source = open_source(
        args.camera,
        args.video,
        args.masks,
        silhouette=_silhouette(args),
        realtime=args.realtime,
    )
    if args.camera is not None and args.seconds is None:
        print("a camera never ends: stop with Ctrl-C (or give --seconds)", file=sys.stderr)
    ready = prepare(args, source)
    plate = args.segmentation in METHODS or (
        args.segmentation == "auto" and ready.descriptor != "pose"
    )
    if args.camera is not None and plate:
        print(
            "step out of view for two seconds so that the background can be learned",
            file=sys.stderr,
        )
    clips, graph, layer, bank = ready.clips, ready.graph, ready.layer, ready.bank
    live = args.live_port != 0 and (args.camera is not None or args.realtime)
    with contextlib.ExitStack() as stack:
        log: Any = stack.enter_context(DecisionLog(args.log)) if args.log else None
        tape = stack.enter_context(MaskTape(fps=graph.fps)) if args.video_out else None
        stops = stack.enter_context(StopOnSignal())
        painter = None
        if live:
            try:
                view = stack.enter_context(LiveView(port=args.live_port))
            except OSError as exc:
                raise OSError(
                    f"--live-port {args.live_port}: cannot serve the live view ({exc})"
                ) from None
            painter = LivePainter(view, clips, graph, bank)
            print(f"live view: {view.url} (this machine only)", file=sys.stderr, flush=True)
        try:
            result = perform(
                source,
                layer,
                bank,
                clips,
                ready.settings,
                start=ready.start,
                seed=args.seed,
                log=log,
                tape=tape,
                on_frame=painter.on_frame if painter else None,
                on_decision=painter.on_decision if painter else None,
                stop=stops,
            )
        finally:
            source.close()
        if result.frames_with_media == 0:
            raise SourceError(
                f"{source.name}: no frame came from the source in "
                f"{result.media_seconds:.1f} s (a camera that does not open, or is in use?)"
            )
        _warn_source(source)
        if result.stopped:
            print(
                f"stopped by {result.stopped} at {result.media_seconds:.1f} s of media: "
                "writing what was performed",
                file=sys.stderr,
                flush=True,
            )
        made = [c for c in result.decisions if c.get("decision") is not None]
        if args.out:
            motion = result.avatar.motion().motion
            write_bvh(motion, args.out)
            _write_timing(args.out, result, motion.n_frames, motion.fps, source.name)
        if tape is not None:
            write_video(result, bank, clips, args.video_out, tape)
    lat = [c["latency_ms"] for c in made]
    jumps = sum("jump" in c for c in made)
    clips_seen = [c["clip"] for c in result.decisions]
    changes = sum(a != b for a, b in itertools.pairwise(clips_seen))
    minutes = max(result.media_seconds, 1e-9) / 60.0
    print(  # the one summary line
        f"{result.media_seconds:.1f} s of media ({result.frames_read} frames): "
        f"{len(made)} decisions of {len(result.decisions)}"
        + (
            f" (p50 {np.percentile(lat, 50):.2f} ms, p99 {np.percentile(lat, 99):.2f} ms)"
            if lat
            else ""
        )
        + f"; the avatar moved {result.avatar.time:.1f} s, {jumps} direct jumps, "
        f"{changes / minutes:.1f} clip changes a minute"
        + ("; bank built" if ready.bank_built else "")
    )
    if result.avatar_start_s > ready.settings.match.window + 0.5:  # a late start
        print(
            f"the avatar's motion (BVH, MP4) starts at {result.avatar_start_s:.2f} s of media, "
            "where the performer was first matched (the log's times are media times; "
            + (f"{args.out}.json says so for the BVH" if args.out else "the MP4 shows them")
            + ")"
        )
    _print_actions(result.decisions, clips)
    if truth is not None:
        _print_agreement(result.decisions, clips, truth)
        _warn_own_take(args.video, clips)
    skipped = getattr(source, "skipped", [])
    if skipped:
        shown = ", ".join(skipped[:5]) + (" ..." if len(skipped) > 5 else "")
        print(
            f"skipped {len(skipped)} unreadable mask files (each a frame without a silhouette, "
            f"in the log as such): {shown}",
            file=sys.stderr,
        )
    for name in ("out", "video_out", "log"):
        if getattr(args, name):
            print(f"wrote {getattr(args, name)}")
            if name == "out":
                print(f"wrote {args.out}.json (the BVH's place in the input's media time)")
    # Ctrl-C is how a camera session ends; another signal is reported as such
    return 0 if result.stopped in ("", "SIGINT") else 128 + _SIGNALS[result.stopped]


def _evaluate(args: argparse.Namespace) -> int:
    truth = truth_for(args.video, args.labels)  # bad: LabelFileError, naming the file
    if truth is None:
        raise ValueError(
            f"{args.video}: no ground truth (no {Path(args.video).name}.json sidecar): "
            "give --labels CSV"
        )
    source = open_source(None, args.video, None, silhouette=_silhouette(args))
    ready = prepare(args, source)
    try:
        result = perform(
            source,
            ready.layer,
            ready.bank,
            ready.clips,
            ready.settings,
            start=ready.start,
            seed=args.seed,
        )
    finally:
        source.close()
    _warn_own_take(args.video, ready.clips)
    _warn_source(source)
    report = evaluation(result.decisions, ready.clips, truth, result.media_seconds)
    report = {
        "video": str(args.video),
        "library": [c.name for c in ready.clips],
        "descriptor": ready.descriptor,
        "graph": {"coords": ready.graph.options.coords, "frames": ready.graph.n_frames},
        "match": dataclasses.asdict(ready.settings.match),
        **report,
    }
    with atomic_write(args.json) as fh:
        fh.write(json.dumps(report, indent=1) + "\n")
    if args.png:
        plot_evaluation(report, args.png, title=f"{Path(args.video).name} against {truth.source}")
    _print_actions(result.decisions, ready.clips)
    best = report["best_at_lag_le_1s"]
    print(
        "agreement (actions the library has): "
        + (f"{best:.2f} at lag {report['best_lag_s']:g} s" if best is not None else "none")
        + f"; chance {report['chance']}; per action "
        + ", ".join(f"{a} {v:.2f}" for a, v in report["per_action_at_best_lag"].items())
        + f"; switches a minute: avatar {report['switches_per_minute']['avatar']}, "
        f"performer {report['switches_per_minute']['performer']}"
    )
    print(f"wrote {args.json}" + (f" and {args.png}" if args.png else ""))
    return 0


def _silhouette(args: argparse.Namespace) -> bool | None:
    return {"auto": None, "yes": True, "no": False}[args.silhouette_video]


def _warn_source(source: Any) -> None:
    """Say so when a video ended before the frames its header declares."""
    why = source.truncated() if hasattr(source, "truncated") else ""
    if why:
        print(f"warning: {why}", file=sys.stderr)


def _warn_own_take(video: str, clips: list[Any]) -> None:
    """Say so when a recording's own take is in the library: then its agreement is not
    that of a performer the library has never seen."""
    side = Path(video).with_name(Path(video).name + ".json")
    try:
        take = json.loads(side.read_text()).get("clip") if side.is_file() else None
    except (OSError, ValueError, AttributeError):
        return
    if take and any(c.name == take for c in clips):
        print(
            f"note: the recording is of {take}, which is in the library: this agreement is "
            f"not that of an unseen performer (--leave-out {take} measures one)"
        )


def _print_actions(decisions: list[dict[str, Any]], clips: list[Any], most: int = 10) -> None:
    """What the avatar did: its actions over media time (an unlabelled clip by name)."""
    # from the avatar's start on (before the performer is first matched it idles, and
    # that motion is dropped)
    first = next((i for i, d in enumerate(decisions) if "located" in d), 0)
    runs = action_runs(decisions[first:], clips, min_seconds=0.5)
    if not runs:
        return
    shown = [f"{a:.1f}-{b:.1f} s {name}" for a, b, name in runs[:most]]
    more = f" ... and {len(runs) - most} more" if len(runs) > most else ""
    print("the avatar did: " + ", ".join(shown) + more)


def _print_agreement(decisions: list[dict[str, Any]], clips: list[Any], truth: Truth) -> None:
    known = library_actions(clips)
    got = agreement(decisions, clips, truth, known=known)
    if got["best_at_lag_le_1s"] is None:
        print(f"agreement: no decision falls on an action of {truth.source} the library has")
        return
    curve = ", ".join(
        f"{lag} s {got['by_lag_s'][lag]:.2f}"
        for lag in ("0", "0.5", "1")
        if got["by_lag_s"][lag] is not None
    )
    n = got["decisions_by_lag_s"][f"{got['best_lag_s']:g}"]
    print(
        f"agreement with {truth.source}: {got['best_at_lag_le_1s']:.2f} of the decisions "
        f"do the performer's action (best lag within 1 s: {got['best_lag_s']:g} s; "
        f"by lag {curve}; {n} decisions)"
    )
