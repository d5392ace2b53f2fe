"""The running avatar, shared by every interface (choice, sketch, performance).

It stands on a frame of the motion graph and moves one frame per ``1 / fps`` seconds:
along a path it was told to take, or, with nothing to do, by eq. 1 (the random walk).
It keeps its history, so its motion, blended as in Lee et al. §4.1.1 with planted feet,
can be produced at any time, and it tracks the root transform that its transitions
have composed (fixed coordinates: the identity).

Besides the graph's transitions it can take a *direct blended jump* (``JUMP`` in a
path) to any frame of the component (with ``anywhere``, of the library): the
motion-matching move of the vision interface (Clavet 2016). A jump is blended exactly
like a transition, with the alignment and distance the graph's own rule gives the pair
(``jump_costs``), so it may go where no transition was kept.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from .graph import (
    BlendSettings,
    FrameFeatures,
    MotionGraph,
    Synthesis,
    compose,
    frame_features,
    pair_distances,
    random_step,
    synthesize,
)
from .motion import Clip, action_keys

__all__ = ["AVATAR_BLENDING", "JUMP", "Avatar", "JumpCosts"]

IntArray = NDArray[np.int64]

#: an edge code in a path given to ``Avatar.take``: a direct blended jump
JUMP = -2


class JumpCosts:
    """What a direct jump between two frames of ``graph`` costs: the graph's frame
    distance ``D(a, b - 1)`` (as for a transition ``a -> b``) and the alignment placing
    ``b``'s motion onto ``a``'s (``pair_distances``), computed on demand."""

    def __init__(self, graph: MotionGraph, clips: Sequence[Clip], anywhere: bool = False) -> None:
        self.graph = graph
        self.anywhere = anywhere
        self._clips = graph.clips_of(clips)
        self._feat: FrameFeatures | None = None
        first = np.zeros(graph.n_frames, dtype=bool)
        first[graph.clip_start[:-1]] = True
        #: frames a jump may land on: not the first of a clip (it has no predecessor to
        #: blend from), and in the component unless ``anywhere``
        self.landing = ~first if anywhere else graph.in_scc & ~first

    @property
    def features(self) -> FrameFeatures:
        if self._feat is None:
            self._feat = frame_features(self._clips, self.graph.options.coords)
        return self._feat

    def __call__(
        self, frame: int, targets: IntArray
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(D (K,), align (K, 4))`` of jumps from ``frame`` to each of ``targets``."""
        targets = np.asarray(targets, dtype=np.int64)
        if targets.size and not self.landing[targets].all():
            bad = int(targets[~self.landing[targets]][0])
            raise ValueError(
                f"frame {bad} cannot be jumped to (outside the component, or a clip's first)"
            )
        o = self.graph.options
        return pair_distances(
            self.features,
            np.full(targets.size, frame, dtype=np.int64),
            targets - 1,
            o.nu,
            **o.terrain_args(),
        )


#: an avatar's blending: ``BlendSettings``' but for planted feet held up to 0.4 m from
#: where the blend puts them before they slide (a graph walk's 0.2 m): a direct jump's
#: blend carries the body further than a graph transition's, and planted feet slide
#: least there (``benchmarks/HISTORY.md``)
AVATAR_BLENDING = BlendSettings(max_offset=0.4)


