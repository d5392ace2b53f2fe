"""Motion from a path through the graph: alignment, blended transitions and planted feet.

Lee et al. §4.1.1. After a transition ``i -> j`` the frames from ``j`` on are displaced so
that pose and velocity at the virtual frame ``j - 1`` equal what was shown at ``i`` (and
``i - 1``); the displacement (per joint a rotation vector, for the root also a
translation) decays to zero over ``b`` frames along a cubic Hermite curve. It is measured
against the frames actually shown, so a transition inside a blend starts from the
blended motion: that is the overlap buffer.

Feet: over a blend the root's height is set so that the lowest foot point is as high as
in the source frame (a blend between a squat and a stance keeps its feet on the floor).
A foot in contact is kept where it touched down (or where it was at the jump; with
``feet="floor"`` brought to the height the source frame gives it over the blend
interval, the root's height set before the leg IK, so that it stays down however a
blend carries the body) and then follows only the source clip's own foot motion; when
it lifts, the correction fades over the swing. This covers the four cases of the paper:
a contact that runs into a blend keeps the trajectory before the transition (case 1),
one that starts inside a blend is fixed where it lands (cases 2 and 3: the start side),
and one that spans the whole blend (case 4) stays planted and the leg absorbs the
difference; when the leg cannot reach, the foot slips and ``Synthesis.unreachable``
counts those frames.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..motion import (
    Clip,
    FloatArray,
    Motion,
    Skeleton,
    forward_kinematics,
    qconj,
    qexp,
    qlog,
    qmul,
)
from ._blending import BlendSettings
from ._features import root_scales, rotate_y, yaw_q
from ._graph import MotionGraph
from ._ik import knee_hinge, leg_chain, solve_leg
from ._quality import lowest_foot
from ._turns import follow_turns, own_turns

__all__ = ["FrameData", "Synthesis", "compose", "synthesize"]

IntArray = NDArray[np.int64]


@dataclass(frozen=True, eq=False)
class Synthesis:
    """A synthesized motion and where each frame came from.

    Attributes
    ----------
    motion : the output, on the skeleton of the graph's first clip.
    frames : (T,) graph frame shown at each output frame.
    jumps : (M,) output frames where a transition lands.
    edges : (M,) the transitions taken.
    states : (T, 2) foot contacts (from the source frames).
    blended : (T,) bool, frames changed by a blend.
    unreachable : frames where a planted foot was out of the leg's reach.
    """

    motion: Motion
    frames: IntArray
    jumps: IntArray
    edges: IntArray
    states: NDArray[np.bool_]
    blended: NDArray[np.bool_]
    unreachable: int


class FrameData:
    """The graph's clips end to end: ``root`` (n, 3) positions (retargeted to the first
    clip's body), ``quats`` (n, J, 4), ``states`` (n, 2) contacts, and the ``skeleton``."""

    def __init__(self, graph: MotionGraph, clips: Sequence[Clip]) -> None:
        chosen = graph.clips_of(clips)
        sizes = np.array([c.motion.n_frames for c in chosen])
        if not np.array_equal(np.concatenate(([0], np.cumsum(sizes))), graph.clip_start):
            raise ValueError("the library's clips do not match the graph (frame counts differ)")
        self.skeleton = chosen[0].motion.skeleton
        scales = root_scales(chosen)
        self.root = np.concatenate(
            [c.motion.root_pos * s for c, s in zip(chosen, scales, strict=True)]
        )
        self.quats = np.concatenate([c.motion.quats for c in chosen])
        self.states = np.concatenate([c.contacts.states for c in chosen])


def compose(
    yaw: float, trans: FloatArray, a_yaw: float, a_trans: FloatArray
) -> tuple[float, FloatArray]:
    """``T o A`` for the rigid maps ``p -> R_y(yaw) p + trans`` of the graph's alignments."""
    return yaw + a_yaw, rotate_y(a_trans, yaw) + trans


