"""Blended transitions, the overlap buffer and planted feet."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from control.graph import (
    BlendSettings,
    GraphOptions,
    MotionGraph,
    build_graph,
    follow_turns,
    foot_slide,
    knee_hinge,
    leg_chain,
    random_walk,
    sole_speed,
    solve_leg,
    synthesize,
)
from control.graph._ik import SOFT_REACH, limit_turns, two_bone_ik
from control.motion import Library, Motion, forward_kinematics, qconj, qlog, qmul, qrot


@pytest.fixture(scope="module")
def graph(medium_lib: Library) -> MotionGraph:
    return build_graph(medium_lib.clips, GraphOptions(coords="relative"))


def _step(q: np.ndarray, t: int) -> np.ndarray:
    """Per-joint rotation vectors (radians) from frame t - 1 to t."""
    return qlog(qmul(q[t], qconj(q[t - 1])))


def _accel_deg(q0: np.ndarray, q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Per-joint second difference (degrees) of three consecutive poses."""
    a = qlog(qmul(q2, qconj(q1))) - qlog(qmul(q1, qconj(q0)))
    return np.degrees(np.linalg.norm(a, axis=-1))


def _edges_with_room(g: MotionGraph, before: int, after: int) -> np.ndarray:
    clip_of = np.searchsorted(g.clip_start, np.arange(g.n_frames), side="right") - 1
    ok = []
    for e in range(g.n_edges):
        s, d = int(g.src[e]), int(g.dst[e])
        if s - before >= g.clip_start[clip_of[s]] and d + after < g.clip_start[clip_of[d] + 1]:
            ok.append(e)
    return np.array(ok)


def _path(g: MotionGraph, edges: list[int], run: int) -> tuple[np.ndarray, np.ndarray]:
    """Play ``run`` frames up to each edge's source, take it, and so on."""
    frames = list(range(int(g.src[edges[0]]) - run, int(g.src[edges[0]]) + 1))
    jumps = []
    for k, e in enumerate(edges):
        jumps.append(len(frames))
        nxt = int(g.src[edges[k + 1]]) if k + 1 < len(edges) else int(g.dst[e]) + 40
        frames += list(range(int(g.dst[e]), nxt + 1))
    return np.array(frames), np.array(jumps)


def test_blend_matches_pose_and_velocity_then_fades(
    graph: MotionGraph, medium_lib: Library
) -> None:
    e = int(_edges_with_room(graph, 5, 40)[np.argmax(graph.dist[_edges_with_room(graph, 5, 40)])])
    frames, jumps = _path(graph, [e], 5)
    b = 15
    syn = synthesize(
        graph, medium_lib.clips, frames, jumps, np.array([e]), BlendSettings(seconds=1.0, ik=False)
    )
    t = int(jumps[0])
    src_q = np.concatenate([c.motion.quats for c in medium_lib.clips])
    d = int(graph.dst[e])
    out = syn.motion.quats
    # pose and velocity carry on across the jump: the second difference there is the
    # target's own (frames d-2, d-1, d), not the raw discontinuity
    shown = _accel_deg(out[t - 2], out[t - 1], out[t])
    own = _accel_deg(src_q[d - 2], src_q[d - 1], src_q[d])
    naive = _accel_deg(out[t - 2], out[t - 1], src_q[d])
    assert np.max(np.abs(shown[1:] - own[1:])) < 1.5
    assert np.max(naive[1:]) > np.max(shown[1:]) + 3.0  # there was a discontinuity to hide
    # root: position continuous (step like the source's own), and back to the source after b
    step = np.linalg.norm(syn.motion.root_pos[t] - syn.motion.root_pos[t - 1])
    assert step < 0.15
    assert syn.blended[t : t + b].all() and not syn.blended[t + b :].any()
    tail = syn.motion.quats[t + b :, 1:]
    np.testing.assert_allclose(
        np.abs(np.sum(tail * src_q[frames[t + b :], 1:], axis=-1)), 1.0, atol=1e-9
    )


