"""The performance loop (Lee et al. §5.3): frames in, a decision every 0.1 s, avatar out.

Media time drives everything (a file runs as fast as it can unless paced; a camera runs
on the clock). The performer's features are sampled into a buffer at the library's rate;
every ``decide_every`` seconds the matcher decides from the avatar's current frame and
the avatar takes what it chose (blending into it); at most one decision a frame, so after
a stall the points missed are skipped (the log says how many), not made in a burst. With
``MatchSettings.jumps`` (the default) that is motion matching: a direct blended jump into
the frame after one of the library's best windows when it fits the performer clearly
better than the avatar's own last second, else playing on; without, the paper's best
cluster path, and now and then the way through the graph to a better window
(relocation). Without a usable silhouette (nobody in view, a dark frame, a camera that
is reconnecting) the avatar simply keeps moving: along its current path, then on its own.
"""

from __future__ import annotations

import dataclasses
import json
from collections import deque
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import IO, Any

import numpy as np
from numpy.typing import NDArray

from control.avatar import Avatar, JumpCosts
from control.clusters import HigherLayer
from control.motion import Clip
from silhouette_bank import Bank, silhouette_features

from ._landmarks import PoseReader
from ._matcher import Matcher, MatchSettings
from ._person import make_segmenter, resolve_segmentation
from ._segment import clean_mask
from ._sources import CameraSource, Source
from ._video import MaskTape

__all__ = ["MAX_COVER", "PerformResult", "PerformSettings", "perform"]

#: a silhouette mask covering more of the frame than this is no performer (a white
#: frame, the lights going on under a background subtractor): treated as no silhouette
MAX_COVER = 0.6


@dataclass(frozen=True)
class PerformSettings:
    decide_every: float = 0.1
    #: "auto": the pose descriptor's landmarks need the pose model; otherwise a camera
    #: learns a plate (mog2) and footage uses a person segmenter (pose)
    segmentation: str = "auto"
    learn_frames: int = 30
    match: MatchSettings = field(default_factory=MatchSettings)
    seconds: float | None = None  # stop after this much media time (cameras never end)
    blend: float = 1.0  # the avatar's blend interval, seconds (transitions and jumps)
    #: run relocation's global search in a thread, its answer taken at a later decision,
    #: so that a live source is never held up by it (it takes tens to hundreds of ms);
    #: None: only for a camera or a paced (``realtime``) file, so that replays stay
    #: deterministic
    background_search: bool | None = None


@dataclass
class PerformResult:
    avatar: Avatar
    decisions: list[dict[str, Any]]
    views: list[int]  # the best-matching view per avatar frame
    media_seconds: float
    frames_read: int  # frames the source gave, with media or not
    #: why the run ended before its source did ("" when it did not): e.g. "SIGTERM"
    stopped: str = ""
    #: frames that carried an image or a mask (a camera that never opens gives none)
    frames_with_media: int = 0
    #: media time (s) of the avatar's first frame: its motion (BVH, MP4) starts there
    avatar_start_s: float = 0.0