def segment_maps(
    align: ArrayLike, yaw: float = 0.0, trans: FloatArray | None = None
) -> tuple[FloatArray, FloatArray]:
    """The maps ``(yaws (M+1,), trans (M+1, 3))`` of a path's segments: the first is
    ``(yaw, trans)``, each next one composed with the alignment ``align[m]`` (yaw, then
    translation) of the transition that begins it."""
    align = np.asarray(align, dtype=np.float64).reshape(-1, 4)
    yaws = np.empty(len(align) + 1)
    out = np.zeros((len(align) + 1, 3))
    yaws[0] = yaw
    if trans is not None:
        out[0] = trans
    for m, a in enumerate(align):
        yaws[m + 1], out[m + 1] = compose(float(yaws[m]), out[m], float(a[0]), a[1:])
    return yaws, out


def hermite(e0: FloatArray, v0: FloatArray, k: FloatArray, b: int) -> FloatArray:
    """Displacement at frames ``k = 1..`` after the jump: value ``e0`` and slope ``v0``
    (per frame) at ``k = 0``, zero value and slope at ``k = b``."""
    u = np.clip(k / b, 0.0, 1.0)
    h = 2.0 * u**3 - 3.0 * u**2 + 1.0
    g = k * (1.0 - u) ** 2
    shape = (-1,) + (1,) * e0.ndim
    return e0 * h.reshape(shape) + v0 * g.reshape(shape)


def synthesize(
    graph: MotionGraph,
    clips: Sequence[Clip],
    frames: IntArray,
    jumps: IntArray,
    edges: IntArray,
    settings: BlendSettings | None = None,
    extra: tuple[IntArray, IntArray, FloatArray] | None = None,
) -> Synthesis:
    """Turn a path through the graph into motion.

    Parameters
    ----------
    graph, clips : the graph and the library clips it was built from.
    frames : (T,) graph frames; consecutive ones play on, hold still or follow a transition.
    jumps : (M,) increasing output frames ``t`` where ``frames[t]`` follows transition
        ``edges[m]`` from ``frames[t - 1]``.
    settings : how transitions are blended and planted feet kept (``BlendSettings``;
        by default its defaults: a 1 s blend, feet held with leg IK).
    extra : ``(src, dst, align)`` of direct jumps that are not graph transitions (the
        vision interface's blended jumps, ``control.Avatar.jump``): edge ``e >=
        graph.n_edges`` is jump ``e - graph.n_edges``, blended like any transition.
    """
    st = settings or BlendSettings()
    data = FrameData(graph, clips)
    frames, jumps, edges, align_of = _checked_path(graph, frames, jumps, edges, extra)
    b = st.frames(graph.fps)

    src_p, src_q, out_p, out_q, blended, v1 = _place_and_blend(
        data, graph, frames, jumps, edges, align_of, b
    )
    if st.turn_limit is not None and jumps.size:
        own = own_turns(src_q, jumps, v1[1])
        out_q = follow_turns(out_q, own, st.turn_limit / graph.fps)
    states = data.states[frames]
    unreachable = 0
    # the root's height over blends: before the leg IK with feet="floor", else after it
    lift = st.ik and blended.any()
    if lift and st.feet == "floor":
        out_p = _lifted(data.skeleton, graph.fps, src_p, src_q, out_p, out_q, blended)
    if st.ik and jumps.size:
        source = (src_p, src_q, v1, states)
        out_q, unreachable = _plant_feet(data.skeleton, graph.fps, out_p, out_q, source, jumps, st)
    if lift and st.feet == "held":  # (planted feet move up or down with the body)
        out_p = _lifted(data.skeleton, graph.fps, src_p, src_q, out_p, out_q, blended)
    motion = Motion(data.skeleton, out_p, out_q, graph.fps, name="walk", source="graph")
    return Synthesis(motion, frames, jumps, edges, states, blended, unreachable)


