"""The Bezier fallback: the curve, the greedy walk, eq. 2."""

from __future__ import annotations

from math import comb

import numpy as np
import pytest

from control.graph import frame_features, pair_distances
from control.motion import Library, qexp, qlog
from control.transition import two_pass_clusters
from control.transition._bezier import (
    average_quats,
    bezier_quats,
    greedy_walk,
    interpolation_frames,
)


def _about_z(angles: np.ndarray) -> np.ndarray:
    v = np.zeros((len(angles), 1, 3))
    v[:, 0, 2] = angles
    return qexp(v)


def test_curve_is_bernstein_in_angle_about_one_axis() -> None:
    theta = np.array([0.0, 0.3, 0.9, 1.2])
    q = bezier_quats(_about_z(theta), 11)
    t = np.linspace(0, 1, 11)
    want = sum(comb(3, i) * t**i * (1 - t) ** (3 - i) * theta[i] for i in range(4))
    got = np.linalg.norm(qlog(q[:, 0]), axis=-1)
    np.testing.assert_allclose(got, want, atol=1e-9)


def test_curve_ends_at_its_end_poses(rng: np.random.Generator) -> None:
    control = qexp(rng.normal(scale=0.8, size=(4, 5, 3)))
    q = bezier_quats(control, 7)
    np.testing.assert_allclose(np.abs(np.sum(q[0] * control[0], axis=-1)), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.abs(np.sum(q[-1] * control[-1], axis=-1)), 1.0, atol=1e-12)
    same = bezier_quats(np.repeat(control[:1], 3, axis=0), 5)
    np.testing.assert_allclose(np.abs(np.sum(same * control[0], axis=-1)), 1.0, atol=1e-12)
    with pytest.raises(ValueError):
        bezier_quats(control, 1)


def test_average_ignores_quaternion_sign(rng: np.random.Generator) -> None:
    q = qexp(rng.normal(scale=0.1, size=(1, 3)))[0]
    avg = average_quats(np.stack((q, -q, q)))
    assert abs(float(np.dot(avg, q))) == pytest.approx(1.0)


def test_greedy_walk_gets_nearer_every_step(medium_lib: Library) -> None:
    feat = frame_features(medium_lib.clips, "relative")
    clusters = two_pass_clusters(feat, 0.8)
    c = clusters.centres
    for source, target in ((0, clusters.k - 1), (3, 7)):
        walk = greedy_walk(feat, clusters, source, target)
        assert walk[0] == source and walk[-1] == target
        d, _ = pair_distances(feat, c[walk], np.full(len(walk), c[target]), 0.01)
        assert np.all(np.diff(d) < 0)
    assert interpolation_frames(1.0, 0.05) == 20 and interpolation_frames(0.0, 0.05) == 2
