"""The frame distance against a slow reference written from the paper's formulas."""

from __future__ import annotations

import numpy as np
import pytest

from control.graph import frame_features, pair_distances, rotate_y, weighted_joints
from control.graph._broad import BroadPhase, squared_gaps
from control.graph._distance import close_pairs, lower_bound_features
from control.graph._features import q_embed
from control.motion import Clip, Library, Motion, qconj, qlog, qmul

NU = 0.01


def _yaw(q: np.ndarray) -> float:
    return float(2.0 * np.arctan2(q[2], q[0]))


def _yq(angle: float) -> np.ndarray:
    return np.array([np.cos(angle / 2), 0.0, np.sin(angle / 2), 0.0])


def _Ry(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _half_angle_sq(qa: np.ndarray, qb: np.ndarray) -> float:
    """|log(qb^-1 qa)|^2 with |log| half the rotation angle (Lee et al. eq. 3)."""
    return float((np.linalg.norm(qlog(qmul(qconj(qb), qa))) / 2.0) ** 2)


def _velocities(m: Motion, f: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Central differences at frame f: joint angular velocities (body frame), root linear
    and root angular velocity (world)."""
    lo, hi = max(f - 1, 0), min(f + 1, m.n_frames - 1)
    dt = (hi - lo) / m.fps
    joints = weighted_joints(m.skeleton)
    ang = np.array([qlog(qmul(qconj(m.quats[lo, j]), m.quats[hi, j])) / dt for j in joints])
    lin = (m.root_pos[hi] - m.root_pos[lo]) / dt
    rot = qlog(qmul(m.quats[hi, 0], qconj(m.quats[lo, 0]))) / dt
    return ang, lin, rot


def reference_distance(
    ca: Clip, fa: int, cb: Clip, fb: int, coords: str, block: float = 0.5
) -> float:
    ma, mb = ca.motion, cb.motion
    joints = weighted_joints(ma.skeleton)
    d = sum(_half_angle_sq(ma.quats[fa, j], mb.quats[fb, j]) for j in joints)
    ang_a, lin_a, rot_a = _velocities(ma, fa)
    ang_b, lin_b, rot_b = _velocities(mb, fb)
    d += NU * float(np.sum((ang_a - ang_b) ** 2))
    qa, qb = ma.quats[fa, 0], mb.quats[fb, 0]
    pa, pb = ma.root_pos[fa], mb.root_pos[fb]
    if coords == "fixed":
        root = _half_angle_sq(qa, qb) + float(np.sum((pa - pb) ** 2))
        root += NU * float(np.sum((lin_a - lin_b) ** 2) + np.sum((rot_a - rot_b) ** 2))
        return d + root
    if coords == "relative":
        turn = _yaw(qa) - _yaw(qb)
        R = _Ry(turn)
        root = _half_angle_sq(qa, qmul(_yq(turn), qb)) + (pa[1] - pb[1]) ** 2
        root += NU * float(np.sum((lin_a - R @ lin_b) ** 2) + np.sum((rot_a - R @ rot_b) ** 2))
        return d + root
    best = np.inf
    for r in range(4):
        turn = r * np.pi / 2
        R = _Ry(turn)
        res = pa - R @ pb
        res = res - block * np.round(res / block)
        root = _half_angle_sq(qa, qmul(_yq(turn), qb)) + res[0] ** 2 + res[2] ** 2
        root += NU * float(np.sum((lin_a - R @ lin_b) ** 2) + np.sum((rot_a - R @ rot_b) ** 2))
        best = min(best, root)
    return d + best


def _locate(lib: Library, f: int) -> tuple[Clip, int]:
    for c in lib.clips:
        if f < c.motion.n_frames:
            return c, f
        f -= c.motion.n_frames
    raise IndexError(f)


@pytest.mark.parametrize("coords", ["fixed", "relative", "terrain"])
def test_matches_slow_reference(walk_lib: Library, coords: str, rng: np.random.Generator) -> None:
    feat = frame_features(walk_lib.clips, coords)
    a = rng.integers(0, feat.n, 60)
    b = rng.integers(0, feat.n, 60)
    d, _ = pair_distances(feat, a, b, NU)
    ref = [
        reference_distance(*_locate(walk_lib, x), *_locate(walk_lib, y), coords)
        for x, y in zip(a, b, strict=True)
    ]
    np.testing.assert_allclose(d, ref, rtol=1e-7, atol=1e-9)


@pytest.mark.parametrize("coords", ["fixed", "relative", "terrain"])
def test_symmetric_with_zero_diagonal(
    walk_lib: Library, coords: str, rng: np.random.Generator
) -> None:
    feat = frame_features(walk_lib.clips, coords)
    a = rng.integers(0, feat.n, 500)
    b = rng.integers(0, feat.n, 500)
    dab, _ = pair_distances(feat, a, b, NU)
    dba, _ = pair_distances(feat, b, a, NU)
    np.testing.assert_allclose(dab, dba, rtol=1e-9, atol=1e-12)
    diag, align = pair_distances(feat, a, a, NU)
    np.testing.assert_allclose(diag, 0.0, atol=1e-12)
    if coords != "terrain":
        np.testing.assert_allclose(align[:, [0, 1, 3]], 0.0, atol=1e-9)


def _moved(clip: Clip, turn: float, shift: np.ndarray) -> Clip:
    m = clip.motion
    q = m.quats.copy()
    q[:, 0] = qmul(_yq(turn), q[:, 0])
    pos = m.root_pos @ _Ry(turn).T + shift
    moved = Motion(m.skeleton, pos, q, m.fps, m.name + "_moved", m.source)
    return Clip(moved, clip.contacts, "", clip.labels, (), clip.source_frames, clip.path)


def test_relative_ignores_heading_and_floor_position(walk_lib: Library) -> None:
    a, b = walk_lib.clips[0], walk_lib.clips[1]
    feat = frame_features([a, b], "relative")
    moved = frame_features([a, _moved(b, 1.234, np.array([3.0, 0.0, -7.0]))], "relative")
    fa = np.repeat(np.arange(a.motion.n_frames), b.motion.n_frames)
    fb = np.tile(np.arange(b.motion.n_frames), a.motion.n_frames) + a.motion.n_frames
    d0, _ = pair_distances(feat, fa, fb, NU)
    d1, al1 = pair_distances(moved, fa, fb, NU)
    np.testing.assert_allclose(d0, d1, rtol=1e-9, atol=1e-10)
    # the alignment undoes the move: aligned frame b lands on frame a horizontally
    pb = moved.world_p[fb]
    c, s = np.cos(al1[:, 0]), np.sin(al1[:, 0])
    x = c * pb[:, 0] + s * pb[:, 2] + al1[:, 1]
    z = -s * pb[:, 0] + c * pb[:, 2] + al1[:, 3]
    np.testing.assert_allclose(x, moved.world_p[fa, 0], atol=1e-9)
    np.testing.assert_allclose(z, moved.world_p[fa, 2], atol=1e-9)
    fixed0 = pair_distances(frame_features([a, b], "fixed"), fa, fb, NU)[0]
    fixed1 = pair_distances(
        frame_features([a, _moved(b, 1.234, np.zeros(3))], "fixed"), fa, fb, NU
    )[0]
    assert np.mean(np.abs(fixed0 - fixed1)) > 0.1  # fixed coordinates do see the turn


def test_terrain_allows_quarter_turns_and_whole_blocks(walk_lib: Library) -> None:
    a, b = walk_lib.clips[0], walk_lib.clips[3]
    fa = np.repeat(np.arange(a.motion.n_frames), 5)
    fb = np.tile(np.arange(5), a.motion.n_frames) + a.motion.n_frames
    d0, _ = pair_distances(frame_features([a, b], "terrain"), fa, fb, NU, block=0.5)
    turned = _moved(b, np.pi / 2, np.array([1.0, 0.3, -1.5]))
    d1, al = pair_distances(frame_features([a, turned], "terrain"), fa, fb, NU, block=0.5)
    np.testing.assert_allclose(d0, d1, rtol=1e-7, atol=1e-9)
    quarter = al[:, 0] / (np.pi / 2)
    np.testing.assert_allclose(quarter, np.round(quarter), atol=1e-9)
    np.testing.assert_allclose(al[:, [1, 3]] / 0.5, np.round(al[:, [1, 3]] / 0.5), atol=1e-6)
    # a shift of a fraction of a block is not free
    off = _moved(b, 0.0, np.array([0.25, 0.0, 0.0]))
    d2, _ = pair_distances(frame_features([a, off], "terrain"), fa, fb, NU, block=0.5)
    assert np.all(d2 >= d0 - 1e-9) and np.mean(d2 - d0) > 0.01


def test_terrain_turns_about_a_block_centre_and_lifts_by_whole_blocks(walk_lib: Library) -> None:
    a, b = walk_lib.clips[0], walk_lib.clips[3]
    fa = np.repeat(np.arange(a.motion.n_frames), 5)
    fb = np.tile(np.arange(5), a.motion.n_frames) + a.motion.n_frames
    origin = np.array([0.21, 0.0, -0.13])  # a block centre that is not the world origin
    kw = {"block": 0.5, "origin": (0.21, -0.13), "rise": 0.15}
    feat0 = frame_features([a, b], "terrain")
    d0, al0 = pair_distances(feat0, fa, fb, NU, **kw)
    # b turned a quarter about that centre and shifted by whole blocks: the same distance,
    # and the alignment puts b's frames where it put them before
    turned = _moved(b, np.pi / 2, np.array([1.0, 0.3, -1.5]) + origin - origin @ _Ry(np.pi / 2).T)
    feat1 = frame_features([a, turned], "terrain")
    d1, al1 = pair_distances(feat1, fa, fb, NU, **kw)
    np.testing.assert_allclose(d0, d1, rtol=1e-7, atol=1e-9)
    p0 = rotate_y(feat0.world_p[fb], al0[:, 0]) + al0[:, 1:]
    p1 = rotate_y(feat1.world_p[fb], al1[:, 0]) + al1[:, 1:]
    np.testing.assert_allclose(p0[:, [0, 2]], p1[:, [0, 2]], atol=1e-9)
    # the lift is a whole number of blocks; without a rise it is the root height difference
    np.testing.assert_allclose(al0[:, 2] / 0.15, np.round(al0[:, 2] / 0.15), atol=1e-9)
    _, free = pair_distances(feat0, fa, fb, NU, block=0.5, origin=(0.21, -0.13))
    np.testing.assert_allclose(free[:, 2], feat0.world_p[fa, 1] - feat0.world_p[fb, 1])
    with pytest.raises(ValueError, match="rise not negative"):
        pair_distances(feat0, fa, fb, NU, block=0.5, rise=-1.0)


def test_embedding_gives_squared_dot(rng: np.random.Generator) -> None:
    q = rng.normal(size=(50, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    p = rng.normal(size=(50, 4))
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    np.testing.assert_allclose(np.sum(q_embed(q) * q_embed(p), axis=1), np.sum(q * p, axis=1) ** 2)


@pytest.mark.parametrize("coords", ["fixed", "relative", "terrain"])
def test_blocked_search_finds_every_close_pair(walk_lib: Library, coords: str) -> None:
    feat = frame_features(walk_lib.clips, coords)
    n = feat.n
    a = np.repeat(np.arange(n), n)
    b = np.tile(np.arange(n), n)
    d, _ = pair_distances(feat, a, b, NU)
    x, norms = lower_bound_features(feat, NU)
    lb = norms[a] + norms[b] - 2.0 * np.sum(x[a].astype(np.float64) * x[b], axis=1)
    assert np.all(lb <= d + 1e-4)  # a lower bound (up to float32 rounding)
    dmax = float(np.quantile(d[a != b], 0.02))
    rows = np.arange(n)
    ca, cb = close_pairs(feat, rows, rows, dmax, NU, max_block_elems=1000)
    found = set(zip(ca.tolist(), cb.tolist(), strict=True))
    truth = {(int(i), int(j)) for i, j, v in zip(a, b, d, strict=True) if v <= dmax and i != j}
    assert truth <= found
    assert len(found) < 0.2 * n * n  # and it actually prunes


@pytest.mark.parametrize("coords", ["fixed", "relative", "terrain"])
def test_the_broad_phase_finds_the_blocked_search_s_pairs(walk_lib: Library, coords: str) -> None:
    """A KD-tree of the columns' principal directions, queried a few rows at a time,
    finds exactly the pairs whose full bound is within the limit (so every pair the
    blocked matrix products find under the threshold); rows and columns need not be the
    same frames."""
    feat = frame_features(walk_lib.clips, coords)
    x, norms = lower_bound_features(feat, NU)
    rng = np.random.default_rng(7)
    rows = np.sort(rng.choice(feat.n, feat.n * 2 // 3, replace=False))
    cols = np.sort(rng.choice(feat.n, feat.n // 2, replace=False))
    a_all, b_all = np.repeat(rows, cols.size), np.tile(cols, rows.size)
    gaps = squared_gaps(x, a_all, b_all)
    broad = BroadPhase.of(x, cols, dims=4)
    for q in (0.01, 0.05, 0.2):
        limit = float(np.quantile(gaps, q))
        got = list(broad.pairs(x, rows, limit, per_block=17))
        tree = set(
            zip(
                np.concatenate([a for a, _ in got]).tolist(),
                np.concatenate([b for _, b in got]).tolist(),
                strict=True,
            )
        )
        inside = (gaps <= limit) & (a_all != b_all)
        assert tree == set(zip(a_all[inside].tolist(), b_all[inside].tolist(), strict=True))
        assert len(tree) > 20  # and not empty
        # the blocked search widens its threshold by its float32 products' slack
        slack = 1e-5 * (1.0 + 4.0 * float(norms.max())) + 1e-6
        blocked = close_pairs(feat, rows, cols, limit - 3 * slack, NU, x, norms, 1000)
        assert (
            blocked[0].size > 10 and set(zip(*map(np.ndarray.tolist, blocked), strict=True)) <= tree
        )


def test_squared_gaps_are_numpy_s(rng: np.random.Generator) -> None:
    x = rng.normal(size=(40, 9)).astype(np.float32)
    a = rng.integers(0, 40, 300)
    b = rng.integers(0, 40, 300)
    want = np.sum((x[a].astype(np.float64) - x[b]) ** 2, axis=1)
    np.testing.assert_allclose(squared_gaps(x, a, b), want, rtol=1e-12)


@pytest.mark.parametrize("coords", ["fixed", "relative", "terrain"])
def test_a_few_pairs_match_a_large_batch(walk_lib: Library, coords: str) -> None:
    """Under 256 pairs the kernel runs on one thread: the same numbers."""
    feat = frame_features(walk_lib.clips, coords)
    rng = np.random.default_rng(4)
    a = rng.integers(0, feat.n, 300)
    b = rng.integers(0, feat.n, 300)
    d_all, al_all = pair_distances(feat, a, b, 0.01)
    d_few, al_few = pair_distances(feat, a[:8], b[:8], 0.01)
    assert np.array_equal(d_few, d_all[:8]) and np.array_equal(al_few, al_all[:8])


def test_rotate_y_of_one_point_is_the_vectorised_rotation(rng) -> None:
    """The scalar path for one float64 point (the sketch search's) gives the numbers of
    the array path, and of scipy's rotation about +Y."""
    from scipy.spatial.transform import Rotation

    for _ in range(20):
        v = rng.normal(size=3)
        a = float(rng.uniform(-4.0, 4.0))
        one = rotate_y(v, a)
        assert one.shape == (3,) and one.dtype == np.float64
        np.testing.assert_allclose(one, rotate_y(v[None], np.array([a]))[0], atol=1e-15)
        np.testing.assert_allclose(one, Rotation.from_rotvec([0.0, a, 0.0]).apply(v), atol=1e-12)