def _checked_path(
    graph: MotionGraph,
    frames: ArrayLike,
    jumps: ArrayLike,
    edges: ArrayLike,
    extra: tuple[IntArray, IntArray, FloatArray] | None,
) -> tuple[IntArray, IntArray, IntArray, FloatArray]:
    """The path's arrays, checked (``_check_path``), and each edge's alignment."""
    frames = np.asarray(frames, dtype=np.int64)
    jumps = np.asarray(jumps, dtype=np.int64)
    edges = np.asarray(edges, dtype=np.int64)
    src_of, dst_of, align_of = _edge_tables(graph, extra)
    _check_path(graph, frames, jumps, edges, src_of, dst_of)
    return frames, jumps, edges, align_of


def _place_and_blend(
    data: FrameData,
    graph: MotionGraph,
    frames: IntArray,
    jumps: IntArray,
    edges: IntArray,
    align_of: FloatArray,
    b: int,
) -> tuple[
    FloatArray, FloatArray, FloatArray, FloatArray, NDArray[np.bool_], tuple[FloatArray, FloatArray]
]:
    """Each segment of the path placed by its transitions' alignments (``src``), and
    the output with each transition's jump in pose and root displaced away over ``b``
    frames (``out``); the frames blended, and each new segment's virtual predecessor."""
    n_out = frames.size
    n_seg = jumps.size + 1
    seg_yaw, seg_trans = segment_maps(align_of[edges])
    seg = np.searchsorted(jumps, np.arange(n_out), side="right")

    def aligned(g: IntArray, s: IntArray) -> tuple[FloatArray, FloatArray]:
        p = rotate_y(data.root[g], seg_yaw[s]) + seg_trans[s]
        q = data.quats[g].copy()
        q[:, 0] = qmul(yaw_q(seg_yaw[s]), q[:, 0])
        return p, q

    src_p, src_q = aligned(frames, seg)
    out_p, out_q = src_p.copy(), src_q.copy()
    blended = np.zeros(n_out, dtype=bool)
    # virtual predecessors (frames j-1, j-2 of each new segment, in its alignment)
    j = frames[jumps]
    starts = graph.clip_start[np.searchsorted(graph.clip_start, j, side="right") - 1]
    pre1 = j - 1
    pre2 = np.where(j - 2 >= starts, j - 2, j - 1)
    v1_p, v1_q = aligned(pre1, np.arange(1, n_seg))
    v2_p, v2_q = aligned(pre2, np.arange(1, n_seg))
    for m, t in enumerate(jumps):
        if t < 1:
            continue
        end = min(t + b, jumps[m + 1] if m + 1 < jumps.size else n_out)
        o2 = t - 2 if t >= 2 else t - 1
        d0 = qmul(out_q[t - 1], qconj(v1_q[m]))
        e0 = qlog(d0)
        # the offset's rate: the rotation between the last two offsets (not the
        # difference of their rotation vectors, which is near 2 pi where the offset
        # nears a half turn and its vector flips: a wild swing of the limb)
        rate = qlog(qmul(d0, qconj(qmul(out_q[o2], qconj(v2_q[m])))))
        p0 = out_p[t - 1] - v1_p[m]
        pp = out_p[o2] - v2_p[m]
        k = np.arange(1, end - t + 1, dtype=np.float64)
        out_q[t:end] = qmul(qexp(hermite(e0, rate, k, b)), src_q[t:end])
        out_p[t:end] = src_p[t:end] + hermite(p0, p0 - pp, k, b)
        blended[t:end] = True

    return src_p, src_q, out_p, out_q, blended, (v1_p, v1_q)


