"""Body, cameras, the numba rasterizer, and headless pyrender (GL tests run in CI)."""

from __future__ import annotations

import resource
from typing import Any

import numpy as np
import pytest

from silhouette_bank import (
    BodyShape,
    CameraRing,
    capsule_body,
    capsule_segments,
    motion_features,
    motion_silhouettes,
    with_proportions,
)
from silhouette_bank._render import motion_features_both


@pytest.fixture(scope="module")
def exercise(mocap, tmp_path_factory):
    from control.motion import load_library

    lib = load_library(mocap, clips=["13_29"], cache_dir=tmp_path_factory.mktemp("c"))
    return lib.clip("13_29").motion


def test_ring_looks_at_the_avatar() -> None:
    ring = CameraRing()
    root = np.array([2.0, 0.95, -1.0])
    poses = ring.poses(root)
    assert poses.shape == (18, 4, 4)
    target = np.array([2.0, ring.target_height, -1.0])
    uv = ring.project(ring.to_camera(np.broadcast_to(target, (18, 1, 3)), poses)[:, 0])
    np.testing.assert_allclose(uv, np.tile(ring.centre, (18, 1)), atol=1e-9)
    eyes = poses[:, :3, 3]
    np.testing.assert_allclose(np.hypot(eyes[:, 0] - 2.0, eyes[:, 2] + 1.0), ring.distance)
    np.testing.assert_allclose(eyes[:, 1], ring.height)
    az = np.degrees(np.arctan2(eyes[:, 0] - 2.0, eyes[:, 2] + 1.0)) % 360
    np.testing.assert_allclose(np.sort(az), np.arange(0, 360, 20), atol=1e-9)


def test_body_covers_the_skeleton(exercise) -> None:
    body = capsule_body(exercise.skeleton)
    assert body.start.size == exercise.skeleton.n_joints - 1 + exercise.skeleton.end_parents.size
    heavy = capsule_body(exercise.skeleton, BodyShape(width=1.3))
    np.testing.assert_allclose(heavy.radius, body.radius * 1.3)
    tall = capsule_segments(exercise, capsule_body(exercise.skeleton, BodyShape(height=1.1)))
    base = capsule_segments(exercise, body)
    assert tall[..., 1].max() == pytest.approx(base[..., 1].max() * 1.1, rel=1e-6)
    with pytest.raises(ValueError, match="width and height"):
        BodyShape(width=0.0)


def test_other_proportions_scale_the_limbs_and_keep_the_feet_down(exercise) -> None:
    from control.motion import find_role

    sk = exercise.skeleton
    base = capsule_segments(exercise, capsule_body(sk))
    shape = BodyShape(legs=1.2, arms=0.85)
    other = capsule_segments(exercise, capsule_body(sk, shape))
    length = lambda seg: np.linalg.norm(seg[0, :, 1] - seg[0, :, 0], axis=-1)  # noqa: E731
    ratio = length(other) / np.where(length(base) > 0, length(base), 1.0)
    body = capsule_body(sk)
    for role, want in (("knee", 1.2), ("ankle", 1.2), ("elbow", 0.85), ("wrist", 0.85)):
        for side in ("left", "right"):  # the bone that ends at that joint
            (b,) = np.flatnonzero(body.end == find_role(sk, f"{side}_{role}"))
            assert ratio[b] == pytest.approx(want)
    for role in ("chest", "neck", "head"):  # the torso as it was
        (b,) = np.flatnonzero(body.end == find_role(sk, role))
        assert ratio[b] == pytest.approx(1.0)
    # each frame's lowest point where it was: longer legs do not go through the floor
    np.testing.assert_allclose(other[..., 1].min(axis=(1, 2)), base[..., 1].min(axis=(1, 2)))
    assert other[..., 1].max() > base[..., 1].max() + 0.05  # the head is higher
    assert shape.to_dict() == {"width": 1.0, "height": 1.0, "legs": 1.2, "arms": 0.85}
    assert BodyShape().to_dict() == {"width": 1.0, "height": 1.0}  # old keys unchanged
    moved = with_proportions(exercise, shape)  # the same body as a motion (pose landmarks)
    np.testing.assert_allclose(capsule_segments(moved, body), other, atol=1e-9)
    assert with_proportions(exercise, BodyShape(width=2.0)) is exercise
    with pytest.raises(ValueError, match="legs and arms"):
        BodyShape(legs=3.0)