class Avatar:
    """An avatar moving through ``graph``.

    Parameters
    ----------
    graph, clips : the motion graph and the library clips it was built from.
    start : first graph frame (default: drawn from the component with ``seed``).
    seed : seeds the probabilistic moves.
    anywhere : direct jumps (and ``start``) may go to any frame of the library, not only
        the graph's component; outside it the avatar plays on, and where its clip ends
        it jumps to the nearest frame (the graph's distance) of the same action with a
        second left to play, else to the component's nearest.
    jump_costs : the ``JumpCosts`` of ``graph`` to use (shared by avatars of one graph,
        so its frame features are computed once); by default its own.
    blend_settings : how its motion is blended and its feet kept (``synthesize``'s
        ``BlendSettings``); by default ``AVATAR_BLENDING``.
    """

    def __init__(
        self,
        graph: MotionGraph,
        clips: Sequence[Clip],
        start: int | None = None,
        seed: int = 0,
        anywhere: bool = False,
        jump_costs: JumpCosts | None = None,
        blend_settings: BlendSettings = AVATAR_BLENDING,
    ) -> None:
        self.graph = graph
        self.blend_settings = blend_settings
        self.clips = list(clips)
        self._rng = np.random.default_rng(seed)
        scc = np.flatnonzero(graph.in_scc)
        if scc.size == 0:
            raise ValueError("the graph has no component to move in")
        if start is None:
            start = int(self._rng.choice(scc))
        elif not (0 <= start < graph.n_frames and (anywhere or graph.in_scc[start])):
            raise ValueError(f"start frame {start} is not in the graph's component")
        self._frames = [int(start)]
        self._jumps: list[int] = []
        self._edges: list[int] = []
        self._plan: deque[tuple[int, int]] = deque()
        self._clock = 0.0
        self._yaw = 0.0
        self._trans = np.zeros(3)
        self._indptr = graph.indptr
        self._like = graph.likelihood()
        self._plays = graph.plays_on()
        # playing on inside a clip, in the component or not (the moves of ``anywhere``)
        self._next = np.ones(graph.n_frames, dtype=bool)
        self._next[graph.clip_start[1:] - 1] = False
        self._actions: IntArray | None = None  # (``action_keys``, when first needed)
        #: landing frames with a second left to play in their clip (with ``_actions``)
        self._lasting = np.zeros(0, dtype=bool)
        self.anywhere = anywhere
        self._blend_frames = blend_settings.frames(graph.fps)
        if jump_costs is not None and (
            jump_costs.graph is not graph or jump_costs.anywhere != anywhere
        ):
            raise ValueError("jump_costs belong to another graph, or another anywhere")
        self.jump_costs = jump_costs or JumpCosts(graph, clips, anywhere)
        # direct jumps taken: edge graph.n_edges + k is jump k
        self._jump_src: list[int] = []
        self._jump_dst: list[int] = []
        self._jump_align: list[NDArray[np.float64]] = []

    # --- state ---------------------------------------------------------------------------

    @property
    def frame(self) -> int:
        """The graph frame shown now."""
        return self._frames[-1]

    @property
    def n_frames(self) -> int:
        return len(self._frames)

    @property
    def time(self) -> float:
        """Seconds of motion so far."""
        return (len(self._frames) - 1) / self.graph.fps

    @property
    def busy(self) -> bool:
        """True while a path given to ``take`` is being performed."""
        return bool(self._plan)

    @property
    def blending(self) -> bool:
        """True while the last transition's blend interval lasts."""
        return bool(self._jumps) and len(self._frames) - self._jumps[-1] < self._blend_frames

    def root_transform(self) -> tuple[float, NDArray[np.float64]]:
        """``(yaw, translation)`` placing the current clip's frames in the avatar's world."""
        return self._yaw, self._trans.copy()

    def recent(self, n: int) -> IntArray:
        """The last ``n`` graph frames shown (fewer at the start)."""
        return np.array(self._frames[-n:], dtype=np.int64)

    def history(self) -> tuple[IntArray, IntArray, IntArray]:
        """``(frames, jumps, edges)`` so far, as ``synthesize`` takes them."""
        return (
            np.array(self._frames, dtype=np.int64),
            np.array(self._jumps, dtype=np.int64),
            np.array(self._edges, dtype=np.int64),
        )

    # --- control -------------------------------------------------------------------------

    def take(self, frames: Sequence[int] | IntArray, edges: Sequence[int] | IntArray) -> None:
        """Perform a path: ``frames[0]`` must be the current frame; ``edges[i]`` is the
        transition into ``frames[i + 1]`` (-1 for playback, or for the same frame again:
        held still; ``JUMP`` for a direct blended jump to a frame of the component).
        Replaces any path in progress."""
        frames = [int(f) for f in frames]
        edges = [int(e) for e in edges]
        if not frames or frames[0] != self.frame:
            raise ValueError(f"a path must start at the avatar's frame {self.frame}")
        if len(edges) != len(frames) - 1:
            raise ValueError("a path needs one edge (or -1) per step")
        plays = self._next if self.anywhere else self._plays
        for f, g, e in zip(frames[:-1], frames[1:], edges, strict=True):
            ok = (
                bool(self.jump_costs.landing[g])
                if e == JUMP
                else (e == -1 and (g == f or (g == f + 1 and plays[f])))
                if e < 0
                else (
                    0 <= e < self.graph.n_edges
                    and self.graph.src[e] == f
                    and self.graph.dst[e] == g
                )
            )
            if not ok:
                raise ValueError(f"step {f} -> {g} (edge {e}) is not in the graph")
        self._plan = deque(zip(frames[1:], edges, strict=True))

    def _way_back(self) -> int:
        """Where the avatar goes when its clip ends outside the component: the frame
        nearest (graph distance) among those that show the same action (a label of the
        clip's) and play on for at least a second; without one, the component's
        nearest. (Sent always to the component's nearest, an exercise take's jumping
        jacks ran into a playground clip for a frame, and the next decision took them
        back.)"""
        g = self.graph
        targets = np.flatnonzero(g.in_scc & self.jump_costs.landing)
        clips = g.clips_of(self.clips)
        k = int(np.searchsorted(g.clip_start, self.frame, side="right")) - 1
        if clips[k].labels[self.frame - g.clip_start[k]] >= 0:  # a labelled action
            if self._actions is None:
                self._actions = action_keys(clips)
                clip = np.searchsorted(g.clip_start, np.arange(g.n_frames), side="right")
                room = g.clip_start[clip] - 1 - np.arange(g.n_frames)  # frames left to play
                self._lasting = self.jump_costs.landing & (room >= g.fps)
            assert self._actions is not None  # (a frame is labelled)
            same = (self._actions == self._actions[self.frame]) & self._lasting
            if same.any():
                targets = np.flatnonzero(same)
        d, _ = self.jump_costs(self.frame, targets)
        return int(targets[int(np.argmin(d))])

    def _align(self, e: int) -> NDArray[np.float64]:
        if e >= self.graph.n_edges:
            return self._jump_align[e - self.graph.n_edges]
        return self.graph.align[e].astype(np.float64)

    @property
    def n_jumps(self) -> int:
        """Direct blended jumps taken so far."""
        return len(self._jump_src)

    def jumps(self) -> tuple[IntArray, IntArray, NDArray[np.float64]]:
        """``(src, dst, align)`` of the direct jumps taken: history edge
        ``graph.n_edges + k`` is jump ``k`` (``synthesize``'s ``extra``)."""
        return (
            np.array(self._jump_src, dtype=np.int64),
            np.array(self._jump_dst, dtype=np.int64),
            np.array(self._jump_align, dtype=np.float64).reshape(-1, 4),
        )

    def clear(self) -> None:
        """Drop the path in progress; the avatar moves on by itself."""
        self._plan.clear()

    def step(self) -> int:
        """Move one frame; return the new frame."""
        if self._plan:
            g, e = self._plan.popleft()
        elif not self.graph.in_scc[self.frame]:  # reached by a jump: play on, or come back
            g, e = (self.frame + 1, -1) if self._next[self.frame] else (self._way_back(), JUMP)
        else:
            g, e = random_step(
                self.graph,
                self.frame,
                float(self._rng.random()),
                self._indptr,
                self._like,
                self._plays,
            )
        if e == JUMP:
            _, al = self.jump_costs(self.frame, np.array([g]))
            self._jump_src.append(self.frame)
            self._jump_dst.append(g)
            self._jump_align.append(al[0])
            e = self.graph.n_edges + len(self._jump_src) - 1
        if e >= 0:
            a = self._align(e)
            self._yaw, self._trans = compose(self._yaw, self._trans, float(a[0]), a[1:])
            self._jumps.append(len(self._frames))
            self._edges.append(e)
        self._frames.append(g)
        return g

    def advance(self, dt: float) -> int:
        """Let ``dt`` seconds pass; return how many frames were stepped."""
        if dt < 0:
            raise ValueError("dt must not be negative")
        self._clock += dt
        n = 0
        period = 1.0 / self.graph.fps
        while self._clock >= period - 1e-12:
            self._clock -= period
            self.step()
            n += 1
        return n

    def motion(self) -> Synthesis:
        """The motion so far, blended, with feet planted."""
        frames, jumps, edges = self.history()
        return synthesize(
            self.graph,
            self.clips,
            frames,
            jumps,
            edges,
            self.blend_settings,
            extra=self.jumps() if self._jump_src else None,
        )
