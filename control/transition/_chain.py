"""Chaining named actions (Peng et al. §5): the game-facing API and motion assembly.

An action is a clip, a frame range of a clip, or a label (the first labelled stretch of
that action in any clip). ``Chainer.chain`` plays the actions in order; between two, the
transition comes from a candidate path of the cluster transition graph stitched greedily
(§5.1-5.3), or, when no path exists, from the Bezier fallback (§5.4). The pieces are
placed one after another in the world (relative coordinates: each piece's heading and
floor position continue the previous one) and every junction is blended by displacement
mapping over ``blend`` seconds (as in the motion graph).

``ChainPlayer`` is the per-frame API for a game loop: a request is queued;
``interrupt=True`` clears the queue and transitions from where the avatar is now.
"""

from __future__ import annotations

import re
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..graph import (
    GraphOptions,
    frame_features,
    graph_sigma,
    hermite,
    pair_distances,
    root_scales,
    rotate_y,
    select_clips,
    yaw_of,
    yaw_q,
)
from ..motion import Clip, Motion, qconj, qexp, qlog, qmul
from ._bezier import average_quats, bezier_quats, greedy_walk, interpolation_frames
from ._cluster import two_pass_clusters
from ._parametric import Blend, ParametricAction
from ._runtime import choose_path, nearest_cluster, stitch_path, transition_point
from ._tgraph import build_transition_graph, candidate_paths

__all__ = ["Action", "ChainPlayer", "ChainResult", "Chainer"]

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]

#: the parametric actions' blends a chainer keeps (the latest): an action queued longer
#: than this many requests ago can no longer be played
KEEP_BLENDS = 1024


@dataclass(frozen=True)
class Action:
    """Library frames ``[start, stop)`` (end to end over the chainer's clips) and a name;
    for a parametric action (``REF@X,Y,Z``) the frames of its blend (numbered past the
    library's: ``Chainer.n_library``) and the answered request."""

    name: str
    start: int
    stop: int
    blend: Blend | None = None


