"""The performance loop (Lee et al. §5.3): frames in, a decision every 0.1 s, avatar out.

Media time drives everything (a file runs as fast as it can unless paced; a camera runs
on the clock). The performer's features are sampled into a buffer at the library's rate;
every ``decide_every`` seconds the matcher decides from the avatar's current frame and
the avatar takes what it chose (blending into it); at most one decision a frame, so after
a stall the points missed are skipped (the log says how many), not made in a burst. With
jumps (``LandingSettings``, the default) that is motion matching: a direct blended jump
into the frame after one of the library's best windows when it fits the performer
clearly better than the avatar's own last second, holding its frame still when that fits
a performer standing still better, else playing on; without, the paper's best cluster
path, and now and then the way through the graph to a better window (relocation).
Without a usable silhouette (nobody in view, a dark frame) the avatar keeps moving on.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
from collections import deque
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import IO, Any

import numpy as np
from numpy.typing import NDArray

from control.avatar import AVATAR_BLENDING, Avatar, JumpCosts
from control.clusters import HigherLayer
from control.kernels import one_thread
from control.motion import Clip
from silhouette_bank import Bank

from ._decision import Decision
from ._fallback import FALLBACK_REASONS, UPRIGHT_REASONS, SilhouetteFallback
from ._frames import FrameReader
from ._matcher import Matcher
from ._search import Bars
from ._settings import PerformSettings
from ._sources import Source
from ._video import MaskTape
from ._voice import PoseVoice
from ._vote import ActionVote, Evidence, Partner

__all__ = ["PerformResult", "Performance", "perform"]

#: degrees a second the avatar's blended joints may turn in a frame beyond what their
#: source frames turn (``control.graph.follow_turns``), and the rate of its leg IK's
#: corrections (``TURN_RATE`` is 300 elsewhere): its blends pile up (a jump every few
#: tenths of a second), and without both limits a fading offset on a fast joint turns
#: faster at junctions than the library's own 99th percentile.
TURN_LIMIT = 450.0
IK_TURN_RATE = 200.0


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
    #: frames a file paced in real time dropped to keep up (``vision._sources``)
    frames_dropped: int = 0


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
    on_frame: Callable[[float, NDArray[np.bool_] | None, Avatar, Any], None] | None = None,
    on_decision: Callable[[dict[str, Any]], None] | None = None,
    stop: Callable[[], str] | None = None,
    fallback: Bank | None = None,
    bars: Bars | None = None,
    voice: Bank | None = None,
) -> PerformResult:
    """Run the loop until the source ends (or ``settings.seconds`` of media time).

    ``tape``: the performer's mask at every avatar frame is appended to it (for the
    side-by-side video, ``vision._video.write_video``). ``on_frame(t, mask, avatar,
    picture)`` is called for every media frame (``picture``: the colour frame and the
    pose model's landmarks, each ``None`` when there are none), ``on_decision(entry)``
    with every decision log entry (the live view uses both). ``stop()`` is asked before
    every frame: a non-empty answer (why) ends the run there, and what was performed is
    returned as usual. ``fallback``: with a pose ``bank``, a silhouette bank of the same
    clips (``vision._fallback``). ``voice``: with a silhouette ``bank``, a pose bank of
    the same clips, whose matcher scores the landmarks read from each silhouette
    (``vision._voice``). ``bars(label, unit)``: progress bars for the search's tables and
    index where they are made before the run (a large library's take minutes)."""
    run = Performance(source, layer, bank, clips, settings, start, seed, fallback, bars, voice)
    return run.run(log=log, tape=tape, on_frame=on_frame, on_decision=on_decision, stop=stop)


class Performance:
    """One performance, a step a method: its ``reader`` (``FrameReader``) reads a frame's
    features, ``advance`` takes the buffer and the avatar's clock to it, ``decide`` at a
    decision point (``place_avatar`` where the performer is first found, ``relocate`` now
    and then without jumps), and ``run`` the loop."""

    def __init__(
        self,
        source: Source,
        layer: HigherLayer,
        bank: Bank,
        clips: Sequence[Clip],
        settings: PerformSettings | None = None,
        start: int | None = None,
        seed: int = 0,
        fallback: Bank | None = None,
        bars: Bars | None = None,
        voice: Bank | None = None,
    ) -> None:
        # the graph's clips, in its order (one of another skeleton would misalign the vote)
        self.graph, clips = layer.graph, layer.graph.clips_of(clips)
        self.source, self.clips, self.start, self.seed = source, clips, start, seed
        self.settings = settings = settings or PerformSettings()
        #: the silhouette's matcher, where the landmarks fail (landmarks only; made below)
        self.fallback: SilhouetteFallback | None = None
        #: the landmarks read from the silhouettes (silhouettes only; made below)
        self.voice: PoseVoice | None = None
        # with ``fuse``, each ballot weighs the other descriptor's evidence too: the
        # landmarks' the silhouette's, the silhouette's the landmarks read from it
        fuse = settings.match.action.fuse
        partner: Partner | None = None
        if fuse and fallback is not None:
            partner = self._silhouette_evidence
        elif fuse and voice is not None:
            partner = self._landmark_evidence
        self.matcher = matcher = Matcher(layer, bank, settings.match, partner=partner)
        # motion matching: relocation at every decision. One set of jump costs for every
        # avatar of the run (``open_matcher`` computes its frame features before the first frame)
        self.jumps = jumps = settings.match.landing.jumps
        self.costs = JumpCosts(self.graph, clips, anywhere=jumps)
        self.avatar = self.open_matcher(start, bars)
        matcher.ready(clips, settings.decide_every)
        if fallback is not None and matcher.desc.kind == "pose":
            period = settings.decide_every
            args = (layer, fallback, clips, matcher, self.avatar, self.costs, period, bars)
            self.fallback = SilhouetteFallback(*args)
        if partner is not None and voice is not None and matcher.desc.kind == "silhouette":
            self.voice = PoseVoice(layer, voice, clips, matcher, settings.decide_every, bars)
        #: what each frame says of the performer
        self.reader = FrameReader(source, settings, matcher.desc, self.fallback, self.voice)
        self.period = 1.0 / self.graph.fps
        #: the performer's features at the library's rate: the last window (``window``)
        #: and before it as many as the matcher's tempos read
        self.history: deque[NDArray[np.float64]] = deque(maxlen=matcher.history_frames)
        self.next_tick = 0.0
        self.next_decision = settings.decide_every
        self.t_avatar = 0.0
        self.decisions: list[dict[str, Any]] = []
        self.views: list[int] = [0]
        self.view = 0
        self.located = False
        self.last_relocate = 0.0
        self.en_route = 0.0  # media time at which the avatar reaches a relocation's window
        background = settings.background_search
        if background is None:
            background = bool(getattr(source, "live", False) or getattr(source, "realtime", False))
        # with jumps the fast index answers within the decision; without, relocation's
        # brute force search may run in a thread
        self.searcher = (
            ThreadPoolExecutor(1, thread_name_prefix="mimic-search")
            if background and not jumps
            else None
        )
        self.pending: Future[tuple[int, int, float] | None] | None = None
        self.t_start = 0.0
        self.tape: MaskTape | None = None

    def _silhouette_evidence(self, vote: ActionVote) -> Evidence | None:
        """The silhouette's evidence for the landmarks' ballot (``Partner``)."""
        return None if self.fallback is None else self.fallback.evidence(vote)

    def _landmark_evidence(self, vote: ActionVote) -> Evidence | None:
        """The landmarks' evidence for the silhouette's ballot (``Partner``)."""
        return None if self.voice is None else self.voice.evidence(vote)

    def open_matcher(self, start: int | None, bars: Bars | None) -> Avatar:
        """With jumps, the search's index opened and the jump costs' frame features
        computed now, not at the first decision (a camera would stall there), and one
        throwaway decision made from the new avatar (``Matcher.warm_up``); the avatar."""
        if self.jumps:
            # the features (numpy on every frame: 1.9 s at 500,000 frames) in a thread
            # while this one opens the search's index (mostly reading: 0.9 s there)
            with ThreadPoolExecutor(1) as pool:
                computing = pool.submit(lambda: self.costs.features)
                self.matcher.windows.open(bars)
                computing.result()
        avatar = self.new_avatar(start)
        if self.jumps:
            recent = avatar.recent(self.matcher.recent_frames)
            self.matcher.warm_up(avatar.frame, recent, self.costs)
        return avatar

    def new_avatar(self, at: int | None) -> Avatar:
        return Avatar(
            self.graph,
            self.clips,
            start=at,
            seed=self.seed,
            anywhere=self.jumps,
            jump_costs=self.costs,
            blend_settings=dataclasses.replace(
                AVATAR_BLENDING,
                seconds=self.settings.blend,
                feet="floor",  # its blends never end: planted feet on the floor
                turn_limit=TURN_LIMIT,
                ik_turn_rate=IK_TURN_RATE,
            ),
        )

    # --- the steps -------------------------------------------------------------------------

    def window(self) -> NDArray[np.float64]:
        """The performer's last window of features ``(m, F)``, ``m`` up to ``matcher.n``."""
        n = len(self.history)
        return np.array(list(itertools.islice(self.history, max(0, n - self.matcher.n), n)))

    def advance(self, t: float) -> None:
        """The library-rate history, and the avatar's clock, up to media time ``t``."""
        while self.next_tick <= t + 1e-9:
            self.history.append(self.reader.latest)
            if self.fallback is not None:
                self.fallback.tick()
            if self.voice is not None:
                self.voice.tick()
            self.next_tick += self.period
        while self.t_avatar + self.period <= t + 1e-9:
            self.avatar.step()
            self.t_avatar += self.period
            if self.tape is not None:
                self.tape.append(self.reader.mask, *self.reader.picture)
            self.views.append(self.view)

    def place_avatar(self, t: float, entry: dict[str, Any]) -> None:
        """Half a window in (``WindowSearch.early``; else at the first whole window):
        start the avatar where the library looks most like the performer (its motion so
        far is dropped), at the frame that matches the performer's latest."""
        matcher = self.matcher
        got = matcher.find_window(window := self.window())
        if got is None:
            return
        self.located = True
        self.last_relocate = t  # that was this second's global search
        # with jumps, where the performer is now (the window's last frame), and the lead
        end = np.array([got[0] + len(window) - 1])
        at = int(matcher.lander.ahead(end)[0]) if self.jumps else got[0]
        self.avatar = self.new_avatar(at)
        self.views, self.view = [got[1]], got[1]
        self.t_start = t
        if self.tape is not None:  # the avatar restarts: so does its video
            self.tape.reset()
            self.tape.append(self.reader.mask, *self.reader.picture)
        entry.update(frame=self.avatar.frame, located=round(got[2], 4))
        entry["clip"], entry["clip_frame"] = self.graph.locate(self.avatar.frame)

    def relocate(self, t: float, d: Decision, entry: dict[str, Any]) -> Decision:
        """Without jumps, now and then: the way through the graph to a better window
        than the decision's, when the global search finds one (in a thread for a live
        source, its answer taken at a later decision)."""
        matcher, settings = self.matcher, self.settings
        got = None
        due = t - self.last_relocate >= settings.match.paths.relocate_every - 1e-9
        if self.searcher is None and due:
            self.last_relocate = t
            got = matcher.find_window(self.window())
        elif self.searcher is not None and self.pending is not None and self.pending.done():
            got, self.pending = self.pending.result(), None
        elif self.searcher is not None and self.pending is None and due:
            self.last_relocate = t
            self.pending = self.searcher.submit(matcher.find_window, self.window())
        if got is None or not got[2] < settings.match.paths.relocate_ratio * d.cost:
            return d
        way = matcher.paths.route(self.avatar.frame, got[0])
        if way is None:  # better elsewhere, but too far away through the graph
            entry["relocation_unreachable"] = int(got[0])
            return d
        # the way there, then the window that matched
        tail = np.arange(got[0] + 1, got[0] + matcher.n, dtype=np.int64)
        frames = np.concatenate((way[0], tail))
        edges = np.concatenate((way[1], np.full(tail.size, -1, np.int64)))
        entry["relocated"] = int(got[0])
        self.en_route = t + (way[0].size - 1) * self.period
        return dataclasses.replace(
            d,
            frames=frames,
            edges=edges,
            cost=got[2],
            view=got[1],
            cluster_path=np.zeros(0, dtype=np.int64),
        )

    def _entry(self, t: float, missed: int) -> dict[str, Any]:
        """A decision point's log entry before the decision: where the avatar is."""
        clip, f = self.graph.locate(self.avatar.frame)
        entry = {"t": round(t, 3), "frame": self.avatar.frame, "clip": clip, "clip_frame": f}
        if missed:
            entry["skipped"] = missed
        if self.reader.others:  # the largest is followed, the log says so
            entry["people_in_view"] = 1 + self.reader.others
        pose = self.reader.pose
        if pose is not None and pose.hidden:  # matched all the same
            entry["hidden"] = list(pose.hidden)
        return entry

    def match(self, entry: dict[str, Any]) -> Decision | None:
        """The matcher's decision for the avatar's frame; where the landmark matcher
        has none for want of a pose, or its upright body matches nothing, the
        silhouette's (``vision._fallback``; ``entry`` says which decided, ``by``, and
        why the silhouette did not)."""
        matcher, avatar = self.matcher, self.avatar
        recent = avatar.recent(matcher.recent_frames)
        d = (
            matcher.decide(avatar.frame, np.array(self.history), recent, avatar.jump_costs)
            if self.jumps
            else matcher.decide(avatar.frame, self.window())
        )
        if self.voice is not None:  # (the share of silhouettes the pose model read)
            read = self.voice.read_share()
            if np.isfinite(read):
                entry["landmarks_read"] = round(read, 2)
        if self.fallback is None:
            return d
        weight = self.fallback.weight_given()  # (where the ballot asked it: limbs hidden)
        if d is not None:
            entry["by"] = "landmarks"
            if weight > 0:
                entry["silhouette_weight"] = round(weight, 2)
            return d
        why = matcher.why.split(" (")[0]
        upright = self.reader.pose is not None and self.reader.pose.upright
        if why not in FALLBACK_REASONS and not (why in UPRIGHT_REASONS and upright):
            return d
        d = self.fallback.decide(avatar.frame, recent, avatar.jump_costs)
        if d is None:
            entry["silhouette"] = self.fallback.why
        else:
            entry["by"] = "silhouette"
        return d

    def decide(self, t: float) -> dict[str, Any]:
        """The decision at media time ``t``: its log entry, the avatar told."""
        settings, matcher, avatar = self.settings, self.matcher, self.avatar
        # at most one decision a frame: after a stall (a camera that froze, a slow
        # frame) the points missed are skipped and said, not made in a burst on the
        # same frame
        missed = int((t + 1e-9 - self.next_decision) // settings.decide_every)
        self.next_decision += (missed + 1) * settings.decide_every
        matcher.vote.skipped(missed)  # (the next vote stands for those points too)
        entry = self._entry(t, missed)
        filled = min(len(self.history), matcher.n)
        full = filled == matcher.n
        # the avatar is placed as soon as half a window is in (then played on until the
        # window is whole), unless told where to start
        if not self.located and settings.match.paths.start_at_best and self.start is None:
            half = filled >= max(2, (matcher.n + 1) // 2) and matcher.windows.early
            if full or half:
                self.place_avatar(t, entry)
                avatar = self.avatar
        # on the way to a relocation's window: no decision may turn it aside
        routing = t < self.en_route - 1e-9
        d = self.match(entry) if full and not routing else None
        by_landmarks = entry.get("by") != "silhouette"  # (relocation searches landmarks)
        relocating = not self.jumps and settings.match.paths.relocate_every > 0
        if d is not None and relocating and by_landmarks:
            d = self.relocate(t, d, entry)
        if d is None:
            entry["decision"] = None
            entry["reason"] = (
                self.reader.why_blank  # nothing to match, on the way or not
                if not np.isfinite(self.reader.latest).all()
                else "en route"
                if routing
                else "filling buffer"
                if not full
                # the performer back in view, in under half of the window so far
                else "filling buffer (back in view)"
                if matcher.why in ("no pose", "no silhouette")
                and (self.fallback is None or self.fallback.why == "no silhouette")
                else matcher.why or "no decision"
            )
            if routing:
                entry["en_route"] = True
            return entry
        avatar.take(d.frames, d.edges)
        self.view = d.view if d.view >= 0 else self.view
        entry.update(d.logged(self.view))
        if 0 <= matcher.vote.voted < len(matcher.vote.names):  # the action voted for
            entry["voted"] = matcher.vote.names[matcher.vote.voted]
        if matcher.lander.repeated is not None and entry.get("by") != "silhouette":
            entry["repeats"] = True  # (the performer goes on: no ballot opened a new action)
        if self.matcher.windows.facing is not None:  # which way the performer is taken to face
            entry["facing"] = "camera" if self.matcher.windows.facing.toward else "away"
        return entry

    def run(
        self,
        log: IO[str] | None = None,
        tape: MaskTape | None = None,
        on_frame: Callable[[float, NDArray[np.bool_] | None, Avatar, Any], None] | None = None,
        on_decision: Callable[[dict[str, Any]], None] | None = None,
        stop: Callable[[], str] | None = None,
    ) -> PerformResult:
        """The loop (``perform`` says what the arguments do)."""
        self.tape = tape
        if tape is not None:
            tape.append(None)  # the avatar's first frame comes before any media
        n_read = n_media = 0
        t = 0.0
        stopped = ""
        # the numeric libraries on one thread: a decision's small matrix products spread
        # over threads waited on one another (its p99 about halves on one thread)
        with one_thread():
            try:
                while True:
                    if stop is not None and (stopped := stop()):
                        break
                    frame = self.source.read()
                    if frame is None:
                        break
                    n_read += 1
                    t = frame.t
                    if self.settings.seconds is not None and t > self.settings.seconds:
                        break
                    mask = self.reader.read(frame)
                    if (
                        frame.image is not None
                        or frame.mask is not None
                        or frame.landmarks is not None
                    ):
                        n_media += 1
                    if on_frame is not None:
                        on_frame(t, mask, self.avatar, self.reader.picture)
                    self.advance(t)
                    if self.next_decision <= t + 1e-9:
                        entry = self.decide(t)
                        self.decisions.append(entry)
                        if on_decision is not None:
                            on_decision(entry)
                        if log is not None:
                            log.write(json.dumps(entry) + "\n")
            finally:
                if self.searcher is not None:  # a search still running is left to finish alone
                    self.searcher.shutdown(wait=False, cancel_futures=True)
        dropped = int(getattr(self.source, "dropped", 0))
        return PerformResult(
            self.avatar,
            self.decisions,
            self.views,
            t,
            n_read,
            stopped,
            n_media,
            self.t_start,
            dropped,
        )