def _edge_tables(
    graph: MotionGraph, extra: tuple[IntArray, IntArray, FloatArray] | None
) -> tuple[IntArray, IntArray, FloatArray]:
    """``(src, dst, align)`` of the graph's transitions, then of ``extra``'s jumps."""
    src, dst = graph.src.astype(np.int64), graph.dst.astype(np.int64)
    align = graph.align.astype(np.float64)
    if extra is None:
        return src, dst, align
    e_src, e_dst, e_align = (np.asarray(x) for x in extra)
    e_align = e_align.astype(np.float64).reshape(-1, 4)
    if not (e_src.shape == e_dst.shape == (e_align.shape[0],)):
        raise ValueError("extra jumps need one src, dst and (yaw, dx, dy, dz) each")
    if e_src.size and (
        min(e_src.min(), e_dst.min()) < 0 or max(e_src.max(), e_dst.max()) >= graph.n_frames
    ):
        raise ValueError(f"extra jumps' frames must lie in 0..{graph.n_frames - 1}")
    if not np.isfinite(e_align).all():
        raise ValueError("extra jumps' alignments must be finite")
    return (
        np.concatenate((src, e_src.astype(np.int64))),
        np.concatenate((dst, e_dst.astype(np.int64))),
        np.concatenate((align, e_align)),
    )


def _lifted(
    skeleton: Skeleton,
    fps: float,
    src_p: FloatArray,
    src_q: FloatArray,
    out_p: FloatArray,
    out_q: FloatArray,
    rows: NDArray[np.bool_],
) -> FloatArray:
    """The output's root positions with, at the frames of ``rows``, its height set so
    that its lowest foot point is as high as the source frame's: blending the root's
    height between a squat and a stance would otherwise lift both feet off the floor for
    the whole blend."""
    src = lowest_foot(Motion(skeleton, src_p[rows], src_q[rows], fps))
    out = lowest_foot(Motion(skeleton, out_p[rows], out_q[rows], fps))
    lifted = out_p.copy()
    lifted[rows, 1] += src - out
    return lifted


def _check_path(
    graph: MotionGraph,
    frames: IntArray,
    jumps: IntArray,
    edges: IntArray,
    src: IntArray,
    dst: IntArray,
) -> None:
    n = graph.n_frames
    if frames.ndim != 1 or frames.size == 0:
        raise ValueError("frames must be a non-empty 1-D array")
    if frames.min() < 0 or frames.max() >= n:
        raise ValueError(f"frames must lie in 0..{n - 1}")
    if jumps.shape != edges.shape or jumps.ndim != 1:
        raise ValueError("jumps and edges must be 1-D arrays of the same length")
    if jumps.size:
        if jumps.min() < 1 or jumps.max() >= frames.size or np.any(np.diff(jumps) <= 0):
            raise ValueError("jumps must be increasing output frames in 1..len(frames) - 1")
        if edges.min() < 0 or edges.max() >= src.size:
            raise ValueError(f"edges must lie in 0..{src.size - 1}")
        bad = (src[edges] != frames[jumps - 1]) | (dst[edges] != frames[jumps])
        if bad.any():
            t = int(jumps[np.argmax(bad)])
            raise ValueError(f"output frame {t}: edge does not lead from frame {frames[t - 1]}")
    played = np.ones(frames.size - 1, dtype=bool)
    played[jumps - 1] = False
    last = np.zeros(n, dtype=bool)
    last[graph.clip_start[1:] - 1] = True
    step = np.diff(frames)
    # a frame plays on to the next, or is held (shown again: a performer standing still)
    wrong = played & (((step != 1) | last[frames[:-1]]) & (step != 0))
    if wrong.any():
        t = int(np.argmax(wrong)) + 1
        raise ValueError(
            f"output frame {t}: frame {frames[t]} neither plays on, is held nor follows a jump"
        )