@dataclass(frozen=True, eq=False)
class ChainResult:
    """The chained motion; ``sources`` (T,) library frame per output frame (-1 for
    interpolated frames, -2 for a parametric action's blended ones); ``pieces`` the
    (kind, first output frame) of every piece."""

    motion: Motion
    sources: IntArray
    pieces: list[tuple[str, int]]
    bezier: int
    #: the parametric actions' answered requests, by action name
    blends: tuple[tuple[str, Blend], ...] = ()
    #: (T,) the frame played at each output frame: as ``sources``, but a blend's frames
    #: by their number (``Action.start`` + the blend's frame)
    played: IntArray | None = None


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
        directed: bool = True,
        example_cost: float = 0.5,
    ) -> None:
        if fallback not in ("bezier", "linear"):
            raise ValueError("fallback must be 'bezier' or 'linear'")
        self.fallback = fallback
        #: a parametric action's examples: ``find_examples``'s ``max_cost``
        self.example_cost = example_cost
        chosen, _ = select_clips(list(clips))
        self.clips = chosen
        self.fps = chosen[0].motion.fps
        self.feat = frame_features(chosen, "relative")
        self.sigma = graph_sigma(self.feat, self.fps, GraphOptions(coords="relative"))
        self.nu = nu
        self.clusters = two_pass_clusters(self.feat, radius * self.sigma, nu)
        self.graph = build_transition_graph(self.feat, self.clusters, directed=directed, nu=nu)
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
        self.n_library = int(self.root.shape[0])
        self._models: dict[tuple[int, int, str], ParametricAction] = {}
        # blends' frames: (first frame number, root (m, 3), quats (m, J, 4), library proxy)
        self._blends: list[tuple[int, FloatArray, FloatArray, IntArray]] = []
        self._next = self.n_library + 1  # a gap: a blend never continues a library clip

    # --- actions ---------------------------------------------------------------------

    def action(self, spec: str, target: Sequence[float] | None = None) -> Action:
        """``CLIP``, ``CLIP:FROM-TO`` (seconds) or ``label:NAME``; a parametric action
        ``REF@[EFFECTOR=]X,Y,Z`` (or ``REF`` with ``target``): the examples of the action
        ``REF`` blended so that ``EFFECTOR`` (a joint role, default ``right_wrist`` at the
        action's apex; ``root``: where it ends, on the floor, ``Y`` ignored) is at ``(X,
        Y, Z)`` metres in the avatar's frame where the action begins (y up, z its forward,
        x its left); ``REF@turn=DEGREES``: the blend that turns the avatar by ``DEGREES``
        (to its left when positive) by the action's end."""
        num = r"([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)"
        m = re.fullmatch(rf"(.+)@(?:([a-z_]+)=)?{num},{num},{num}", spec)
        turn = re.fullmatch(rf"(.+)@turn={num}", spec)
        effector = "right_wrist"
        if m is not None:
            spec, effector = m.group(1), m.group(2) or effector
            target = [float(m.group(k)) for k in (3, 4, 5)]
        elif turn is not None:
            spec, effector, target = turn.group(1), "turn", [float(turn.group(2)), 0.0, 0.0]
        if target is None:
            return self._plain_action(spec)
        return self.parametric(self._plain_action(spec), target, effector)

    def parametric(
        self, reference: Action, target: Sequence[float], effector: str = "right_wrist"
    ) -> Action:
        """The blend of ``reference``'s examples that puts ``effector`` at ``target``
        (``ParametricAction``; its examples are found once per reference and effector)."""
        key = (reference.start, reference.stop, effector)
        if key not in self._models:
            self._models[key] = ParametricAction(
                self.feat,
                self.root,
                self.quats,
                self.skeleton,
                self.fps,
                (reference.start, reference.stop),
                effector=effector,
                key="end" if effector in ("root", "turn") else "apex",
                nu=self.nu,
                max_cost=self.example_cost,
            )
        model = self._models[key]
        blend = model.request(np.asarray(target, dtype=np.float64))
        first = self._next
        proxy = model.aligned[int(np.argmax(blend.weights))]
        self._blends.append((first, blend.motion.root_pos, blend.motion.quats, proxy))
        del self._blends[:-KEEP_BLENDS]  # a long game loop: bounded memory
        self._next = first + proxy.size + 1
        where = f"{target[0]:g}" if effector == "turn" else ",".join(f"{x:g}" for x in target)
        return Action(f"{reference.name}@{effector}={where}", first, first + proxy.size, blend)

    def _frame(self, f: int) -> tuple[FloatArray, FloatArray]:
        """Root position and rotations of frame ``f`` (a library frame or a blend's)."""
        if f < self.n_library:
            return self.root[f], self.quats[f]
        first, root, quats, _ = self._blend_of(f)
        return root[f - first], quats[f - first]

    def _lib(self, f: int) -> int:
        """``f``, or for a blend's frame the library frame it stands in for (its heaviest
        example's, aligned): what transitions into and out of the blend are found by."""
        if f < self.n_library:
            return f
        first, _, _, proxy = self._blend_of(f)
        return int(proxy[f - first])

    def _blend_of(self, f: int) -> tuple[int, FloatArray, FloatArray, IntArray]:
        for b in reversed(self._blends):
            if b[0] <= f < b[0] + b[3].size:
                return b
        raise ValueError(f"frame {f} is neither a library frame nor a blend's")

    def _plain_action(self, spec: str) -> Action:
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
        a = nearest_cluster(self.feat, self.clusters, self._lib(last), self.nu)
        b = nearest_cluster(self.feat, self.clusters, self._lib(action.start), self.nu)
        path = choose_path(self.paths, a, b, self.rng)
        body = list(range(action.start, action.stop))
        if path is None:
            walk = greedy_walk(self.feat, self.clusters, a, b, self.nu)
            inner = walk[1:-1] or walk
            half = max(1, len(inner) // 2)
            c = self.clusters.centres
            c1 = average_quats(self.quats[c[inner[:half]]])
            c2 = average_quats(self.quats[c[inner[half:] or inner[:half]]])
            d, _ = pair_distances(
                self.feat,
                np.array([self._lib(last)]),
                np.array([self._lib(action.start)]),
                self.nu,
            )
            n = interpolation_frames(float(d[0]), self.delta)
            q_last, q_first = self._frame(last)[1], self._frame(action.start)[1]
            control = np.stack((q_last, c1, c2, q_first))
            if self.fallback == "linear":  # the baseline: slerp straight to the target
                control = control[[0, 3]]
            return body, bezier_quats(control, n + 2)[1:-1]
        here = self._lib(last)
        seq = (
            stitch_path(self.feat, self.graph, [here], path, nu=self.nu)
            if path.size > 1
            else [here]
        )
        tail = np.array(seq[-10:], dtype=np.int64)
        # enter within the first 25 frames, and within the first third of a short action
        # (entered near its end, a requested action would hardly be seen)
        head = np.array(
            [self._lib(f) for f in body[: min(25, max(1, len(body) // 3))]], dtype=np.int64
        )
        i, j, _ = transition_point(self.feat, tail, head, self.nu)
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
        motion, played = self._assemble(items)
        sources = np.where(played >= self.n_library, -2, played)  # a blend's frames: -2
        blends = tuple((a.name, a.blend) for a in acts if a.blend is not None)
        return ChainResult(motion, sources, pieces, n_bezier, blends, played)

    # --- assembly --------------------------------------------------------------------

    def _assemble(self, items: list[int | FloatArray]) -> tuple[Motion, IntArray]:
        placer = _Placer(self)
        out = [placer.push(item) for item in items]
        root = np.array([o[0] for o in out])
        quats = np.array([o[1] for o in out])
        sources = np.array([o[2] for o in out], dtype=np.int64)
        motion = Motion(self.skeleton, root, quats, self.fps, name="chain", source="transition")
        return motion, sources


class _Placer:
    """Places frames one at a time: library frames continue their clip; a new piece is
    turned and moved so that it continues the avatar's heading and floor position, and
    the pose difference at the junction fades over the blend interval (displacement
    mapping against what was shown, so a junction inside a blend starts from the
    blended pose); interpolated poses keep the root where it is."""

    def __init__(self, chainer: Chainer) -> None:
        self.ch = chainer
        self.yaw = 0.0
        self.trans = np.zeros(3)
        self.prev_src: int | None = None
        self.root: FloatArray | None = None
        self.quats: FloatArray | None = None
        self.e0: FloatArray | None = None
        self.p0 = 0.0
        self.k = 0

    def push(self, item: int | FloatArray) -> tuple[FloatArray, FloatArray, int]:
        ch = self.ch
        if isinstance(item, (int, np.integer)):
            f = int(item)
            continuing = self.prev_src is not None and abs(f - self.prev_src) == 1
            f_root, f_quats = ch._frame(f)
            if not continuing and self.quats is not None and self.root is not None:
                self.yaw = float(yaw_of(self.quats[0])) - float(yaw_of(f_quats[0]))
                p = rotate_y(f_root, self.yaw)
                self.trans = np.array([self.root[0] - p[0], 0.0, self.root[2] - p[2]])
                q_new = f_quats.copy()
                q_new[0] = qmul(yaw_q(self.yaw), f_quats[0])
                self.e0 = qlog(qmul(self.quats, qconj(q_new)))
                self.p0 = float(self.root[1] - (p[1] + self.trans[1]))
                self.k = 0
            root = rotate_y(f_root, self.yaw) + self.trans
            quats = f_quats.copy()
            quats[0] = qmul(yaw_q(self.yaw), f_quats[0])
            if self.e0 is not None:
                self.k += 1
                if self.k >= ch.blend:
                    self.e0 = None
                else:
                    kk = np.array([float(self.k)])
                    quats = qmul(
                        qexp(hermite(self.e0, np.zeros_like(self.e0), kk, ch.blend)[0]), quats
                    )
                    root = root + np.array(
                        [
                            0.0,
                            float(hermite(np.array(self.p0), np.array(0.0), kk, ch.blend)[0]),
                            0.0,
                        ]
                    )
            self.prev_src = f
            src = f
        else:
            pose = np.asarray(item)
            assert self.quats is not None and self.root is not None
            quats = pose.copy()
            tilt = qmul(yaw_q(-float(yaw_of(pose[0]))), pose[0])
            quats[0] = qmul(yaw_q(float(yaw_of(self.quats[0]))), tilt)
            root = self.root.copy()
            self.prev_src = None
            self.e0 = None
            src = -1
        self.root, self.quats = root, quats
        return root, quats, src


class ChainPlayer:
    """The per-frame API for a game loop.

    ``request(action)`` queues an action; ``request(action, interrupt=True)`` drops the
    queue and the rest of what is playing, so the avatar turns towards the new action from
    where it is (the dodge example). ``next()`` returns the next frame's root position
    ``(3,)``, local rotations ``(J, 4)`` and library frame (-1 for an interpolated pose,
    -2 for a blended one); with nothing left to do the avatar holds its last pose.
    ``request(action, target=(x, y, z))`` asks for a parametric action (``Chainer.action``).
    """

    def __init__(self, chainer: Chainer) -> None:
        self.ch = chainer
        self._placer = _Placer(chainer)
        self._queue: deque[Action] = deque()
        self._plan: deque[int | FloatArray] = deque()
        self._last_src: int | None = None
        self._last: tuple[FloatArray, FloatArray, int] | None = None

    @property
    def idle(self) -> bool:
        return not self._plan and not self._queue

    def request(
        self,
        action: str | Action,
        interrupt: bool = False,
        target: Sequence[float] | None = None,
    ) -> None:
        if isinstance(action, Action):
            act = action if target is None else self.ch.parametric(action, target)
        else:
            act = self.ch.action(action, target)
        if interrupt:
            self._queue.clear()
            self._plan.clear()
        self._queue.append(act)

    def next(self) -> tuple[FloatArray, FloatArray, int]:
        if not self._plan and self._queue:
            act = self._queue.popleft()
            if self._last_src is None:
                self._plan.extend(range(act.start, act.stop))
            else:
                frames, poses = self.ch._transition(self._last_src, act)
                if poses is not None:
                    self._plan.extend(list(poses))
                self._plan.extend(frames)
        if not self._plan:
            if self._last is None:
                raise ValueError("nothing requested yet")
            return self._last
        root, quats, src = self._placer.push(self._plan.popleft())
        if src >= 0:
            self._last_src = src
        self._last = (root, quats, -2 if src >= self.ch.n_library else src)
        return self._last
