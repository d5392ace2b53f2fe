"""Chaining named actions (Peng et al. §5): the game-facing API and motion assembly.

An action is a clip, a frame range of a clip, or a label (the first labelled stretch of
that action in any clip). ``Chainer.chain`` plays the actions in order; between two, the
transition comes from a candidate path of the cluster transition graph stitched greedily
(§5.1-5.3), or, when no path exists, from the Bezier fallback (§5.4). The pieces are
placed one after another in the world (relative coordinates: each piece's heading and
floor position continue the previous one) and every junction is blended by displacement
mapping over ``blend`` seconds (as in the motion graph).

Not built yet: the per-frame API for a game loop (queue, interruption).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..graph import GraphOptions, frame_features, pair_distances, select_clips
from ..graph._features import root_scales, rotate_y, yaw_of, yaw_q
from ..graph._graph import _sigma
from ..graph._synth import _hermite
from ..motion import Clip, Motion, qconj, qexp, qlog, qmul
from ._bezier import average_quats, bezier_quats, greedy_walk, interpolation_frames
from ._cluster import two_pass_clusters
from ._runtime import choose_path, nearest_cluster, stitch_path, transition_point
from ._tgraph import build_transition_graph, candidate_paths

__all__ = ["Action", "ChainResult", "Chainer"]

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Action:
    """Library frames ``[start, stop)`` (end to end over the chainer's clips) and a name."""

    name: str
    start: int
    stop: int


@dataclass(frozen=True, eq=False)
class ChainResult:
    """The chained motion; ``sources`` (T,) library frame per output frame (-1 for
    interpolated frames); ``pieces`` the (kind, first output frame) of every piece."""

    motion: Motion
    sources: IntArray
    pieces: list[tuple[str, int]]
    bezier: int


class Chainer:
    """Preprocessed library (§4) plus the run-time phase (§5)."""

    def __init__(
        self,
        clips: Sequence[Clip],
        radius: float = 10.0,
        k: int = 5,
        delta: float | None = None,
        blend: float = 0.5,
        seed: int = 0,
        nu: float = 0.01,
        fallback: str = "bezier",
    ) -> None:
        if fallback not in ("bezier", "linear"):
            raise ValueError("fallback must be 'bezier' or 'linear'")
        self.fallback = fallback
        chosen, _ = select_clips(list(clips))
        self.clips = chosen
        self.fps = chosen[0].motion.fps
        self.feat = frame_features(chosen, "relative")
        self.sigma = _sigma(self.feat, self.fps, GraphOptions(coords="relative"))
        self.nu = nu
        self.clusters = two_pass_clusters(self.feat, radius * self.sigma, nu)
        self.graph = build_transition_graph(self.feat, self.clusters)
        self.paths = candidate_paths(self.graph, k=k)
        self.delta = delta if delta is not None else self.sigma / 2.0
        self.blend = max(1, round(blend * self.fps))
        self.rng = np.random.default_rng(seed)
        scales = root_scales(chosen)
        self.root = np.concatenate(
            [c.motion.root_pos * s for c, s in zip(chosen, scales, strict=True)]
        )
        self.quats = np.concatenate([c.motion.quats for c in chosen])
        self.skeleton = chosen[0].motion.skeleton

    # --- actions ---------------------------------------------------------------------

    def action(self, spec: str) -> Action:
        """``CLIP``, ``CLIP:FROM-TO`` (seconds) or ``label:NAME``."""
        starts = self.feat.clip_start
        names = [c.name for c in self.clips]
        if spec.startswith("label:"):
            want = spec[6:]
            for i, c in enumerate(self.clips):
                idx = [j for j, n in enumerate(c.label_names) if n.lower() == want.lower()]
                if idx:
                    hit = np.flatnonzero(c.labels == idx[0])
                    run_end = hit[0] + int(np.argmax(np.diff(np.append(hit, -9)) != 1)) + 1
                    return Action(want, int(starts[i] + hit[0]), int(starts[i] + run_end))
            raise ValueError(f"no clip has the label {want!r}")
        m = re.fullmatch(r"([^:]+)(?::([\d.]+)-([\d.]+))?", spec)
        if not m or m.group(1) not in names:
            raise ValueError(f"unknown action {spec!r}: give CLIP, CLIP:FROM-TO (s) or label:NAME")
        i = names.index(m.group(1))
        a, b = int(starts[i]), int(starts[i + 1])
        if m.group(2):
            f0 = a + round(float(m.group(2)) * self.fps)
            f1 = a + round(float(m.group(3)) * self.fps)
            if not a <= f0 < f1 <= b:
                raise ValueError(
                    f"{spec}: the range is not inside the clip ({(b - a) / self.fps:.1f} s)"
                )
            a, b = f0, f1
        return Action(spec, a, b)

    # --- transitions -----------------------------------------------------------------

    def _transition(self, last: int, action: Action) -> tuple[list[int], FloatArray | None]:
        """Frames from ``last`` into ``action`` (library frames), or, with no path, the
        interpolated poses ``(n, J, 4)`` to put before the action's first frame."""
        a = nearest_cluster(self.feat, self.clusters, last, self.nu)
        b = nearest_cluster(self.feat, self.clusters, action.start, self.nu)
        path = choose_path(self.paths, a, b, self.rng)
        body = list(range(action.start, action.stop))
        if path is None:
            walk = greedy_walk(self.feat, self.clusters, a, b, self.nu)
            inner = walk[1:-1] or walk
            half = max(1, len(inner) // 2)
            c = self.clusters.centres
            c1 = average_quats(self.quats[c[inner[:half]]])
            c2 = average_quats(self.quats[c[inner[half:] or inner[:half]]])
            d, _ = pair_distances(self.feat, np.array([last]), np.array([action.start]), self.nu)
            n = interpolation_frames(float(d[0]), self.delta)
            control = np.stack((self.quats[last], c1, c2, self.quats[action.start]))
            if self.fallback == "linear":  # the baseline: slerp straight to the target
                control = control[[0, 3]]
            return body, bezier_quats(control, n + 2)[1:-1]
        seq = (
            stitch_path(self.feat, self.graph, [last], path, nu=self.nu)
            if path.size > 1
            else [last]
        )
        tail = np.array(seq[-10:], dtype=np.int64)
        i, j, _ = transition_point(self.feat, tail, np.array(body[:25]), self.nu)
        return seq[1 : len(seq) - tail.size + i + 1] + body[j:], None

    def chain(self, actions: Sequence[str | Action]) -> ChainResult:
        """The actions in order with synthesized transitions."""
        acts = [a if isinstance(a, Action) else self.action(a) for a in actions]
        if not acts:
            raise ValueError("no actions")
        items: list[int | FloatArray] = list(range(acts[0].start, acts[0].stop))
        pieces: list[tuple[str, int]] = [(acts[0].name, 0)]
        n_bezier = 0
        for act in acts[1:]:
            last = next(x for x in reversed(items) if isinstance(x, int))
            frames, poses = self._transition(int(last), act)
            if poses is not None:
                pieces.append(("bezier", len(items)))
                items.extend(list(poses))
                n_bezier += 1
            pieces.append((act.name, len(items)))
            items.extend(frames)
        motion, sources = self._assemble(items)
        return ChainResult(motion, sources, pieces, n_bezier)

    # --- assembly --------------------------------------------------------------------

    def _assemble(self, items: list[int | FloatArray]) -> tuple[Motion, IntArray]:
        n = len(items)
        root = np.zeros((n, 3))
        quats = np.zeros((n, self.quats.shape[1], 4))
        sources = np.full(n, -1, dtype=np.int64)
        yaw, trans = 0.0, np.zeros(3)
        junctions: list[int] = []  # output frames where a new piece starts
        prev_src: int | None = None
        for t, item in enumerate(items):
            if isinstance(item, (int, np.integer)):
                f = int(item)
                continuing = prev_src is not None and abs(f - prev_src) == 1
                if not continuing and t > 0:
                    # place this piece so that its first frame continues the output
                    y_src = float(yaw_of(self.quats[f, 0]))
                    y_out = float(yaw_of(quats[t - 1, 0]))
                    yaw = y_out - y_src
                    p = rotate_y(self.root[f], yaw)
                    trans = np.array([root[t - 1, 0] - p[0], 0.0, root[t - 1, 2] - p[2]])
                    junctions.append(t)
                root[t] = rotate_y(self.root[f], yaw) + trans
                quats[t] = self.quats[f]
                quats[t, 0] = qmul(yaw_q(yaw), self.quats[f, 0])
                sources[t] = f
                prev_src = f
            else:
                # interpolated pose: joints from the curve; the root keeps its place and
                # heading, its tilt follows the curve
                pose = np.asarray(item)
                quats[t] = pose
                y_out = float(yaw_of(quats[t - 1, 0]))
                tilt = qmul(yaw_q(-float(yaw_of(pose[0]))), pose[0])
                quats[t, 0] = qmul(yaw_q(y_out), tilt)
                root[t] = root[t - 1]
                prev_src = None
        self._blend_junctions(root, quats, junctions)
        motion = Motion(self.skeleton, root, quats, self.fps, name="chain", source="transition")
        return motion, sources

    def _blend_junctions(self, root: FloatArray, quats: FloatArray, junctions: list[int]) -> None:
        """Displacement-map each junction: the first frame of a piece takes the pose of
        the frame before it and the difference fades over the blend interval."""
        b = self.blend
        ends = [*junctions[1:], root.shape[0]]
        for t, stop in zip(junctions, ends, strict=True):
            end = min(t + b, stop)
            e0 = qlog(qmul(quats[t - 1], qconj(quats[t])))
            k = np.arange(0, end - t, dtype=np.float64)
            zero = np.zeros_like(e0)
            quats[t:end] = qmul(qexp(_hermite(e0, zero, k, b)), quats[t:end])
            p0 = root[t - 1] - root[t]
            p0[[0, 2]] = 0.0  # horizontal continuity comes from the placement
            root[t:end] += _hermite(p0, np.zeros(3), k, b)