def test_same_pose_farther_away_gives_the_same_features(exercise) -> None:
    body = capsule_body(exercise.skeleton)
    near = CameraRing(distance=3.0, width=320, height_px=240)
    far = CameraRing(distance=4.5, width=320, height_px=240)
    frames = np.array([40, 200, 400])
    fn, _ = motion_features(exercise, body, near, frames)
    ff, _ = motion_features(exercise, body, far, frames)
    # perspective changes a little with distance; Hu moments and centre barely move
    np.testing.assert_allclose(ff[..., :2], fn[..., :2], atol=0.1)
    assert np.abs(ff[..., :7] - fn[..., :7]).mean() < 0.3
    np.testing.assert_allclose(ff[..., 7:], fn[..., 7:], atol=0.03)


def test_root_motion_shows_a_walk(mocap, tmp_path_factory) -> None:
    from control.motion import load_library

    lib = load_library(mocap, clips=["02_01"], cache_dir=tmp_path_factory.mktemp("c"))
    m = lib.clip("02_01").motion
    feats, moves = motion_features(m, capsule_body(m.skeleton), CameraRing())
    assert feats.shape == (m.n_frames, 18, 9) and moves.shape == (m.n_frames, 18, 2)
    assert np.all(moves[0] == 0.0)
    speed = np.abs(moves[1:, :, 0]).mean(axis=0)  # sideways image motion per view
    # walking past the camera moves the root sideways; walking towards it hardly
    assert speed.max() > 4.0 * speed.min()


@pytest.mark.gl
@pytest.mark.parametrize("descriptor", ["hu", "multigrid"])
def test_with_and_without_a_shadow_from_one_rasterization(exercise, descriptor: str) -> None:
    ring = CameraRing(n_views=4)
    body = capsule_body(exercise.skeleton, BodyShape())
    frames = np.arange(0, 200, 9)
    both = motion_features_both(exercise, body, ring, frames, chunk=7, descriptor=descriptor)
    for shadow, (feats, moves) in zip((False, True), both, strict=True):
        want = motion_features(exercise, body, ring, frames, shadow=shadow, descriptor=descriptor)
        assert feats.tobytes() == want[0].tobytes() and moves.tobytes() == want[1].tobytes()
    plain, shadowed = both
    assert not np.array_equal(plain[0], shadowed[0])  # the shadow shows
    (alone,) = motion_features_both(
        exercise, body, ring, frames, shadows=(True,), descriptor=descriptor
    )
    assert alone[0].tobytes() == shadowed[0].tobytes()


def test_pyrender_agrees_with_the_rasterizer(exercise) -> None:
    from silhouette_bank._gl import GLRenderer

    ring = CameraRing()
    body = capsule_body(exercise.skeleton)
    seg = capsule_segments(exercise, body)
    frames = np.array([0, 150, 300, 450])
    ras = motion_silhouettes(exercise, body, ring, frames)
    poses = ring.poses(exercise.root_pos)
    ious = []
    with GLRenderer(ring) as gl:
        for i, f in enumerate(frames):
            gl.set_body(seg[f], body.radius)
            for v in range(ring.n_views):
                g = gl.render(poses[f, v])
                assert set(np.unique(g)) <= {0, 1}
                a = ras[i, v]
                ious.append((g & a).sum() / (g | a).sum())
    # the mesh is a low-poly version of the exact capsules
    assert min(ious) > 0.9 and np.mean(ious) > 0.95


