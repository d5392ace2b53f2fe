"""Following a sketched path by best-first search in the lower layer (Lee et al. §5.2,
the second approach, eq. 8).

The sketch is resampled into goal points ``spacing`` metres apart. Each step searches
paths of exactly ``step_frames`` frames from the avatar's frame (playback and
transitions, each transition moving the avatar by its rigid alignment), best first by

    E = ||p_g - p|| - c * u . (p_g - p) / ||p_g - p||          (eq. 8)

plus the length of sketch still ahead of the goal ``p_g`` (so that a path that reaches
a goal and goes on to the next ranks ahead of one that stops at it). ``p`` is the root
projected on the ground (the centre of mass's proxy), ``u`` the facing direction. A path
whose root comes closer than ``body_radius`` to an obstacle is rejected. The first
complete path popped is committed and the search starts again from its end: a fixed
number of frames per step, so the avatar moves at a constant rate, and the sketch may
grow between steps (``extend``) while it is still being drawn.
"""

from __future__ import annotations

import dataclasses
import heapq
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..graph import FrameData, MotionGraph, Synthesis, compose, rotate_y, synthesize, yaw_of
from ..graph._features import yaw_q
from ..motion import Clip, Motion, qmul
from ._files import Environment

__all__ = [
    "SketchSettings",
    "SketchTracker",
    "ground_path",
    "path_deviation",
    "resample",
    "start_map",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class SketchSettings:
    """``c`` weighs facing the goal against nearing it (metres; 0 drops the facing term);
    ``step_frames`` frames are committed per search; goals lie ``spacing`` metres apart
    and count as reached within ``reach``; ``body_radius`` metres are kept from
    obstacles; a search expands at most ``max_expansions`` partial paths; dead ends are
    backed out of at most ``max_backtracks`` times."""

    c: float = 0.5
    step_frames: int = 8
    spacing: float = 0.5
    reach: float = 0.5
    body_radius: float = 0.3
    max_expansions: int = 1000
    max_backtracks: int = 40


def resample(points: FloatArray, spacing: float) -> FloatArray:
    """Points ``spacing`` apart along a polyline ``(n, 2)``, the last point included."""
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    s = np.concatenate(([0.0], np.cumsum(seg)))
    n = max(1, math.ceil(s[-1] / spacing))
    at = np.linspace(0.0, s[-1], n + 1)[1:]
    return np.stack([np.interp(at, s, points[:, k]) for k in range(2)], axis=1)


def path_deviation(xz: FloatArray, sketch: FloatArray) -> FloatArray:
    """Distance ``(n,)`` of each ground point to the nearest point of the sketch."""
    a = sketch[:-1]
    ab = np.diff(sketch, axis=0)
    ap = xz[:, None, :] - a[None]
    t = np.clip((ap * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-12), 0.0, 1.0)
    return np.asarray(np.linalg.norm(ap - t[..., None] * ab, axis=-1).min(axis=1))


def ground_path(
    root: FloatArray,
    heading: FloatArray,
    align: FloatArray,
    frames: IntArray,
    edges: IntArray,
    yaw: float,
    trans: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Root on the ground ``(T, 2)`` and facing angles ``(T,)`` of a graph path
    (``edges[i]`` leads into ``frames[i + 1]``, -1 for playback) placed by the map
    ``p -> R_y(yaw) p + trans``."""
    out = np.empty((len(frames), 2))
    facing = np.empty(len(frames))
    for t, f in enumerate(frames):
        if t > 0 and edges[t - 1] >= 0:
            al = align[edges[t - 1]]
            yaw, trans = compose(yaw, trans, float(al[0]), al[1:])
        p = rotate_y(root[f], yaw) + trans
        out[t] = (p[0], p[2])
        facing[t] = yaw + heading[f]
    return out, facing


def start_map(
    root: FloatArray, heading: FloatArray, frame: int, at: FloatArray, toward: FloatArray
) -> tuple[float, FloatArray]:
    """The map ``(yaw, trans)`` that puts ``frame``'s root on the ground point ``at``,
    facing ``toward``."""
    d = np.asarray(toward, dtype=np.float64) - at
    yaw = math.atan2(d[0], d[1]) - float(heading[frame])  # facing (sin a, cos a)
    r = rotate_y(root[frame], yaw)
    return yaw, np.array([at[0] - r[0], 0.0, at[1] - r[2]])


class SketchTracker:
    """An avatar following a sketch; ``step()`` plans and commits ``step_frames`` frames.

    The avatar starts at ``start`` (default: the component frame whose motion heads most
    nearly straight on, drawn with ``seed`` among the best) placed on the sketch's first
    point, facing along its first segment.
    """

    def __init__(
        self,
        graph: MotionGraph,
        clips: Sequence[Clip],
        sketch: FloatArray,
        env: Environment | None = None,
        settings: SketchSettings | None = None,
        start: int | None = None,
    ) -> None:
        self.graph = graph
        self.clips = list(clips)
        self.settings = settings or SketchSettings()
        if self.settings.step_frames < 1 or not self.settings.spacing > 0:
            raise ValueError("step_frames must be at least 1 and spacing positive")
        self.env = env
        data = FrameData(graph, clips)
        self._root = data.root
        self._heading = yaw_of(data.quats[:, 0])
        self._plays = graph.plays_on()
        self._indptr = graph.indptr
        self._align = graph.align.astype(np.float64)
        self.sketch = np.asarray(sketch, dtype=np.float64).reshape(-1, 2)
        self.goals = np.zeros((0, 2))
        self._ahead = np.zeros(0)
        self._set_goals()
        self.goal = 0
        if start is None:
            start = self._default_start()
        if not (0 <= start < graph.n_frames and graph.in_scc[start]):
            raise ValueError(f"start frame {start} is not in the graph's component")
        self._yaw, self._trans = start_map(self._root, self._heading, start, *self.sketch[:2])
        self.frames = [int(start)]
        self.jumps: list[int] = []
        self.edges: list[int] = []
        self.expansions: list[int] = []
        self.search_seconds = 0.0
        self.stuck = False
        self.backtracks = 0
        # before each committed step: (frames, jumps, yaw, trans, goal) and the step ends
        # found to lead nowhere from there
        self._undo: list[tuple[tuple[int, int, float, FloatArray, int], set[int]]] = []
        self._banned: set[int] = set()
        self._best: tuple[int, list[int], list[int], list[int], float, FloatArray, int] | None
        self._best = None

    # --- the sketch ------------------------------------------------------------------------

    def _set_goals(self) -> None:
        self.goals = resample(self.sketch, self.settings.spacing)
        seg = np.linalg.norm(np.diff(np.vstack((self.goals, self.goals[-1:])), axis=0), axis=1)
        self._ahead = np.cumsum(seg[::-1])[::-1]  # sketch length beyond each goal

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
        """A component frame that walks straight on: over the next second of playback,
        forward motion nearest a walk's 1.3 m with the least sideways motion and turn."""
        g = self.graph
        n = max(1, round(g.fps))
        idx = np.flatnonzero(g.in_scc)
        idx = idx[idx + n < g.n_frames]
        runs = np.cumsum(np.concatenate(([0], ~self._plays)))
        idx = idx[runs[idx + n] == runs[idx]]
        if idx.size == 0:
            return int(np.flatnonzero(g.in_scc)[0])
        move = self._root[idx + n] - self._root[idx]
        h = self._heading[idx]
        forward = move[:, 0] * np.sin(h) + move[:, 2] * np.cos(h)
        side = move[:, 0] * np.cos(h) - move[:, 2] * np.sin(h)
        turn = np.angle(np.exp(1j * (self._heading[idx + n] - h)))
        cost = np.abs(forward - 1.3) + np.abs(side) + np.abs(turn)
        return int(idx[np.argmin(cost)])

    # --- state -----------------------------------------------------------------------------

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
        while not self.done:
            n = self._plan()
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

    def _plan(self) -> int:
        t0 = time.perf_counter()
        s = self.settings
        g = self.graph
        x, z, a = self.position()
        first, goal0 = self._score(x, z, a, self.goal)
        self.goal = goal0  # goals within reach where the avatar stands (a grown sketch)
        if self.done:
            return 0
        # nodes: (frame, yaw, trans, depth, parent, edge, goal)
        nodes: list[tuple[int, float, FloatArray, int, int, int, int]] = [
            (self.frame, self._yaw, self._trans, 0, -1, -1, goal0)
        ]
        heap = [(first, 0)]
        found = -1
        expanded = 0
        deepest = (0, 0.0, 0)  # (depth, -score, node): the fallback when the search runs out
        while heap and expanded < s.max_expansions:
            score, i = heapq.heappop(heap)
            f, yaw, trans, depth, _, _, goal = nodes[i]
            if depth == s.step_frames or goal >= len(self.goals):
                if f not in self._banned:
                    found = i
                    break
                continue
            deepest = max(deepest, (depth, -score, i))
            expanded += 1
            succ: list[tuple[int, int]] = []
            if self._plays[f] and g.in_scc[f + 1]:
                succ.append((f + 1, -1))
            for e in range(self._indptr[f], self._indptr[f + 1]):
                succ.append((int(g.dst[e]), e))
            for h, e in succ:
                if e >= 0:
                    al = self._align[e]
                    yaw2, trans2 = compose(yaw, trans, float(al[0]), al[1:])
                else:
                    yaw2, trans2 = yaw, trans
                x2, z2, a2 = self._ground(h, yaw2, trans2)
                if (
                    self.env is not None
                    and self.env.clearance(np.array([[x2, z2]]))[0] < s.body_radius
                ):
                    continue
                score, goal2 = self._score(x2, z2, a2, goal)
                nodes.append((h, yaw2, trans2, depth + 1, i, e, goal2))
                heapq.heappush(heap, (score, len(nodes) - 1))
        self.expansions.append(expanded)
        self.search_seconds += time.perf_counter() - t0
        if found < 0 and heap:
            found = deepest[2]  # out of expansions: the best of the longest partial paths
        if found <= 0:  # every way on collides (a local minimum of eq. 8)
            return 0
        self._undo.append(
            ((len(self.frames), len(self.jumps), self._yaw, self._trans, self.goal), self._banned)
        )
        self._banned = set()
        chain = []
        i = found
        while nodes[i][4] >= 0:
            chain.append(i)
            i = nodes[i][4]
        for i in reversed(chain):
            f, yaw, trans, _, _, e, goal = nodes[i]
            if e >= 0:
                self.jumps.append(len(self.frames))
                self.edges.append(e)
            self.frames.append(f)
        last = nodes[found]
        self._yaw, self._trans, self.goal = last[1], last[2], last[6]
        return len(chain)

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
        nearest obstacle (with an environment), and seconds of motion planned per second
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
        if self.env is not None:
            out["min_clearance_m"] = round(float(self.env.clearance(root).min()), 3)
            out["body_radius_m"] = self.settings.body_radius
        return out

    def _start_map(self) -> tuple[float, FloatArray]:
        return start_map(self._root, self._heading, self.frames[0], *self.sketch[:2])

    def motion(self) -> Synthesis:
        """The planned motion, blended, placed on the sketch."""
        syn = synthesize(
            self.graph,
            self.clips,
            np.array(self.frames),
            np.array(self.jumps, dtype=np.int64),
            np.array(self.edges, dtype=np.int64),
        )
        yaw, trans = self._start_map()
        m = syn.motion
        q = m.quats.copy()
        q[:, 0] = qmul(yaw_q(yaw), q[:, 0])
        placed = Motion(m.skeleton, rotate_y(m.root_pos, yaw) + trans, q, m.fps, "sketch", "graph")
        return dataclasses.replace(syn, motion=placed)
