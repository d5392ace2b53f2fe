"""The running avatar, shared by every interface (choice, sketch, performance).

It stands on a frame of the motion graph and moves one frame per ``1 / fps`` seconds:
along a path it was told to take, or, with nothing to do, by eq. 1 (the random walk).
It keeps its history, so its motion, blended as in Lee et al. §4.1.1 with planted feet,
can be produced at any time, and it tracks the root transform that its transitions
have composed (fixed coordinates: the identity).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from .graph import MotionGraph, Synthesis, compose, random_step, synthesize
from .motion import Clip

__all__ = ["Avatar"]

IntArray = NDArray[np.int64]


class Avatar:
    """An avatar moving through ``graph``.

    Parameters
    ----------
    graph, clips : the motion graph and the library clips it was built from.
    start : first graph frame (default: drawn from the component with ``seed``).
    seed : seeds the probabilistic moves.
    blend : blend interval b in seconds; ``ik`` keeps planted feet in place.
    """

    def __init__(
        self,
        graph: MotionGraph,
        clips: Sequence[Clip],
        start: int | None = None,
        seed: int = 0,
        blend: float = 1.0,
        ik: bool = True,
    ) -> None:
        self.graph = graph
        self.clips = list(clips)
        self.blend = blend
        self.ik = ik
        self._rng = np.random.default_rng(seed)
        scc = np.flatnonzero(graph.in_scc)
        if scc.size == 0:
            raise ValueError("the graph has no component to move in")
        if start is None:
            start = int(self._rng.choice(scc))
        elif not (0 <= start < graph.n_frames and graph.in_scc[start]):
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
        self._blend_frames = max(1, round(blend * graph.fps))

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
        transition into ``frames[i + 1]`` (-1 for playback). Replaces any path in progress."""
        frames = [int(f) for f in frames]
        edges = [int(e) for e in edges]
        if not frames or frames[0] != self.frame:
            raise ValueError(f"a path must start at the avatar's frame {self.frame}")
        if len(edges) != len(frames) - 1:
            raise ValueError("a path needs one edge (or -1) per step")
        plays = self._plays
        for f, g, e in zip(frames[:-1], frames[1:], edges, strict=True):
            ok = (
                (e < 0 and g == f + 1 and plays[f])
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

    def clear(self) -> None:
        """Drop the path in progress; the avatar moves on by itself."""
        self._plan.clear()

    def step(self) -> int:
        """Move one frame; return the new frame."""
        if self._plan:
            g, e = self._plan.popleft()
        else:
            g, e = random_step(
                self.graph,
                self.frame,
                float(self._rng.random()),
                self._indptr,
                self._like,
                self._plays,
            )
        if e >= 0:
            a = self.graph.align[e].astype(np.float64)
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
            self.graph, self.clips, frames, jumps, edges, blend=self.blend, ik=self.ik
        )