@pytest.mark.gl
def test_two_thousand_renders_with_flat_memory(exercise) -> None:
    from silhouette_bank._gl import GLRenderer

    ring = CameraRing(width=160, height_px=120)  # (a leak per render grows at any size)
    body = capsule_body(exercise.skeleton)
    seg = capsule_segments(exercise, body)
    poses = ring.poses(exercise.root_pos)
    with GLRenderer(ring) as gl:
        for k in range(2000):
            if k % 18 == 0:
                gl.set_body(seg[(k // 18) % exercise.n_frames], body.radius)
            gl.render(poses[0, k % 18])
            if k == 199:
                rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        assert gl.renders == 2000
    grown_mb = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss) / 1024
    assert grown_mb < 20, f"memory grew {grown_mb:.1f} MB over 1,800 renders"


@pytest.mark.gl
def test_scenery_shows_in_shaded_renders_but_not_in_silhouettes(exercise) -> None:
    from control.sketch import Environment, environment_mesh
    from silhouette_bank._gl import GLRenderer

    ring = CameraRing(width=160, height_px=120)
    body = capsule_body(exercise.skeleton)
    seg = capsule_segments(exercise, body)
    pose = ring.poses(exercise.root_pos)[0, 0]
    # a wall between the camera (view 0) and the avatar, and one behind it
    root = exercise.root_pos[0]
    cam = pose[:3, 3]
    mid = 0.5 * (root + cam)
    wall = np.array([[-0.3, -0.3], [0.3, -0.3], [0.3, 0.3], [-0.3, 0.3]]) + mid[[0, 2]]
    mesh = environment_mesh(Environment(obstacles=(wall,)))
    assert mesh is not None and environment_mesh(Environment()) is None
    with GLRenderer(ring) as gl:
        gl.set_body(seg[0], body.radius)
        alone, shaded_alone = gl.render(pose), gl.render_shaded(pose)
        gl.set_scenery(*mesh)
        with_wall, shaded_wall = gl.render(pose), gl.render_shaded(pose)
    assert np.array_equal(alone, with_wall)  # silhouettes are the body's alone
    lit = (shaded_wall.sum(axis=2) > 0) & (shaded_alone.sum(axis=2) == 0)
    assert lit.sum() > 100  # the wall is drawn


@pytest.mark.gl
def test_a_shaded_render_does_not_depend_on_the_order_pyrender_keeps_its_meshes(
    mocap, monkeypatch
) -> None:
    # pyrender keeps a scene's meshes in a set (its order that of their addresses) and
    # draws them sorted by their distance from the camera; where the face's spheres meet
    # the head at one depth, the first drawn shows. 14_20 seen from 45 degrees, by the
    # camera ``mimic record --colour`` places for its first 200 frames: frame 100 has
    # such pixels
    import dataclasses

    import pyrender

    from control.motion import load_library
    from silhouette_bank._render import shaded_frames
    from vision import RecordSettings
    from vision._record import camera_poses

    motion = load_library(mocap, clips=["14_20"]).clip("14_20").motion
    settings = RecordSettings(azimuth=45.0, width=640, height=480)
    frames = np.arange(95, 106)
    poses = camera_poses(motion, settings, np.arange(200))[frames]
    sub = dataclasses.replace(motion, root_pos=motion.root_pos[frames], quats=motion.quats[frames])
    body = capsule_body(motion.skeleton, settings.body)
    nodes = pyrender.Scene.mesh_nodes

    def colour(node: Any) -> float:  # (the face is dark, the body light)
        return float(node.mesh.primitives[0].material.baseColorFactor[0])

    def shot(face_first: bool) -> np.ndarray:
        def ordered(scene: Any) -> list[Any]:
            return sorted(nodes.fget(scene), key=colour, reverse=not face_first)

        monkeypatch.setattr(pyrender.Scene, "mesh_nodes", property(ordered))
        return np.array(list(shaded_frames(sub, settings.ring(), body=body, camera_poses=poses)))

    np.testing.assert_array_equal(shot(True), shot(False))


def test_write_mp4_never_follows_a_planted_name(tmp_path) -> None:  # type: ignore[no-untyped-def]
    import numpy as np
    import pytest

    from silhouette_bank import write_mp4

    target = tmp_path / "victim.txt"
    target.write_text("keep me")
    (tmp_path / ".v.tmp.mp4").symlink_to(target)  # the old, predictable temporary name
    write_mp4(tmp_path / "v.mp4", [np.zeros((16, 16, 3), np.uint8)] * 3, 15.0)
    assert target.read_text() == "keep me" and (tmp_path / "v.mp4").stat().st_size > 0
    with pytest.raises(ValueError, match="no frames"):
        write_mp4(tmp_path / "w.mp4", [], 15.0)
    left = {p.name for p in tmp_path.iterdir()}
    assert left == {"victim.txt", ".v.tmp.mp4", "v.mp4"}