def test_transition_inside_a_blend_starts_from_the_shown_motion(
    graph: MotionGraph, medium_lib: Library
) -> None:
    room = _edges_with_room(graph, 5, 40)
    # two transitions, the second 2-6 frames after landing from the first (inside its blend)
    pairs = [
        (int(e1), int(e2))
        for e1 in room
        for e2 in room
        if 1 <= graph.src[e2] - graph.dst[e1] <= 5
        and graph.locate(int(graph.src[e2]))[0] == graph.locate(int(graph.dst[e1]))[0]
    ]
    assert pairs, "the test graph should have transitions close enough to overlap"
    first, second = pairs[0]
    frames = np.concatenate(
        (
            np.arange(graph.src[first] - 5, graph.src[first] + 1),
            np.arange(graph.dst[first], graph.src[second] + 1),
            np.arange(graph.dst[second], graph.dst[second] + 30),
        )
    )
    t2 = 6 + int(graph.src[second] - graph.dst[first]) + 1
    jumps = np.array([6, t2])
    syn = synthesize(
        graph,
        medium_lib.clips,
        frames,
        jumps,
        np.array([first, second]),
        BlendSettings(seconds=1.0, ik=False),
    )
    src_q = np.concatenate([c.motion.quats for c in medium_lib.clips])
    d = int(graph.dst[second])
    out = syn.motion.quats
    shown = _accel_deg(out[t2 - 2], out[t2 - 1], out[t2])
    own = _accel_deg(src_q[d - 2], src_q[d - 1], src_q[d])
    assert np.max(np.abs(shown[1:] - own[1:])) < 2.5
    naive = _accel_deg(out[t2 - 2], out[t2 - 1], src_q[d])
    assert np.max(naive[1:]) > np.max(shown[1:]) + 3.0
    assert syn.blended[6:t2].all()  # it did start inside the first blend
    assert syn.blended[t2 : t2 + 15].all()


def test_the_knee_bends_smoothly_as_a_target_passes_out_of_reach() -> None:
    """A target moving steadily from 90% to 110% of the leg's length: the knee
    straightens gradually (the exact solution's angle has an infinite slope at full
    extension: the last millimetres snapped the knee straight, 3.5 degrees for a step
    of 0.9 mm)."""
    n = 200
    hip = np.zeros((n, 3))
    knee = np.tile([0.0, -0.45, 0.05], (n, 1))
    ankle = np.tile([0.0, -0.9, 0.0], (n, 1))
    full = np.linalg.norm(knee[0] - hip[0]) + np.linalg.norm(ankle[0] - knee[0])
    target = np.zeros((n, 3))
    target[:, 1] = -np.linspace(0.9, 1.1, n) * full
    dk, _ = two_bone_ik(hip, knee, ankle, target, np.tile([1.0, 0.0, 0.0], (n, 1)))
    w = qrot(dk, ankle - knee)
    angle = np.degrees(
        np.arccos(
            np.sum((hip - knee) * w, axis=1)
            / np.linalg.norm(hip - knee, axis=1)
            / np.linalg.norm(w, axis=1)
        )
    )
    assert np.max(np.abs(np.diff(angle))) < 2.0
    assert angle[-1] > 170.0 and angle[0] < 155.0


def _held_leg(lib: Library, n: int) -> tuple:
    """The first clip's motion, its FK, its left leg's chain, and its first frame's joint
    positions and orientations held for ``n`` frames."""
    m = lib.clips[0].motion
    pose = forward_kinematics(m)
    p = np.repeat(pose.positions[:1], n, axis=0)
    o = np.repeat(pose.orientations[:1], n, axis=0)
    return m, pose, leg_chain(m.skeleton, "left"), p, o


