"""``mimic perform``: the avatar follows a performer from a camera, a video or masks; the
BVH, the side-by-side MP4, the decision log and the live view; a stop writes what was
performed."""

from __future__ import annotations

import argparse
import contextlib
import itertools
import json
import signal
import sys
import threading
from pathlib import Path
from typing import Any

import numpy as np

from control.artifacts import atomic_write
from control.motion import Clip, write_bvh
from control.progress import bar
from silhouette_bank import MP4_FOURCC
from vision import (
    METHODS,
    MaskTape,
    PerformResult,
    Source,
    SourceError,
    Stage,
    StagePainter,
    Truth,
    agreement,
    avatar_labels,
    library_actions,
    open_source,
    perform,
    switch_delays,
    truth_for,
    write_video,
)

from .args import number
from .outputs import Output, OutputSet
from .run import (
    Prepared,
    prepare,
    print_actions,
    warn_own_take,
    warn_source,
)
from .run_args import add_run_args, run_settings, silhouette_flag

__all__ = ["DecisionLog", "StopOnSignal", "add_perform_command"]


def add_perform_command(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "perform",
        help="the avatar follows a performer: camera, video, or masks in; BVH, MP4, log out",
        description="Every 0.1 s of media time the performer's last silhouettes are matched "
        "against the avatar's possible next actions (the silhouette bank); the best is taken.",
    )
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument(
        "--camera",
        type=_camera,
        help="a webcam's index, or 'browser': the live page's camera (open the page it "
        "prints; the browser asks to use the camera)",
    )
    src.add_argument("--video", help="a video file (colour, or a silhouette video)")
    src.add_argument("--masks", help="a folder of mask images")
    add_run_args(p)
    p.add_argument(
        "--realtime",
        action="store_true",
        help="pace a file like a camera (frames whose time passed while the loop was busy "
        "are dropped, as a camera's are)",
    )
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
        type=number(int, 0, 65535),
        default=8765,
        help="with --camera or --realtime, the live page at http://127.0.0.1:PORT/: the "
        "performer, the avatar in 3D, its actions (0: none; --camera browser needs one)",
    )
    p.set_defaults(func=_perform)


def _camera(text: str) -> int | str:
    """``--camera``: a webcam index, or ``browser``."""
    return "browser" if text == "browser" else int(number(int, 0, 1000)(text))


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
    """The JSON-lines decision log, written line by line (each line flushed) to ``path``
    (``mimic perform``: the log's temporary file, moved into place with the run's other
    outputs, ``mimic.outputs``). A write that fails names ``said`` (the option and the
    path the user gave)."""

    def __init__(self, path: str | Path, said: str = "") -> None:
        self.path = Path(path)
        self.said = said or str(path)
        self._fh = open(self.path, "w", buffering=1, encoding="utf-8")  # noqa: SIM115
        self.lines = 0

    def write(self, text: str) -> int:
        try:
            n = self._fh.write(text)
            self._fh.flush()
        except OSError as exc:
            raise OSError(f"{self.said}: could not be written ({exc.strerror or exc})") from None
        self.lines += text.count("\n")
        return n

    def __enter__(self) -> DecisionLog:
        return self

    def __exit__(self, *exc: object) -> None:
        self._fh.close()


def _write_timing(
    path: Path, out: str, result: PerformResult, frames: int, fps: float, source: str
) -> None:
    """``OUT.json`` beside the BVH ``out`` (written to ``path``): where its frames lie in
    the input's media time (a BVH has no field for it), so that the avatar lines up with
    the input after a late start."""
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


def _outputs(args: argparse.Namespace) -> OutputSet:
    """The run's outputs, checked against each other and its inputs before any work."""
    out = args.out
    return OutputSet(
        [
            Output("--out", Path(out)) if out else None,
            Output("--out's timing file", Path(f"{out}.json")) if out else None,
            Output("--video-out", Path(args.video_out), MP4_FOURCC) if args.video_out else None,
            Output("--log", Path(args.log)) if args.log else None,
        ],
        [
            ("--video", args.video),
            ("--video's sidecar", f"{args.video}.json" if args.video else None),
            ("--labels", args.labels),
            ("--masks", args.masks),
        ],
    )