def _foot_targets(
    out_pts: FloatArray,
    src_pts: FloatArray,
    pred_pts: FloatArray,
    contact: NDArray[np.bool_],
    fade: int,
    max_offset: float,
    from_source: bool = False,
    floor: int = 0,
) -> FloatArray:
    """Where each frame's ankle should be ((T, 3)): planted during contact, fading after.

    A contact run is anchored where the foot touched down in the output, or with
    ``from_source`` where the source put it; with ``floor`` > 0 its height goes to the
    source's over that many frames (a foot the blend still holds in the air comes down:
    at once, the leg would jerk at the junction). The correction is at most
    ``max_offset`` metres: beyond that the foot slides along with the body rather than
    stretch or fold the leg.
    """
    n = out_pts.shape[0]
    target = out_pts.copy()
    inc = src_pts - pred_pts
    inc[0] = 0.0
    csum = np.cumsum(inc, axis=0)
    c = contact.astype(np.int8)
    edges = np.diff(np.concatenate(([0], c, [0])))
    starts = np.flatnonzero(edges == 1)
    ends = np.flatnonzero(edges == -1)  # exclusive
    for s, e in zip(starts, ends, strict=True):
        anchor = src_pts[s] if from_source else out_pts[s]
        r = anchor + csum[s:e] - csum[s] - out_pts[s:e]
        if floor:  # to the source's height (on the floor), eased in over ``floor`` frames
            x = np.minimum(1.0, np.arange(1, e - s + 1) / floor)
            r[:, 1] += (src_pts[s, 1] - anchor[1]) * (3.0 * x**2 - 2.0 * x**3)
        size = np.linalg.norm(r, axis=1, keepdims=True)
        r *= np.minimum(1.0, max_offset / np.maximum(size, 1e-12))
        target[s:e] = out_pts[s:e] + r
        residual = target[e - 1] - out_pts[e - 1]
        nxt = starts[starts > s]
        stop = min(e + fade, n, int(nxt[0]) if nxt.size else n)
        if stop > e:
            x = (np.arange(e, stop) - e + 1) / (fade + 1)
            w = 1.0 - (3.0 * x**2 - 2.0 * x**3)
            target[e:stop] = out_pts[e:stop] + residual * w[:, None]
    return target


def _plant_feet(
    skeleton: Skeleton,
    fps: float,
    out_p: FloatArray,
    out_q: FloatArray,
    source: tuple[FloatArray, FloatArray, tuple[FloatArray, FloatArray], NDArray[np.bool_]],
    jumps: IntArray,
    st: BlendSettings,
) -> tuple[FloatArray, int]:
    """The output's quaternions with each planted foot kept by leg IK (``_foot_targets``)
    and the frames where a leg could not reach; ``source``: the source frames' root
    positions and quaternions, the virtual frames before the jumps and the feet's
    contact states."""
    src_p, src_q, virtual, states = source
    fade, max_offset, from_source = round(st.fade * fps), st.max_offset, st.anchor == "source"
    floor = st.frames(fps) if st.feet == "floor" else 0
    pose = forward_kinematics(Motion(skeleton, out_p, out_q, fps))
    src_pose = forward_kinematics(Motion(skeleton, src_p, src_q, fps))
    v_pose = forward_kinematics(Motion(skeleton, virtual[0], virtual[1], fps))
    out_q = out_q.copy()
    unreachable = 0
    for foot, side in enumerate(("left", "right")):
        chain = leg_chain(skeleton, side)
        ankle = chain[2]
        src_pts = src_pose.positions[:, ankle]
        pred = np.concatenate((src_pts[:1], src_pts[:-1]))
        pred[jumps] = v_pose.positions[:, ankle]
        out_pts = pose.positions[:, ankle]
        target = _foot_targets(
            out_pts, src_pts, pred, states[:, foot], fade, max_offset, from_source, floor
        )
        todo = np.flatnonzero(np.linalg.norm(target - out_pts, axis=1) > 1e-5)
        if todo.size == 0:
            continue
        hinge = knee_hinge(pose.positions, pose.orientations, chain)
        new = solve_leg(
            skeleton,
            pose.positions[todo],
            pose.orientations[todo],
            chain,
            target[todo],
            hinge,
            todo,
            st.ik_turn_rate / fps,
        )
        out_q[todo[:, None], np.array(chain)[None, :]] = new
        hip = pose.positions[todo, chain[0]]
        leg = np.linalg.norm(pose.positions[todo, chain[1]] - hip, axis=1) + np.linalg.norm(
            pose.positions[todo, ankle] - pose.positions[todo, chain[1]], axis=1
        )
        unreachable += int(np.sum(np.linalg.norm(target[todo] - hip, axis=1) > leg))
    return out_q, unreachable