def test_a_target_near_the_far_side_of_the_hip_does_not_flip_the_thigh(
    medium_lib: Library,
) -> None:
    """Targets passing close to the point opposite the ankle, through the hip: the
    shortest swing there is near a half turn, its axis turning round within a few
    frames (a jump blended into a deep squat turned a thigh 170 degrees in one frame).
    The correction fades out beyond ``SWING_LIMIT``: the thigh never turns more than a
    few degrees a frame; a small correction still reaches its target."""
    m, pose, chain, p, o = _held_leg(medium_lib, 101)
    hip, _, ankle = chain
    n = 101
    d = p[0, ankle] - p[0, hip]
    e1 = np.cross(d, [0.0, 0.0, 1.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(d, e1)
    e2 /= np.linalg.norm(e2)
    way = -d / np.linalg.norm(d) + 0.05 * e1 + np.linspace(-0.5, 0.5, n)[:, None] * e2
    target = p[:, hip] + np.linalg.norm(d) * way / np.linalg.norm(way, axis=1, keepdims=True)
    target[:10] = p[:10, ankle] + 0.03 * e1  # a small correction first
    hinge = knee_hinge(pose.positions, pose.orientations, chain)
    new = solve_leg(m.skeleton, p, o, chain, target, hinge)
    q = np.repeat(m.quats[:1], n, axis=0)
    q[:, list(chain)] = new
    after = forward_kinematics(Motion(m.skeleton, np.repeat(m.root_pos[:1], n, axis=0), q, m.fps))
    # within 3 mm of a target 3 cm off (the soft reach: this leg is nearly straight)
    np.testing.assert_allclose(after.positions[:10, ankle], target[:10], atol=3e-3)
    thigh = after.orientations[:, hip]
    turn = np.degrees(
        2.0 * np.arccos(np.clip(np.abs(np.sum(thigh[1:] * thigh[:-1], axis=1)), 0, 1))
    )
    assert turn[10:].max() < 5.0, turn.max()


def _turns(q: np.ndarray) -> np.ndarray:
    """Degrees each rotation of ``q`` ``(N, 4)`` turns from the one before."""
    return np.degrees(2.0 * np.arccos(np.clip(np.abs(np.sum(q[1:] * q[:-1], axis=1)), 0, 1)))


def test_the_leg_correction_turns_at_most_a_step_a_frame(medium_lib: Library) -> None:
    """A nearly straight leg whose planted ankle the blend carries 5 cm a frame towards
    the hip (a pelvis dragged away from its foot): solved frame by frame the knee must
    fold tens of degrees in one frame; with the frames given, the hip's and the knee's
    corrections turn at most ``step`` a frame, and a run of frames starts and ends
    within ``step`` of no correction (the foot slides instead). Frames outside the run
    are not corrected."""
    m, pose, chain, p, o = _held_leg(medium_lib, 12)
    hip, _, ankle = chain
    n = 12
    up = p[0, hip] - p[0, ankle]
    up /= np.linalg.norm(up)
    target = p[:, ankle] + np.minimum(np.arange(n), 6)[:, None] * 0.05 * up
    hinge = knee_hinge(pose.positions, pose.orientations, chain)
    frames = np.concatenate((np.arange(10, 16), np.arange(30, 36)))  # two runs
    free = solve_leg(m.skeleton, p, o, chain, target, hinge)
    held = solve_leg(m.skeleton, p, o, chain, target, hinge, frames, 10.0)
    rest = np.repeat(m.quats[:1, list(chain)], n, axis=0)

    def corrections(new: np.ndarray, j: int) -> np.ndarray:
        # the correction's change in the joint's local rotation, identity for none
        return qmul(new[:, j], qconj(rest[:, j]))

    knee_free = _turns(corrections(free, 1))
    assert knee_free[:5].max() > 20.0  # frame by frame, the knee folds 22 degrees at once
    for j in (0, 1):
        c = corrections(held, j)
        ident = np.array([1.0, 0.0, 0.0, 0.0])
        for run in (c[:6], c[6:]):
            steps = _turns(np.concatenate((ident[None], run, ident[None])))
            assert steps.max() <= 10.0 + 1e-6, (j, steps)
    # where no turn is limited, the correction is the full one
    calm = target.copy()
    calm[:] = p[:, ankle] + 0.004 * up
    a = solve_leg(m.skeleton, p, o, chain, calm, hinge)
    b = solve_leg(m.skeleton, p, o, chain, calm, hinge, frames, 10.0)
    np.testing.assert_allclose(a, b, atol=1e-9)


def test_limit_turns_checks_its_shapes() -> None:
    with pytest.raises(ValueError, match="q must be"):
        limit_turns(np.zeros((3, 3)), np.arange(3), 10.0)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (3, 1))
    np.testing.assert_array_equal(limit_turns(q, np.arange(3), 10.0), q)


def test_two_bone_ik_reaches_and_keeps_the_foot(
    medium_lib: Library, rng: np.random.Generator
) -> None:
    m = medium_lib.clips[0].motion
    pose = forward_kinematics(m)
    hip, knee, ankle = leg_chain(m.skeleton, "left")
    n = m.n_frames
    target = pose.positions[:, ankle] + rng.normal(scale=0.04, size=(n, 3))
    hinge = knee_hinge(pose.positions, pose.orientations, (hip, knee, ankle))
    new = solve_leg(
        m.skeleton, pose.positions, pose.orientations, (hip, knee, ankle), target, hinge
    )
    q = m.quats.copy()
    q[:, [hip, knee, ankle]] = new
    after = forward_kinematics(Motion(m.skeleton, m.root_pos, q, m.fps))
    p = pose.positions
    leg = np.linalg.norm(p[:, knee] - p[:, hip], axis=1) + np.linalg.norm(
        p[:, ankle] - p[:, knee], axis=1
    )
    reach = np.linalg.norm(target - p[:, hip], axis=1) < SOFT_REACH * leg
    assert reach.mean() > 0.5
    np.testing.assert_allclose(after.positions[reach, ankle], target[reach], atol=1e-6)
    # near or out of reach: eased towards the straight leg, never shorter than SOFT_REACH of it
    gap = np.linalg.norm(after.positions[~reach, ankle] - target[~reach], axis=1)
    assert np.all(
        gap
        <= np.linalg.norm(target[~reach] - p[~reach, hip], axis=1) - SOFT_REACH * leg[~reach] + 1e-9
    )
    np.testing.assert_allclose(
        np.abs(np.sum(after.orientations[:, ankle] * pose.orientations[:, ankle], axis=-1)),
        1.0,
        atol=1e-9,
    )
    # a target out of reach: the leg points at it, straight
    far = pose.positions[:, hip] + np.array([0.0, -5.0, 0.0])
    dk, dh = two_bone_ik(
        pose.positions[:, hip],
        pose.positions[:, knee],
        pose.positions[:, ankle],
        far,
        np.tile(hinge, (n, 1)),
    )
    assert np.all(np.isfinite(dk)) and np.all(np.isfinite(dh))


def test_planted_feet_slide_less(graph: MotionGraph, medium_lib: Library) -> None:
    frames, jumps, edges = random_walk(graph, 1500, seed=3)
    with_ik = synthesize(graph, medium_lib.clips, frames, jumps, edges)
    without = synthesize(graph, medium_lib.clips, frames, jumps, edges, BlendSettings(ik=False))
    slide_ik = foot_slide(with_ik.motion, with_ik.states).mean()
    # the raw capture's own slide on the frames this walk shows
    per_frame = np.concatenate([sole_speed(c.motion, c.contacts.states) for c in medium_lib.clips])
    slide_raw = float(np.nanmean(per_frame[frames]))
    assert slide_ik < 0.7 * foot_slide(without.motion, without.states).mean()
    assert slide_ik < 1.3 * slide_raw


def test_a_held_frame_stands_still(graph: MotionGraph, medium_lib: Library) -> None:
    """A frame shown again (a performer standing still) is the same pose at the same
    place, its root not moved on, and the motion plays on from there as before (outside
    a blend: within one, the blend's offset goes on fading)."""
    frames, jumps, edges = random_walk(graph, 400, seed=1)
    calm = [
        t
        for t in range(1, frames.size - 1)
        if not np.any((jumps <= t + 1) & (jumps > t - 2 * graph.fps))  # no blend under way
    ]
    t = calm[len(calm) // 2]
    held = np.concatenate((frames[: t + 1], np.full(10, frames[t]), frames[t + 1 :]))
    later = np.where(jumps > t, jumps + 10, jumps)
    plain = synthesize(graph, medium_lib.clips, frames, jumps, edges, BlendSettings(ik=False))
    still = synthesize(graph, medium_lib.clips, held, later, edges, BlendSettings(ik=False))
    p, q = still.motion.root_pos, still.motion.quats
    np.testing.assert_allclose(p[t : t + 11], np.broadcast_to(p[t], (11, 3)))
    np.testing.assert_allclose(q[t : t + 11], np.broadcast_to(q[t], (11, *q.shape[1:])))
    np.testing.assert_allclose(p[: t + 1], plain.motion.root_pos[: t + 1])
    np.testing.assert_allclose(p[t + 11 :], plain.motion.root_pos[t + 1 :], atol=1e-9)
    np.testing.assert_allclose(q[t + 11 :], plain.motion.quats[t + 1 :], atol=1e-9)


def test_bad_paths_are_refused(graph: MotionGraph, medium_lib: Library) -> None:
    frames, jumps, edges = random_walk(graph, 200, seed=1)
    with pytest.raises(ValueError, match="neither plays on, is held nor follows a jump"):
        synthesize(graph, medium_lib.clips, frames[::2], np.zeros(0, int), np.zeros(0, int))
    with pytest.raises(ValueError, match="edge does not lead"):
        synthesize(graph, medium_lib.clips, frames, jumps, np.roll(edges, 1))
    with pytest.raises(ValueError, match="increasing"):
        synthesize(graph, medium_lib.clips, frames, jumps[::-1], edges[::-1])
    with pytest.raises(ValueError, match="blend"):
        synthesize(graph, medium_lib.clips, frames, jumps, edges, BlendSettings(seconds=0.0))
    with pytest.raises(KeyError, match="lacks"):
        synthesize(graph, medium_lib.clips[:3], frames, jumps, edges)


def test_a_blend_near_a_half_turn_does_not_swing_the_limb(
    graph: MotionGraph, medium_lib: Library
) -> None:
    """A transition whose offset in one joint is close to a half turn, the last two
    offsets on either side of it (their rotation vectors point opposite ways): the blend
    turns the joint back smoothly, never much faster than a half turn over the blend
    (taking the offset's rate as the difference of those vectors, near 2 pi, would swing
    the arm by up to 150 degrees a frame)."""
    room = _edges_with_room(graph, 5, 40)
    e = next(
        int(e)
        for e in room
        if graph.locate(int(graph.src[e]))[0] != graph.locate(int(graph.dst[e]))[0]
    )
    frames, jumps = _path(graph, [e], 5)
    s, joint = int(graph.src[e]), 3
    src_q = np.concatenate([c.motion.quats for c in medium_lib.clips])
    name, f = graph.locate(int(graph.dst[e]))
    k = [c.name for c in medium_lib.clips].index(name)
    q = medium_lib.clips[k].motion.quats.copy()

    def turn(deg: float) -> np.ndarray:
        a = np.radians(deg) / 2
        return np.array([np.cos(a), np.sin(a), 0.0, 0.0])

    # the target, its joint turned 179 degrees from the source's pose, the frame before
    # that 179 the other way: offsets of -179 and +179 degrees about the same axis
    q[f - 1 :, joint] = qmul(turn(179.0), src_q[s, joint])
    q[f - 2, joint] = qmul(turn(-179.0), src_q[s - 1, joint])
    clips = list(medium_lib.clips)
    clips[k] = dataclasses.replace(clips[k], motion=dataclasses.replace(clips[k].motion, quats=q))
    syn = synthesize(
        graph, clips, frames, jumps, np.array([e]), BlendSettings(seconds=1.0, ik=False)
    )
    out = syn.motion.quats[:, joint]
    t = int(jumps[0])
    step = np.degrees(
        np.linalg.norm(qlog(qmul(out[t - 1 : t + 15], qconj(out[t - 2 : t + 14]))), axis=-1)
    )
    # a half turn taken away over the blend's 15 frames by the Hermite curve: its
    # fastest frame turns 1.5 x 180 / 15 = 18 degrees
    assert step.max() < 20.0


def _reference_follow(want: np.ndarray, own: np.ndarray, step: float) -> np.ndarray:
    """``follow_turns`` written with scipy's rotations, frame by frame and joint by joint."""
    from scipy.spatial.transform import Rotation, Slerp

    def rot(q: np.ndarray) -> Rotation:
        return Rotation.from_quat(q[..., [1, 2, 3, 0]])  # scipy: (x, y, z, w)

    out = want.copy()
    for t in range(1, want.shape[0]):
        for j in range(want.shape[1]):
            prev, goal = rot(out[t - 1, j]), rot(want[t, j])
            turn = (prev.inv() * goal).magnitude()
            cap = max(np.radians(step), own[t, j])
            if turn > cap:
                r = Slerp([0.0, 1.0], Rotation.concatenate([prev, goal]))([cap / turn])[0]
                q = r.as_quat()[[3, 0, 1, 2]]
                out[t, j] = q if np.dot(q, want[t, j]) >= 0 else -q
            # (else the wanted rotation itself)
    return out


def test_follow_turns_lets_a_joint_turn_a_step_beyond_its_source() -> None:
    """A joint whose wanted rotation jumps 90 degrees while its source turns 2 degrees a
    frame goes ``step`` a frame and catches up; a joint whose source turns faster than
    ``step`` follows it; every frame equals scipy's slerp of the same rule."""
    n, step = 30, 10.0
    axis = np.array([0.0, 0.6, 0.8])
    ang = np.radians(np.stack((2.0 * np.arange(n), 25.0 * np.arange(n)), axis=1))  # (n, 2)
    ang[12:, 0] += np.radians(90.0)  # joint 0: a blend's offset lands at once at frame 12
    want = np.concatenate(
        (np.cos(ang / 2)[..., None], np.sin(ang / 2)[..., None] * axis), axis=-1
    )  # (n, 2, 4)
    own = np.zeros((n, 2))
    own[1:, 0], own[1:, 1] = np.radians(2.0), np.radians(25.0)
    out = follow_turns(want, own, step)
    np.testing.assert_allclose(out, _reference_follow(want, own, step), atol=1e-9)
    per = np.degrees(np.linalg.norm(qlog(qmul(qconj(out[:-1]), out[1:])), axis=-1))  # (n-1, 2)
    assert per[:, 0].max() <= step + 1e-6 and per[11, 0] == pytest.approx(step)
    np.testing.assert_allclose(per[:, 1], 25.0, atol=1e-6)  # the fast source, untouched
    np.testing.assert_allclose(out[:12], want[:12], atol=1e-12)  # nothing to limit
    # 90 degrees at 10 - 2 a frame: caught up 12 frames later, then the wanted motion
    np.testing.assert_allclose(np.abs(np.sum(out[24:, 0] * want[24:, 0], -1)), 1.0, atol=1e-9)
    with pytest.raises(ValueError, match="want must be"):
        follow_turns(want[:, 0], own, step)
    with pytest.raises(ValueError, match="step must be"):
        follow_turns(want, own, 0.0)


def test_a_turn_limit_keeps_every_joint_within_its_step_or_its_source(
    graph: MotionGraph, medium_lib: Library
) -> None:
    """``BlendSettings.turn_limit`` on a path of several transitions (no IK): no joint
    turns in a frame by more than the limit's step or its source frame's own turn; a
    limit no blend reaches changes nothing."""
    room = _edges_with_room(graph, 5, 40)
    edges: list[int] = []
    for e in room:  # a chain of transitions, each taken 3-12 frames after the last lands
        if not edges or 3 <= int(graph.src[e]) - int(graph.dst[edges[-1]]) <= 12:
            same = (
                not edges
                or graph.locate(int(graph.src[e]))[0] == graph.locate(int(graph.dst[edges[-1]]))[0]
            )
            if same:
                edges.append(int(e))
        if len(edges) == 4:
            break
    assert len(edges) >= 2
    frames, jumps = _path(graph, edges, 5)
    edges_a = np.array(edges)
    plain = synthesize(
        graph, medium_lib.clips, frames, jumps, edges_a, BlendSettings(seconds=0.5, ik=False)
    )
    limit = 150.0
    held = synthesize(
        graph,
        medium_lib.clips,
        frames,
        jumps,
        edges_a,
        BlendSettings(seconds=0.5, ik=False, turn_limit=limit),
    )
    q = held.motion.quats
    per = np.linalg.norm(qlog(qmul(qconj(q[:-1]), q[1:])), axis=-1)  # (T - 1, J) radians
    src = np.concatenate([c.motion.quats for c in medium_lib.clips])[frames]
    own = np.linalg.norm(qlog(qmul(qconj(src[:-1]), src[1:])), axis=-1)
    own[jumps - 1] = np.inf  # (across a jump the source's own turn is its virtual frame's)
    cap = np.maximum(np.radians(limit / graph.fps), own) + 1e-9
    assert (per <= cap).all()
    assert not np.allclose(held.motion.quats, plain.motion.quats)  # the blends were limited
    loose = synthesize(
        graph,
        medium_lib.clips,
        frames,
        jumps,
        edges_a,
        BlendSettings(seconds=0.5, ik=False, turn_limit=1e9),
    )
    np.testing.assert_allclose(loose.motion.quats, plain.motion.quats, atol=1e-12)
    with pytest.raises(ValueError, match="turn_limit"):
        BlendSettings(turn_limit=0.0)