def _perform(args: argparse.Namespace) -> int:
    if args.labels and not args.video:
        raise ValueError("--labels needs --video (the labels name its file)")
    truth = truth_for(args.video, args.labels) if args.video else None  # bad: LabelFileError
    settings = run_settings(args)  # a bad setting is said before any work
    outputs = _outputs(args)  # a clash or an unwritable place: said before any work
    browser = args.camera == "browser"
    if browser and args.live_port == 0:
        raise ValueError("--camera browser needs the live page: give --live-port a port, not 0")
    with contextlib.ExitStack() as stack:
        stage = _stage(args, stack, camera=browser)  # (the page may open while loading)
        source = (
            stage.camera
            if stage is not None and stage.camera is not None
            else open_source(
                args.camera,
                args.video,
                args.masks,
                silhouette=silhouette_flag(args),
                realtime=args.realtime,
            )
        )
        if args.camera is not None and args.seconds is None:
            print("a camera never ends: stop with Ctrl-C (or give --seconds)", file=sys.stderr)
        ready = prepare(settings, source)
        segmentation = settings.perform.segmentation
        plate = segmentation in METHODS or (segmentation == "auto" and ready.descriptor != "pose")
        if args.camera is not None and plate:
            print(
                "step out of view for two seconds so that the background can be learned",
                file=sys.stderr,
            )
        with outputs:
            result = _run(args, source, ready, outputs, stage, truth)
            written = outputs.commit()
    _summary(args, source, ready, result, truth, written)
    if result.stopped and result.frames_with_media == 0:
        print(
            f"stopped by {result.stopped} before the first frame: nothing was performed, "
            "nothing written",
            file=sys.stderr,
        )
        return 128 + _SIGNALS[result.stopped]
    # Ctrl-C is how a camera session ends; another signal is reported as such
    return 0 if result.stopped in ("", "SIGINT") else 128 + _SIGNALS[result.stopped]


def _stage(args: argparse.Namespace, stack: contextlib.ExitStack, camera: bool) -> Stage | None:
    """The live page, served for a camera or a paced file (``--live-port``; none for a
    file read as fast as it goes: nobody could watch it)."""
    if args.live_port == 0 or not (args.camera is not None or args.realtime):
        return None
    try:
        stage = stack.enter_context(Stage(port=args.live_port, camera=camera))
    except OSError as exc:
        raise OSError(f"--live-port {args.live_port}: cannot serve the live page ({exc})") from None
    print(f"live page: {stage.url} (this machine only)", file=sys.stderr, flush=True)
    return stage


def _run(
    args: argparse.Namespace,
    source: Source,
    ready: Prepared,
    outputs: OutputSet,
    stage: Stage | None,
    truth: Truth | None,
) -> PerformResult:
    """The performance, with its log, tape, live page and signal handling; its outputs
    (BVH and timing, MP4, log) written to ``outputs``' temporary files, also after a
    stop."""
    clips, graph, layer, bank = ready.clips, ready.graph, ready.layer, ready.bank
    log_out = outputs.find("--log")
    with contextlib.ExitStack() as stack:
        log: Any = (
            stack.enter_context(DecisionLog(outputs.stage(log_out), log_out.said()))
            if log_out
            else None
        )
        tape = stack.enter_context(MaskTape(fps=graph.fps)) if args.video_out else None
        stops = stack.enter_context(StopOnSignal())
        painter = StagePainter(stage, clips, graph, truth) if stage is not None else None
        try:
            result = perform(
                source,
                layer,
                bank,
                clips,
                ready.settings,
                start=ready.start,
                seed=args.seed,
                fallback=ready.fallback,
                voice=ready.voice,
                bars=bar,
                log=log,
                tape=tape,
                on_frame=painter.on_frame if painter else None,
                on_decision=painter.on_decision if painter else None,
                stop=stops,
            )
        finally:
            source.close()
        if result.frames_with_media == 0 and not result.stopped:
            raise SourceError(_nothing_read(args, source, result))
        warn_source(source)
        _say_page(stage)
        if result.stopped:
            print(
                f"stopped by {result.stopped} at {result.media_seconds:.1f} s of media: "
                "writing what was performed",
                file=sys.stderr,
                flush=True,
            )
        if result.frames_with_media == 0:
            return result  # stopped before the first frame: nothing to write
        _write(args, source, ready, result, outputs, tape, log)
    return result


