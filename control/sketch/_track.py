"""Following a sketched path (Lee et al. §5.2): by best-first search in the lower layer
(the second approach, eq. 8), or by choosing among the avatar's actions (the first).

The sketch is resampled into goal points ``spacing`` metres apart. Each step searches
paths of exactly ``step_frames`` frames from the avatar's frame (playback and
transitions, each transition moving the avatar by its rigid alignment), best first by

    E = ||p_g - p|| - c * u . (p_g - p) / ||p_g - p||          (eq. 8)

plus the length of sketch still ahead of the goal ``p_g`` (so that a path that reaches
a goal and goes on to the next ranks ahead of one that stops at it). ``p`` is the root
projected on the ground (the centre of mass's proxy), ``u`` the facing direction. A path
whose root comes closer than ``body_radius`` to an obstacle is rejected. On block
terrain (a terrain graph: quarter turns about block centres, whole-block shifts and
lifts) a path is also rejected where a planted foot would stand on a block of another
level than the one it was captured on (relative to the avatar's lift), or a foot in the
air would be inside a block. The first
complete path popped is committed and the search starts again from its end: a fixed
number of frames per step, so the avatar moves at a constant rate, and the sketch may
grow between steps (``extend``) while it is still being drawn.

The first approach (given a higher layer) chooses, at each step, the cluster path of
the avatar's cluster tree whose most probable motion's root path is nearest the sketch
ahead by DTW (the root path resampled every ``dtw_spacing`` metres against as much of
the sketch ahead as the path is long), plus the sketch length left beyond that part,
and performs that motion to its end.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..clusters import HigherLayer
from ..graph import (
    BlendSettings,
    CapturedTerrain,
    FrameData,
    MotionGraph,
    Synthesis,
    rotate_y,
    synthesize,
    yaw_of,
    yaw_q,
)
from ..motion import Clip, Motion, qmul
from ._actions import ActionPlanner
from ._blocks import BlockFit
from ._files import Environment
from ._ground import SketchSettings, ground_path, path_deviation, resample_polyline, start_map
from ._search import SearchTable, search_step

__all__ = ["SketchTracker"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


class SketchTracker:
    """An avatar following a sketch; ``step()`` plans and commits ``step_frames`` frames.

    The avatar starts at ``start`` (default: the component frame whose motion heads most
    nearly straight on) placed on the sketch's first point, facing along its first
    segment. On block terrain it is turned by a quarter turn and placed on the blocks'
    grid instead, as near that as the blocks allow; ``captured`` is the terrain the
    library was captured on (default: ``captured_terrain`` of the graph's clips).

    With ``layer`` (the graph's higher layer) each step takes the first approach: the
    best action of the avatar's cluster tree, performed to its end.

    ``place``: the start frame's map ``(yaw, translation)`` into the sketch's world, for an
    avatar already moving there (``Avatar.root_transform``: the live page's sketches),
    instead of the sketch's first point facing along its first segment (not on terrain).
    """

    def __init__(
        self,
        graph: MotionGraph,
        clips: Sequence[Clip],
        sketch: FloatArray,
        env: Environment | None = None,
        settings: SketchSettings | None = None,
        start: int | None = None,
        captured: CapturedTerrain | None = None,
        layer: HigherLayer | None = None,
        place: tuple[float, FloatArray] | None = None,
    ) -> None:
        self.graph = graph
        self.clips = list(clips)
        self.settings = settings or SketchSettings()
        if self.settings.step_frames < 1 or not self.settings.spacing > 0:
            raise ValueError("step_frames must be at least 1 and spacing positive")
        self.env = env
        self.layer = layer
        if layer is not None and layer.graph is not graph:
            raise ValueError("the higher layer must be built on the same graph")
        if layer is not None and env is not None and env.terrain is not None:
            raise ValueError("the first approach (actions) does not handle block terrain")
        data = FrameData(graph, clips)
        self._root = data.root
        self._heading = yaw_of(data.quats[:, 0])
        self._plays = graph.plays_on()
        self._indptr = graph.indptr
        self._align = graph.align.astype(np.float64)
        self._search_table: SearchTable | None = None  # made by the search's first step
        self.sketch = np.asarray(sketch, dtype=np.float64).reshape(-1, 2)
        self.goals = np.zeros((0, 2))
        self._ahead = np.zeros(0)
        #: the first approach's planner (with ``layer``), else the search of eq. 8
        self.actions = ActionPlanner(layer, self.settings) if layer is not None else None
        self._set_goals()
        self.goal = 0
        self.terrain = env.terrain if env is not None else None
        self.blocks = (
            BlockFit(graph, self.clips, self.terrain, self.settings, captured)
            if self.terrain is not None
            else None
        )
        start = self._place_start(start, place)
        self._yaw, self._trans = self._start
        self.frames = [start]
        self.jumps: list[int] = []
        self.edges: list[int] = []
        self.expansions: list[int] = []
        self.step_seconds: list[float] = []  # compute time of each planning step
        self.search_seconds = 0.0
        self.stuck = False
        self.backtracks = 0
        # before each committed step: (frames, jumps, yaw, trans, goal) and the step ends
        # found to lead nowhere from there
        self._undo: list[tuple[tuple[int, int, float, FloatArray, int], set[int]]] = []
        self._banned: set[int] = set()
        self._best: tuple[int, list[int], list[int], list[int], float, FloatArray, int] | None
        self._best = None

    def _place_start(self, start: int | None, place: tuple[float, FloatArray] | None) -> int:
        """The avatar's first frame, and where it stands (``_start``: the yaw and the
        translation into the sketch's world): on the blocks' grid on terrain, at
        ``place``, or by the sketch's first segment (from the best start frame when none
        is given)."""
        graph = self.graph
        if start is not None and not (0 <= start < graph.n_frames and graph.in_scc[start]):
            raise ValueError(f"start frame {start} is not in the graph's component")
        if place is not None and self.blocks is not None:
            raise ValueError("on block terrain the start is placed on the blocks' grid")
        if self.blocks is not None:
            start, self._start = self.blocks.start(
                start, self.sketch, self._root, self._heading, self._start_ranking
            )
        elif place is not None:
            if start is None:
                raise ValueError("a start placed in the sketch's world needs its start frame")
            self._start = (float(place[0]), np.asarray(place[1], dtype=np.float64))
        else:
            if start is None:
                start = self._default_start()
            self._start = start_map(self._root, self._heading, start, *self.sketch[:2])
        return int(start)

    # --- the sketch ------------------------------------------------------------------------

    def _set_goals(self) -> None:
        self.goals = resample_polyline(self.sketch, self.settings.spacing)
        seg = np.linalg.norm(np.diff(np.vstack((self.goals, self.goals[-1:])), axis=0), axis=1)
        self._ahead = np.cumsum(seg[::-1])[::-1]  # sketch length beyond each goal
        if self.actions is not None:
            self.actions.set_sketch(self.sketch)

    def extend(self, points: FloatArray) -> None:
        """Append newly drawn points to the sketch (the goals already reached stay so)."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        self.sketch = np.vstack((self.sketch, pts))
        keep = np.concatenate(([True], np.any(np.diff(self.sketch, axis=0) != 0, axis=1)))
        self.sketch = self.sketch[keep]
        reached = self.goals[: self.goal]
        self._set_goals()
        # goals are resampled from the start of the sketch: map progress by position
        if reached.size:
            self.goal = int(np.argmin(np.linalg.norm(self.goals - reached[-1], axis=1))) + 1

    def _default_start(self) -> int:
        return int(self._start_ranking()[0])

    def _start_ranking(self) -> IntArray:
        """Component frames, those that walk straight on first: over the next second of
        playback, forward motion nearest a walk's 1.3 m with the least sideways motion
        and turn."""
        g = self.graph
        n = max(1, round(g.fps))
        scc = np.flatnonzero(g.in_scc)
        idx = scc[scc + n < g.n_frames]
        runs = g.playback_runs()
        idx = idx[runs[idx + n] == runs[idx]]
        if idx.size == 0:
            return scc
        move = self._root[idx + n] - self._root[idx]
        h = self._heading[idx]
        forward = move[:, 0] * np.sin(h) + move[:, 2] * np.cos(h)
        side = move[:, 0] * np.cos(h) - move[:, 2] * np.sin(h)
        turn = np.angle(np.exp(1j * (self._heading[idx + n] - h)))
        cost = np.abs(forward - 1.3) + np.abs(side) + np.abs(turn)
        return np.asarray(idx[np.argsort(cost, kind="stable")], dtype=np.int64)

    # --- state -----------------------------------------------------------------------------

    @property
    def captured(self) -> CapturedTerrain | None:
        """On block terrain, the terrain the library was captured on."""
        return self.blocks.captured if self.blocks is not None else None

    @property
    def progress(self) -> float:
        """First approach: metres of the sketch matched so far (0 for the search)."""
        return self.actions.progress if self.actions is not None else 0.0

    @property
    def frame(self) -> int:
        return self.frames[-1]

    @property
    def done(self) -> bool:
        return self.goal >= len(self.goals) or self.stuck

    def _ground(self, f: int, yaw: float, trans: FloatArray) -> tuple[float, float, float]:
        """Root ``(x, z)`` and facing angle of frame ``f`` under the map ``(yaw, trans)``."""
        p = rotate_y(self._root[f], yaw) + trans
        return float(p[0]), float(p[2]), yaw + float(self._heading[f])

    def position(self) -> tuple[float, float, float]:
        return self._ground(self.frame, self._yaw, self._trans)

    # --- the search ------------------------------------------------------------------------

    def _score(self, x: float, z: float, facing: float, goal: int) -> tuple[float, int]:
        """Eq. 8 toward the first goal not yet reached (advancing ``goal`` past goals
        within reach), plus the sketch left beyond it."""
        s = self.settings
        while goal < len(self.goals):
            dx = self.goals[goal, 0] - x
            dz = self.goals[goal, 1] - z
            dist = math.hypot(dx, dz)
            if dist > s.reach:
                facing_term = (math.sin(facing) * dx + math.cos(facing) * dz) / dist
                return dist - s.c * facing_term + float(self._ahead[goal]), goal
            goal += 1
        return -1e9, goal  # everything reached

    def step(self) -> int:
        """Plan and commit one step; the number of frames added (0 when done or stuck).

        When every way on collides, the last steps are undone and planned again without
        the end that led into the corner (at most ``max_backtracks`` times in all)."""
        if self.actions is not None:
            if self.done:
                return 0
            n = self.actions.step(self)
            self.stuck = n == 0
            return n
        while not self.done:
            n = search_step(self)
            if n or self.done:
                return n
            if not self._undo or self.backtracks >= self.settings.max_backtracks:
                self.stuck = True
                if self._best is not None and (self._best[6], self._best[0]) > (
                    self.goal,
                    len(self.frames),
                ):
                    # give up where the avatar got furthest, not where backing out ended
                    _, self.frames, self.jumps, self.edges, self._yaw, self._trans, self.goal = (
                        self._best
                    )
                return 0
            if self._best is None or (self.goal, len(self.frames)) > (self._best[6], self._best[0]):
                self._best = (
                    len(self.frames),
                    list(self.frames),
                    list(self.jumps),
                    list(self.edges),
                    self._yaw,
                    self._trans,
                    self.goal,
                )
            # undo the last step; from there, no step may end on any frame it went through
            (nf, nj, yaw, trans, goal), banned = self._undo.pop()
            banned.update(self.frames[nf:])
            del self.frames[nf:], self.jumps[nj:], self.edges[nj:]
            self._yaw, self._trans, self.goal, self._banned = yaw, trans, goal, banned
            self.backtracks += 1
        return 0

    def run(self, max_seconds: float) -> None:
        """Step until the sketch is followed, the avatar is stuck, or ``max_seconds`` of
        motion are planned."""
        limit = round(max_seconds * self.graph.fps)
        while not self.done and len(self.frames) - 1 < limit:
            if self.step() == 0:
                break

    # --- results ---------------------------------------------------------------------------

    def root_path(self) -> FloatArray:
        """The planned root on the ground ``(T, 2)``, frame by frame."""
        yaw, trans = self._start_map()
        edges = np.full(len(self.frames) - 1, -1, dtype=np.int64)
        edges[np.array(self.jumps, dtype=np.int64) - 1] = self.edges
        return ground_path(
            self._root, self._heading, self._align, np.array(self.frames), edges, yaw, trans
        )[0]

    def summary(self, compute_seconds: float) -> dict[str, Any]:
        """How the sketch was followed: reached its end or not, stuck, backtracks,
        seconds of motion, the root's mean and max deviation from the sketch, the
        nearest obstacle (with obstacles or walls), and seconds of motion planned per second
        of ``compute_seconds``."""
        root = self.root_path()
        dev = path_deviation(root, self.sketch)
        seconds = (len(self.frames) - 1) / self.graph.fps
        out: dict[str, Any] = {
            "followed": bool(self.goal >= len(self.goals)),
            "stuck": self.stuck,
            "backtracks": self.backtracks,
            "motion_seconds": round(seconds, 2),
            "deviation_mean_m": round(float(dev.mean()), 3),
            "deviation_max_m": round(float(dev.max()), 3),
            "realtime_factor": round(seconds / compute_seconds, 1) if compute_seconds > 0 else None,
        }
        if self.env is not None and (self.env.obstacles or self.env.bounds is not None):
            out["min_clearance_m"] = round(float(self.env.clearance(root).min()), 3)
            out["body_radius_m"] = self.settings.body_radius
        return out

    def terrain_report(self, syn: Synthesis) -> dict[str, Any]:
        """How the synthesized, placed motion ``syn`` stands on the blocks
        (``BlockFit.report``)."""
        if self.blocks is None:
            raise ValueError("not on block terrain")
        return self.blocks.report(syn)

    def _start_map(self) -> tuple[float, FloatArray]:
        return self._start

    def motion(self, blend: float | None = None) -> Synthesis:
        """The planned motion, blended over ``blend`` seconds, placed on the sketch. By
        default, on block terrain the blends are short (0.3 s: transitions come often and
        each blend moves the body off the blocks' grid), else 1 s; on terrain planted
        feet are held where the checked path put them."""
        syn = synthesize(
            self.graph,
            self.clips,
            np.array(self.frames),
            np.array(self.jumps, dtype=np.int64),
            np.array(self.edges, dtype=np.int64),
            BlendSettings(
                seconds=blend if blend is not None else 0.3 if self.terrain is not None else 1.0,
                anchor="source" if self.terrain is not None else "output",
                max_offset=0.45 if self.terrain is not None else 0.2,
            ),
        )
        yaw, trans = self._start_map()
        m = syn.motion
        q = m.quats.copy()
        q[:, 0] = qmul(yaw_q(yaw), q[:, 0])
        placed = Motion(m.skeleton, rotate_y(m.root_pos, yaw) + trans, q, m.fps, "sketch", "graph")
        return dataclasses.replace(syn, motion=placed)
