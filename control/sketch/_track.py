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
import heapq
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..clusters import HigherLayer
from ..dtw import dtw
from ..graph import (
    CapturedTerrain,
    FrameData,
    MotionGraph,
    Synthesis,
    captured_terrain,
    compose,
    foot_track,
    rotate_y,
    synthesize,
    yaw_of,
    yaw_q,
)
from ..motion import Clip, Motion, foot_points, qmul
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
    backed out of at most ``max_backtracks`` times; on terrain a foot in the air may dip
    ``foot_clearance`` metres below a block's top (marker noise)."""

    c: float = 0.5
    step_frames: int = 8
    spacing: float = 0.5
    reach: float = 0.5
    body_radius: float = 0.3
    max_expansions: int = 1000
    max_backtracks: int = 40
    #: terrain: how far (metres) a foot in the air may dip below the top of a block
    foot_clearance: float = 0.03
    #: first approach: cluster paths reached within ``lookahead`` seconds are candidates
    lookahead: float = 3.0
    #: first approach: root path and sketch are compared every ``dtw_spacing`` metres
    dtw_spacing: float = 0.1
    #: first approach: at most this many actions (an even spread) are compared per choice
    max_actions: int = 128


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
    nearly straight on) placed on the sketch's first point, facing along its first
    segment. On block terrain it is turned by a quarter turn and placed on the blocks'
    grid instead, as near that as the blocks allow; ``captured`` is the terrain the
    library was captured on (default: ``captured_terrain`` of the graph's clips).

    With ``layer`` (the graph's higher layer) each step takes the first approach: the
    best action of the avatar's cluster tree, performed to its end.
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
        self.sketch = np.asarray(sketch, dtype=np.float64).reshape(-1, 2)
        self.goals = np.zeros((0, 2))
        self._ahead = np.zeros(0)
        self._set_goals()
        self.goal = 0
        self.terrain = env.terrain if env is not None else None
        self.captured: CapturedTerrain | None = None
        if self.terrain is not None:
            self._setup_terrain(captured)
        if start is not None and not (0 <= start < graph.n_frames and graph.in_scc[start]):
            raise ValueError(f"start frame {start} is not in the graph's component")
        if self.terrain is not None:
            start, self._start = self._terrain_start(start)
        else:
            if start is None:
                start = self._default_start()
            self._start = start_map(self._root, self._heading, start, *self.sketch[:2])
        self._yaw, self._trans = self._start
        self.frames = [int(start)]
        self.jumps: list[int] = []
        self.edges: list[int] = []
        self.expansions: list[int] = []
        self.step_seconds: list[float] = []  # compute time of each planning step
        self.search_seconds = 0.0
        self.progress = 0.0  # first approach: metres of the sketch matched so far
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
        # the sketch every dtw_spacing metres from its start, with arc lengths (first
        # approach)
        self._fine = np.vstack((self.sketch[:1], resample(self.sketch, self.settings.dtw_spacing)))
        steps = np.linalg.norm(np.diff(self._fine, axis=0), axis=1)
        self._fine_s = np.concatenate(([0.0], np.cumsum(steps)))

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
        runs = np.cumsum(np.concatenate(([0], ~self._plays)))
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

    # --- block terrain ---------------------------------------------------------------------

    def _setup_terrain(self, captured: CapturedTerrain | None) -> None:
        g = self.graph
        terrain = self.terrain
        assert terrain is not None
        if g.options.coords != "terrain":
            raise ValueError(
                f"a terrain environment needs a terrain graph (coords 'terrain'), "
                f"not {g.options.coords!r}"
            )
        if abs(g.options.block - terrain.block) > 1e-6:
            raise ValueError(
                f"the environment's blocks are {terrain.block} m but the graph's are "
                f"{g.options.block} m"
            )
        by_name = {c.name: c for c in self.clips}
        chosen = [by_name[n] for n in g.clip_names]
        feet = foot_track(chosen)
        if captured is None:
            captured = captured_terrain(chosen, terrain.block, feet=feet)
        self.captured = captured
        self._rise = g.options.rise if g.options.rise > 0 else captured.rise
        self._toe = feet.toe
        self._ankle = feet.ankle
        self._support = feet.support
        self._states = feet.states
        self._level = captured.level_of(feet.toe[..., 1])

    def _on_blocks(self, f: int, yaw: float, trans: FloatArray) -> bool:
        """Frame ``f`` placed by ``(yaw, trans)`` fits the blocks: each planted foot on a
        block of the level it was captured on (plus the avatar's lift), and each foot in
        the air above the block under it."""
        terrain = self.terrain
        cap = self.captured
        assert terrain is not None and cap is not None
        c, sn = math.cos(yaw), math.sin(yaw)
        rise = self._rise
        lift = round(float(trans[1]) / rise)
        for foot in (0, 1):
            if self._states[f, foot]:
                sx, sz = self._support[f, foot]
                level = terrain.level_at_point(
                    c * sx + sn * sz + trans[0], -sn * sx + c * sz + trans[2]
                )
                if level != self._level[f, foot] + lift:
                    return False
                continue
            for pts, floor in ((self._toe, cap.toe_floor), (self._ankle, cap.ankle_floor)):
                px, py, pz = pts[f, foot]
                level = terrain.level_at_point(
                    c * px + sn * pz + trans[0], -sn * px + c * pz + trans[2]
                )
                if py + trans[1] < floor + level * rise - self.settings.foot_clearance:
                    return False
        return True

    def _terrain_start(self, start: int | None) -> tuple[int, tuple[float, FloatArray]]:
        """The first start frame (``start``, else by ``_start_ranking``) with both feet
        planted that fits the blocks when turned by the quarter turn nearest the sketch's
        direction and put on the grid (block centres on block centres) as near the
        sketch's first point as the blocks allow, lifted to the level under it."""
        terrain, cap = self.terrain, self.captured
        assert terrain is not None and cap is not None
        b = terrain.block
        at, toward = self.sketch[0], self.sketch[1]
        d = toward - at
        want = math.atan2(d[0], d[1])
        centre = np.array(terrain.first_centre)
        origin = np.array([cap.origin[0], 0.0, cap.origin[1]])
        candidates = [start] if start is not None else self._start_ranking()[:400]
        for f in candidates:
            f = int(f)
            if start is None and not self._states[f].all():
                continue
            yaw = 0.5 * math.pi * round((want - float(self._heading[f])) / (0.5 * math.pi))
            o = rotate_y(origin, yaw)
            r = rotate_y(self._root[f], yaw)
            k = np.round((at - (r[[0, 2]] - o[[0, 2]] + centre)) / b)
            tries = sorted(
                (k + np.array([i, j]) for i in (-1, 0, 1) for j in (-1, 0, 1)),
                key=lambda kk: float(np.linalg.norm(centre + kk * b - o[[0, 2]] + r[[0, 2]] - at)),
            )
            for kk in tries:
                xz = centre + kk * b - o[[0, 2]]
                trans = np.array([xz[0], 0.0, xz[1]])
                planted = np.flatnonzero(self._states[f])
                if planted.size:
                    foot = int(planted[0])
                    sx, sz = self._support[f, foot]
                    p = rotate_y(np.array([sx, 0.0, sz]), yaw) + trans
                    level = terrain.level_at_point(float(p[0]), float(p[2]))
                    trans[1] = (level - int(self._level[f, foot])) * self._rise
                if self._on_blocks(f, yaw, trans):
                    return f, (yaw, trans)
        raise ValueError(
            "no start frame fits the blocks at the sketch's first point "
            f"({at[0]:.2f}, {at[1]:.2f}); move the start onto a block"
        )

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
        if self.layer is not None:
            if self.done:
                return 0
            n = self._plan_action()
            self.stuck = n == 0
            return n
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
                if self.terrain is not None and not self._on_blocks(h, yaw2, trans2):
                    continue
                score, goal2 = self._score(x2, z2, a2, goal)
                nodes.append((h, yaw2, trans2, depth + 1, i, e, goal2))
                heapq.heappush(heap, (score, len(nodes) - 1))
        self.expansions.append(expanded)
        self.step_seconds.append(time.perf_counter() - t0)
        self.search_seconds += self.step_seconds[-1]
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

    def _actions(self) -> list[int]:
        """The first approach's candidates: nodes of the avatar's cluster tree first
        reached within the look-ahead that have no child within it (cluster paths)."""
        assert self.layer is not None
        tree = self.layer.forest.tree(self.frame)
        t = (tree.arrival + tree.root_frame - self.frame) / self.graph.fps
        _, leaves = tree.subtree(t <= self.settings.lookahead)
        return [int(x) for x in leaves if x != 0]

    def _plan_action(self) -> int:
        """The first approach: choose the action whose root path is nearest the sketch
        ahead by DTW (against the part of the sketch ahead as long as the root path),
        plus the sketch left beyond that part; commit it."""
        assert self.layer is not None
        t0 = time.perf_counter()
        s = self.settings
        g = self.graph
        bound = math.floor(s.lookahead * g.fps + 1e-9)
        total = float(self._fine_s[-1])
        best: tuple[float, Any, float] | None = None
        actions = self._actions()
        if len(actions) > s.max_actions:  # an even spread of them
            pick = np.linspace(0, len(actions) - 1, s.max_actions).round().astype(int)
            actions = [actions[i] for i in np.unique(pick)]
        tried = 0
        for node in actions:
            pm = self.layer.motion_to(self.frame, node, bound)
            if pm is None or pm.frames.size < 2:
                continue
            tried += 1
            ground, _ = ground_path(
                self._root, self._heading, self._align, pm.frames, pm.edges, self._yaw, self._trans
            )
            if self.env is not None and self.env.clearance(ground).min() < s.body_radius:
                continue
            q = np.vstack((ground[:1], resample(ground, s.dtw_spacing)))
            length = float(np.linalg.norm(np.diff(ground, axis=0), axis=1).sum())
            # the part of the sketch it covers: up to the point nearest its end (no
            # further on than its own length and a metre)
            end = self._nearest_along(ground[-1], self.progress, self.progress + length + 1.0)
            ahead = self._sketch_between(self.progress, end, q.shape[0])
            cost = dtw(q, ahead) / math.sqrt(q.shape[0]) + (total - end)
            if best is None or cost < best[0]:
                best = (cost, pm, end)
        self.expansions.append(tried)
        self.step_seconds.append(time.perf_counter() - t0)
        self.search_seconds += self.step_seconds[-1]
        if best is None:
            return 0
        _, pm, end = best
        n0 = len(self.frames)
        for i, e in enumerate(pm.edges):
            if e >= 0:
                al = self._align[e]
                self._yaw, self._trans = compose(self._yaw, self._trans, float(al[0]), al[1:])
                self.jumps.append(n0 + i)
                self.edges.append(int(e))
        self.frames.extend(int(f) for f in pm.frames[1:])
        # progress: that part; its goals are reached when the avatar ends within twice
        # ``reach`` of the sketch
        self.progress = max(self.progress, end)
        x, z, a = self.position()
        if np.hypot(*(self._sketch_between(end, end, 1)[0] - (x, z))) <= 2.0 * s.reach:
            goal_s = total - self._ahead  # arc length of each goal
            reached = int(np.searchsorted(goal_s, self.progress + s.reach, side="right"))
            self.goal = max(self.goal, reached)
        self.goal = max(self.goal, self._score(x, z, a, self.goal)[1])
        return pm.frames.size - 1

    def _nearest_along(self, p: FloatArray, s0: float, s1: float) -> float:
        """Arc length of the sketch point nearest ``p`` between arc lengths ``s0``, ``s1``
        (every ``dtw_spacing`` metres)."""
        lo, hi = np.searchsorted(self._fine_s, (s0, s1), side="right")
        lo = max(int(lo) - 1, 0)
        pts = self._fine[lo : max(int(hi), lo + 1)]
        k = int(np.argmin(np.hypot(pts[:, 0] - p[0], pts[:, 1] - p[1])))
        return max(s0, float(self._fine_s[lo + k]))

    def _sketch_between(self, s0: float, s1: float, n: int) -> FloatArray:
        """``n`` points evenly spaced along the sketch from arc length ``s0`` to ``s1``."""
        at = np.linspace(s0, s1, max(n, 2))
        return np.stack([np.interp(at, self._fine_s, self._fine[:, k]) for k in range(2)], axis=1)

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
        """How the synthesized, placed motion ``syn`` stands on the blocks: at planted
        frames, the toe's height above the top of the block under the foot (error:
        mean |e|, 95th percentile, max |e|; and the planted frames off by more than half
        a block), and the deepest a foot in the air goes below a block's top."""
        terrain, cap = self.terrain, self.captured
        if terrain is None or cap is None:
            raise ValueError("not on block terrain")
        ankle, toe = foot_points(syn.motion)
        mid = 0.5 * (ankle[..., [0, 2]] + toe[..., [0, 2]])
        top = terrain.level_at(mid.reshape(-1, 2)).reshape(mid.shape[:2]) * self._rise
        err = toe[..., 1] - cap.toe_floor - top
        planted = err[syn.states]
        tops = terrain.level_at(toe[..., [0, 2]].reshape(-1, 2)).reshape(toe.shape[:2])
        swing = (toe[..., 1] - cap.toe_floor - tops * self._rise)[~syn.states]
        a = np.abs(planted)
        return {
            "planted_frames": int(a.size),
            "foot_height_error_mean_m": round(float(a.mean()), 4) if a.size else None,
            "foot_height_error_p95_m": round(float(np.percentile(a, 95)), 4) if a.size else None,
            "foot_height_error_max_m": round(float(a.max()), 4) if a.size else None,
            "planted_off_block": int((a > 0.5 * self._rise).sum()),
            "swing_deepest_below_top_m": round(float(-min(0.0, swing.min())), 4)
            if swing.size
            else 0.0,
            "rise_m": round(self._rise, 4),
        }

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
            anchor="source" if self.terrain is not None else "output",
            max_offset=0.45 if self.terrain is not None else 0.2,
            blend=blend if blend is not None else 0.3 if self.terrain is not None else 1.0,
        )
        yaw, trans = self._start_map()
        m = syn.motion
        q = m.quats.copy()
        q[:, 0] = qmul(yaw_q(yaw), q[:, 0])
        placed = Motion(m.skeleton, rotate_y(m.root_pos, yaw) + trans, q, m.fps, "sketch", "graph")
        return dataclasses.replace(syn, motion=placed)