def perform(
    source: Source,
    layer: HigherLayer,
    bank: Bank,
    clips: Sequence[Clip],
    settings: PerformSettings | None = None,
    start: int | None = None,
    seed: int = 0,
    log: IO[str] | None = None,
    tape: MaskTape | None = None,
    on_frame: Callable[[float, NDArray[np.bool_] | None, Avatar], None] | None = None,
    on_decision: Callable[[dict[str, Any]], None] | None = None,
    stop: Callable[[], str] | None = None,
) -> PerformResult:
    """Run the loop until the source ends (or ``settings.seconds`` of media time).

    ``tape``: the performer's mask at every avatar frame is appended to it (for the
    side-by-side video, ``vision._video.write_video``). ``on_frame(t, mask, avatar)`` is
    called for every media frame, ``on_decision(entry)`` with every decision log entry
    (the live view uses both). ``stop()`` is asked before every frame: a non-empty
    answer (why) ends the run there, and what was performed is returned as usual."""
    settings = settings or PerformSettings()
    graph = layer.graph
    matcher = Matcher(layer, bank, settings.match)
    jumps = settings.match.jumps  # motion matching: relocation is every decision's
    # one set of jump costs for every avatar of the run, its frame features computed
    # before the first frame rather than at the first jump
    costs = JumpCosts(graph, clips, anywhere=jumps)
    if jumps:  # built now, not at the first decision (a camera would stall there)
        _ = costs.features
        matcher.index()

    def new_avatar(at: int | None) -> Avatar:
        return Avatar(
            graph,
            clips,
            start=at,
            seed=seed,
            anywhere=jumps,
            jump_costs=costs,
            blend=settings.blend,
        )

    avatar = new_avatar(start)
    if jumps and bank.features.shape[0] >= matcher.n:
        # one throwaway decision on a window of the library itself, so that the first
        # real one does not pay for loading or compiling the search and DTW kernels
        # (0.5 s on a fresh install: a stall a performer would see)
        probe = np.asarray(bank.features[: matcher.n, 0], dtype=np.float64)
        matcher.decide(avatar.frame, probe, avatar.recent(matcher.recent_frames), costs)
        matcher.why, matcher.last_own = "", float("inf")
    segmenter: Any = None
    landmarks = matcher.desc.kind == "pose"
    reader = PoseReader() if landmarks else None
    why_blank = ""  # why the latest frame has no features
    period = 1.0 / graph.fps
    buffer: deque[NDArray[np.float64]] = deque(maxlen=matcher.n)
    blank = np.full(matcher.n_features, np.nan)  # a frame without a silhouette
    latest = blank
    latest_mask: NDArray[np.bool_] | None = None
    next_tick = 0.0
    next_decision = settings.decide_every
    t_avatar = 0.0
    decisions: list[dict[str, Any]] = []
    if tape is not None:
        tape.append(None)  # the avatar's first frame comes before any media
    views: list[int] = [0]
    view = 0
    located = False
    last_relocate = 0.0
    en_route = 0.0  # media time at which the avatar reaches a relocation's window
    background = settings.background_search
    if background is None:
        background = isinstance(source, CameraSource) or bool(getattr(source, "realtime", False))
    # with jumps the fast index answers within the decision; without, relocation's brute
    # force search may run in a thread
    searcher = (
        ThreadPoolExecutor(1, thread_name_prefix="mimic-search")
        if background and not jumps
        else None
    )
    pending: Future[tuple[int, int, float] | None] | None = None
    n_read = 0
    t = 0.0
    stopped = ""
    n_media = 0
    t_start = 0.0
    try:
        while True:
            if stop is not None and (stopped := stop()):
                break
            frame = source.read()
            if frame is None:
                break
            n_read += 1
            t = frame.t
            if settings.seconds is not None and t > settings.seconds:
                break
            mask: NDArray[np.bool_] | None
            if frame.mask is not None:
                if landmarks:
                    raise ValueError(
                        f"{source.name}: the pose descriptor needs "
                        "colour frames, and this source gives silhouettes (use a silhouette "
                        "descriptor: --descriptor multigrid)"
                    )
                mask = clean_mask(frame.mask)
            elif frame.image is not None:
                if segmenter is None:
                    method = resolve_segmentation(
                        settings.segmentation, isinstance(source, CameraSource), landmarks
                    )
                    segmenter = make_segmenter(method, settings.learn_frames)
                mask = segmenter.apply(frame.image)
            else:
                mask = None
            problem = frame.problem  # e.g. an unreadable mask file: no silhouette, said why
            if frame.image is not None or frame.mask is not None:
                n_media += 1
            cover = float(mask.mean()) if mask is not None and mask.size else 0.0
            if not landmarks and cover > MAX_COVER:
                # a lighting change, a white frame, a bad mask: no performer looks so
                mask, problem = None, f"the mask covers {cover:.0%} of the frame"
            if reader is not None:
                lm = getattr(segmenter, "landmarks", None) if frame.image is not None else None
                h_px, w_px = frame.image.shape[:2] if frame.image is not None else (1, 1)
                latest = reader.read(lm, (w_px, h_px))
                why_blank = reader.why
            elif mask is not None:
                latest = silhouette_features(mask, descriptor=matcher.desc)
            else:
                latest, why_blank = blank, problem or "no silhouette"
            latest_mask = mask
            if on_frame is not None:
                on_frame(t, mask, avatar)
            # the library-rate buffer, and the avatar's clock
            while next_tick <= t + 1e-9:
                buffer.append(latest)
                next_tick += period
            while t_avatar + period <= t + 1e-9:
                avatar.step()
                t_avatar += period
                if tape is not None:
                    tape.append(latest_mask)
                views.append(view)
            if next_decision <= t + 1e-9:
                # at most one decision a frame: after a stall (a camera that froze, a slow
                # frame) the points missed are skipped and said, not made in a burst on
                # the same frame
                missed = int((t + 1e-9 - next_decision) // settings.decide_every)
                next_decision += (missed + 1) * settings.decide_every
                clip, f = graph.locate(avatar.frame)
                entry: dict[str, Any] = {
                    "t": round(t, 3),
                    "frame": avatar.frame,
                    "clip": clip,
                    "clip_frame": f,
                }
                if missed:
                    entry["skipped"] = missed
                full = len(buffer) == matcher.n
                if full and not located and settings.match.locate and start is None:
                    # the first full buffer: start the avatar where the library looks most
                    # like the performer (its motion so far is dropped), unless told where
                    got = matcher.locate(np.array(buffer))
                    if got is not None:
                        located = True
                        last_relocate = t  # that was this second's global search
                        # with jumps, where the performer is now: the window's last frame
                        at = got[0] + matcher.n - 1 if jumps else got[0]
                        avatar = new_avatar(at)
                        views, view = [got[1]], got[1]
                        t_start = t
                        if tape is not None:  # the avatar restarts: so does its video
                            tape.reset()
                            tape.append(latest_mask)
                        entry.update(frame=avatar.frame, located=round(got[2], 4))
                        entry["clip"], entry["clip_frame"] = graph.locate(avatar.frame)
                # on the way to a relocation's window: no decision may turn it aside
                routing = t < en_route - 1e-9
                d = None
                if full and not routing:
                    d = (
                        matcher.decide(
                            avatar.frame,
                            np.array(buffer),
                            avatar.recent(matcher.recent_frames),
                            avatar.jump_costs,
                        )
                        if jumps
                        else matcher.decide(avatar.frame, np.array(buffer))
                    )
                every = 0.0 if jumps else settings.match.relocate
                got = None
                if d is not None and every > 0:
                    due = t - last_relocate >= every - 1e-9
                    if searcher is None and due:
                        last_relocate = t
                        got = matcher.locate(np.array(buffer))
                    elif searcher is not None and pending is not None and pending.done():
                        got, pending = pending.result(), None
                    elif searcher is not None and pending is None and due:
                        last_relocate = t
                        pending = searcher.submit(matcher.locate, np.array(buffer))
                    if got is not None and got[2] < settings.match.relocate_ratio * d.cost:
                        way = matcher.route(avatar.frame, got[0])
                        if way is None:  # better elsewhere, but too far away through the graph
                            entry["relocation_unreachable"] = int(got[0])
                        else:
                            # the way there, then the window that matched
                            tail = np.arange(got[0] + 1, got[0] + matcher.n, dtype=np.int64)
                            frames = np.concatenate((way[0], tail))
                            edges = np.concatenate((way[1], np.full(tail.size, -1, np.int64)))
                            d = dataclasses.replace(
                                d,
                                frames=frames,
                                edges=edges,
                                cost=got[2],
                                view=got[1],
                                cluster_path=np.zeros(0, dtype=np.int64),
                            )
                            entry["relocated"] = int(got[0])
                            en_route = t + (way[0].size - 1) * period
                if d is None:
                    entry["decision"] = None
                    entry["reason"] = (
                        why_blank  # nothing to match, on the way or not
                        if not np.isfinite(latest).all()
                        else "en route"
                        if routing
                        else "filling buffer"
                        if not full
                        else matcher.why or "no decision"
                    )
                    if routing:
                        entry["en_route"] = True
                else:
                    avatar.take(d.frames, d.edges)
                    view = d.view if d.view >= 0 else view
                    if "plays_on" in d.extra:
                        entry["plays_on"] = True
                    if "jump" in d.extra:
                        entry.update(
                            jump=int(d.extra["jump"]),
                            own_cost=round(d.extra["own"], 4)
                            if np.isfinite(d.extra["own"])
                            else None,
                            blend=round(d.extra["blend"], 4),
                        )
                    entry.update(
                        decision=[int(c) for c in d.cluster_path],
                        cost=round(d.cost, 4) if np.isfinite(d.cost) else None,
                        runner_up=round(d.runner_up, 4) if np.isfinite(d.runner_up) else None,
                        view=view,
                        candidates=d.candidates,
                        latency_ms=round(d.latency_ms, 3),
                    )
                decisions.append(entry)
                if on_decision is not None:
                    on_decision(entry)
                if log is not None:
                    log.write(json.dumps(entry) + "\n")
    finally:
        if searcher is not None:  # a search still running is left to finish alone
            searcher.shutdown(wait=False, cancel_futures=True)
    return PerformResult(avatar, decisions, views, t, n_read, stopped, n_media, t_start)