def _say_page(stage: Stage | None) -> None:
    """How the page's camera did: why it ended, its latency and frame rate."""
    camera = stage.camera if stage is not None else None
    if camera is None:
        return
    if camera.ended and camera.ended != "stopped":
        print(f"{camera.name}: {camera.ended}: writing what was performed", file=sys.stderr)
    got = stage.page_stats if stage is not None else {}
    if got.get("p50_ms") is not None:
        print(
            f"the page: camera frame to avatar pose p50 {got['p50_ms']:.0f} ms, "
            f"p99 {got['p99_ms']:.0f} ms over its last 10 s; it sent {got['fps']:.1f} "
            f"frames a second ({got['frames']:.0f} in all, {camera.refused} refused)"
        )


def _nothing_read(args: argparse.Namespace, source: Source, result: PerformResult) -> str:
    """Why a source gave no frame, as its kind says."""
    if args.camera == "browser":
        return f"{source.name}: no frame came from the page in {result.media_seconds:.1f} s"
    if args.camera is not None:
        return (
            f"{source.name}: no frame came from the camera in {result.media_seconds:.1f} s "
            "(a camera that does not open, or is in use?)"
        )
    if args.masks is not None:
        return f"{source.name}: no mask image in the folder could be read"
    return f"{source.name}: no frame could be read from the video (is it one OpenCV reads?)"


def _write(
    args: argparse.Namespace,
    source: Source,
    ready: Prepared,
    result: PerformResult,
    outputs: OutputSet,
    tape: MaskTape | None,
    log: DecisionLog | None,
) -> None:
    """The run's outputs into their temporary files (``outputs.commit`` moves them into
    place): the BVH and its timing, the MP4, the log that was written as it went."""
    out, timing = outputs.find("--out"), outputs.find("--out's timing file")
    if out is not None and timing is not None:
        motion = result.avatar.motion().motion
        outputs.write(out, lambda p: write_bvh(motion, p))
        outputs.write(
            timing,
            lambda p: _write_timing(p, args.out, result, motion.n_frames, motion.fps, source.name),
        )
    video = outputs.find("--video-out")
    if video is not None and tape is not None:
        outputs.write(video, lambda p: write_video(result, ready.bank, ready.clips, p, tape))
    if log is not None and log.lines:  # (written as it went)
        found = outputs.find("--log")
        assert found is not None
        outputs.write(found, lambda p: None)


def _summary(
    args: argparse.Namespace,
    source: Source,
    ready: Prepared,
    result: PerformResult,
    truth: Truth | None,
    written: list[Output],
) -> None:
    """The one summary line, what the avatar did, its agreement with the labels, and
    what was written."""
    clips = ready.clips
    made = [c for c in result.decisions if c.get("decision") is not None]
    lat = [c["latency_ms"] for c in made]
    jumps = sum("jump" in c for c in made)
    clips_seen = [c["clip"] for c in result.decisions]
    changes = sum(a != b for a, b in itertools.pairwise(clips_seen))
    minutes = max(result.media_seconds, 1e-9) / 60.0
    print(  # the one summary line
        f"{result.media_seconds:.1f} s of media ({result.frames_read} frames"
        + (
            f", {result.frames_dropped} dropped to keep up in real time"
            if result.frames_dropped
            else ""
        )
        + "): "
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
    crowded = sum(1 for c in result.decisions if c.get("people_in_view", 1) > 1)
    if crowded:
        print(
            f"{crowded} decision points saw more than one person in view: the avatar followed the "
            "largest silhouette (the log's people_in_view)"
        )
    print_actions(result.decisions, clips)
    if truth is not None:
        _print_agreement(result.decisions, clips, truth)
        warn_own_take(args.video, clips)
    skipped = getattr(source, "skipped", [])
    if skipped:
        shown = ", ".join(skipped[:5]) + (" ..." if len(skipped) > 5 else "")
        print(
            f"skipped {len(skipped)} unreadable mask files (each a frame without a silhouette, "
            f"in the log as such): {shown}",
            file=sys.stderr,
        )
    for out in written:  # (only what was written: a log of no decision is not)
        print(
            f"wrote {out.path}"
            + (" (the BVH's place in the input's media time)" if "timing" in out.option else "")
        )


def _print_agreement(decisions: list[dict[str, Any]], clips: list[Clip], truth: Truth) -> None:
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
    at = [float(d["t"]) for d in decisions]
    theirs = [truth.label_at(t) for t in at]
    lag = switch_delays(avatar_labels(decisions, clips), theirs, at, known)
    if lag["switches"]:
        followed = lag["switches"] - lag["missed"]
        after = f", a median {lag['median_s']:g} s later" if followed else ""
        print(
            f"the avatar took up the performer's new action at {followed} of "
            f"{lag['switches']} changes{after}"
        )
