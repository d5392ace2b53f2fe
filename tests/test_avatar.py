"""The running avatar (``control.avatar``): moving, taking paths, its root transform, and
its direct blended jumps (the vision interface's motion-matching move)."""

from __future__ import annotations

import numpy as np
import pytest

from control.avatar import JUMP, Avatar
from control.graph import (
    BlendSettings,
    FrameData,
    GraphOptions,
    MotionGraph,
    build_graph,
    foot_slide,
    joint_jumps,
    lowest_foot,
    pair_distances,
    rotate_y,
    synthesize,
)
from control.motion import Library


@pytest.fixture(scope="module")
def graph(medium_lib: Library) -> MotionGraph:
    return build_graph(medium_lib.clips, GraphOptions(coords="relative"))


def test_a_jump_is_blended_like_a_transition(graph: MotionGraph, medium_lib: Library) -> None:
    scc = np.flatnonzero(graph.in_scc)
    a = Avatar(graph, medium_lib.clips, start=int(scc[10]), seed=0)
    for _ in range(20):
        a.step()
    landing = np.flatnonzero(a.jump_costs.landing)
    # far away in the library, and no transition leads there
    target = int(landing[len(landing) // 2])
    assert not np.any((graph.src == a.frame) & (graph.dst == target))
    d, align = a.jump_costs(a.frame, np.array([target]))
    d2, align2 = pair_distances(
        a.jump_costs.features, np.array([a.frame]), np.array([target - 1]), graph.options.nu
    )
    assert d[0] == pytest.approx(d2[0]) and np.allclose(align, align2)
    src = a.frame
    a.take([src, target, target + 1, target + 2], [JUMP, -1, -1])
    for _ in range(30):
        a.step()
    assert a.n_jumps == 1
    s, t, al = a.jumps()
    assert s.tolist() == [src] and t.tolist() == [target] and np.allclose(al[0], align[0])
    frames, jumps, edges = a.history()
    assert edges[-1] >= graph.n_edges or graph.n_edges in edges
    syn = a.motion()
    k = int(jumps[np.flatnonzero(edges == graph.n_edges)[0]])
    assert syn.blended[k]
    # the junction moves joints no more than the library's own largest per-frame change
    lib_jumps = np.concatenate([joint_jumps(c.motion) for c in medium_lib.clips])
    assert joint_jumps(syn.motion)[k - 1] <= np.percentile(lib_jumps, 99.9)
    # the same motion as synthesize given the jump as an extra edge
    again = synthesize(graph, medium_lib.clips, frames, jumps, edges, a.blend_settings, a.jumps())
    assert np.allclose(again.motion.quats, syn.motion.quats)
    # its planted feet are held up to 0.4 m from where the blend puts them (a graph
    # walk's 0.2): they slide less
    states = np.concatenate([c.contacts.states for c in medium_lib.clips])[frames]
    tight = synthesize(graph, medium_lib.clips, frames, jumps, edges, extra=a.jumps())
    held, loose = foot_slide(syn.motion, states), foot_slide(tight.motion, states)
    assert a.blend_settings.max_offset == 0.4 and held.mean() < loose.mean()
    with pytest.raises(ValueError, match="max_offset"):
        BlendSettings(max_offset=-0.1)
    # the feet stay where the library's feet are
    assert lowest_foot(syn.motion).max() <= max(
        lowest_foot(c.motion).max() for c in medium_lib.clips
    )


def test_bad_jumps_are_refused(graph: MotionGraph, medium_lib: Library) -> None:
    scc = np.flatnonzero(graph.in_scc)
    a = Avatar(graph, medium_lib.clips, start=int(scc[0]), seed=0)
    first = int(graph.clip_start[1])  # a clip's first frame has no predecessor to blend from
    with pytest.raises(ValueError, match="not in the graph"):
        a.take([a.frame, first], [JUMP])
    with pytest.raises(ValueError, match="cannot be jumped to"):
        a.jump_costs(a.frame, np.array([first]))
    frames, jumps, edges = np.array([0, 5]), np.array([1]), np.array([graph.n_edges])
    with pytest.raises(ValueError, match="edges must lie"):
        synthesize(graph, medium_lib.clips, frames, jumps, edges)
    extra = (np.array([0]), np.array([6]), np.zeros((1, 4)))
    with pytest.raises(ValueError, match="does not lead"):
        synthesize(graph, medium_lib.clips, frames, jumps, edges, extra=extra)


def test_avatar_moves_takes_and_keeps_its_transform(medium_lib: Library) -> None:
    g = build_graph(medium_lib.clips, GraphOptions(coords="relative"))
    avatar = Avatar(g, medium_lib.clips, seed=4)
    assert avatar.advance(1.0) == 15 and avatar.n_frames == 16
    assert avatar.advance(0.03) == 0 and avatar.advance(0.04) == 1
    for _ in range(600):
        avatar.step()
    frames, jumps, _ = avatar.history()
    assert g.in_scc[frames].all() and jumps.size > 0
    with pytest.raises(ValueError, match="must start at the avatar's frame"):
        avatar.take([avatar.frame + 1, avatar.frame + 2], [-1])
    with pytest.raises(ValueError, match="not in the graph"):
        avatar.take([avatar.frame, avatar.frame + 5], [-1])
    while avatar.blending:
        avatar.step()
    syn = avatar.motion()
    yaw, trans = avatar.root_transform()
    data = FrameData(g, medium_lib.clips)
    np.testing.assert_allclose(
        syn.motion.root_pos[-1], rotate_y(data.root[avatar.frame], yaw) + trans, atol=1e-9
    )


def test_planted_feet_on_the_floor_when_blends_end_mid_contact(mocap) -> None:
    """Direct jumps every 0.2-1 s through an exercise take, blended over 0.5 s (the vision
    interface's avatar): a blend may end while a foot it planted is still down. Held where
    it touched down in the blended motion (``feet="held"``), that foot can be held up in
    the air after the blend (the root's height is set after the leg IK, and only over
    blends); ``feet="floor"`` brings it down to the source's height over the blend."""
    from control.avatar import JumpCosts
    from control.motion import load_library

    lib = load_library(mocap, clips=["13_30"])
    g = build_graph(lib.clips, GraphOptions(coords="relative", threshold=0.03))
    own = lowest_foot(lib.clips[0].motion)
    costs = JumpCosts(g, lib.clips, anywhere=True)
    rng = np.random.default_rng(0)
    frames, jumps, src, dst, align = list(range(10, 20)), [], [], [], []
    while len(frames) < 300:
        a, j = frames[-1], int(rng.integers(1, g.n_frames - 20))
        jumps.append(len(frames))
        src.append(a)
        dst.append(j)
        align.append(costs(a, np.array([j]))[1][0])
        frames += list(range(j, j + int(rng.integers(3, 16))))
    path = (np.array(frames), np.array(jumps), g.n_edges + np.arange(len(jumps)))
    extra = (np.array(src), np.array(dst), np.array(align))
    excess = {}
    for feet in ("held", "floor"):
        st = BlendSettings(seconds=0.5, max_offset=0.4, feet=feet)
        syn = synthesize(g, lib.clips, *path, st, extra)
        excess[feet] = lowest_foot(syn.motion) - own[path[0]]
    assert excess["held"].max() > 0.12 and (excess["held"] > 0.1).mean() > 0.01
    assert excess["floor"].max() < 0.06
    a = Avatar(g, lib.clips, blend_settings=BlendSettings(feet="floor"))
    assert a.blend_settings.feet == "floor"
    with pytest.raises(ValueError, match="feet"):
        BlendSettings(feet="air")


def test_where_its_clip_ends_the_avatar_keeps_the_action(mocap) -> None:
    """Outside the component a jumping avatar plays on; where its clip ends it goes on
    in the same action (the nearest frame of it with a second left to play), not to the
    component's nearest frame, which here is a knee raise while the take ends jogging."""
    from control.motion import load_library

    lib = load_library(mocap, clips=["13_29", "13_30", "01_01"])
    g = build_graph(lib.clips, GraphOptions(coords="relative", threshold=0.03))
    clips = g.clips_of(lib.clips)
    labels = np.concatenate(
        [[c.label_at(i) or "" for i in range(c.motion.n_frames)] for c in clips]
    )
    k = [c.name for c in clips].index("13_30")
    end = int(g.clip_start[k + 1] - 1)
    assert labels[end] == "Jog" and not g.in_scc[end - 3 : end + 1].any()
    a = Avatar(g, lib.clips, start=end - 3, anywhere=True)
    for _ in range(4):
        a.step()
    shown = a.history()[0]
    assert shown[3] == end and labels[shown[4]] == "Jog"
    clip_end = g.clip_start[np.searchsorted(g.clip_start, shown[4], side="right")] - 1
    assert clip_end - shown[4] >= g.fps
    component = np.flatnonzero(g.in_scc & a.jump_costs.landing)
    d, _ = a.jump_costs(end, component)
    assert labels[component[np.argmin(d)]] != "Jog"
