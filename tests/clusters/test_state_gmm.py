"""Motion state vectors (eq. 4), the reference orientation, and the mixture with BIC."""

from __future__ import annotations

import numpy as np
import pytest

from control.clusters import (
    decorrelation_frames,
    fit_mixture,
    orientation_distance,
    select_by_bic,
    state_vectors,
)
from control.clusters._gmm import keyframe_seeds
from control.clusters._state import reference_orientation
from control.graph import frame_features, weighted_joints
from control.motion import Library, qexp


def _random_q(rng: np.random.Generator, n: int, spread: float) -> np.ndarray:
    return qexp(rng.normal(scale=spread, size=(n, 3)))


@pytest.mark.parametrize("elems", [1 << 26, 1000])
def test_reference_orientation_is_the_minimax_one(
    rng: np.random.Generator, monkeypatch: pytest.MonkeyPatch, elems: int
) -> None:
    """Also with the candidates measured against a few frames at a time (``_ELEMS``
    1,000: 4 to 58 columns a pass, the last one shorter), as against 500,000 frames."""
    from control.clusters import _state

    monkeypatch.setattr(_state, "_ELEMS", elems)
    q = _random_q(rng, 200, 1.2)
    q[::3] *= -1.0  # the sign of a quaternion must not matter
    ref = reference_orientation(q, block=17, sample=23)
    d = orientation_distance(q[:, None, :], q[None, :, :])
    worst = d.max(axis=1)
    assert np.max(orientation_distance(ref, q)) == pytest.approx(worst.min(), abs=1e-9)
    # the same orientation as measuring all pairs (the first minimax one), on spreads
    # with many near ties too
    for spread, n in ((1.2, 500), (0.05, 3000), (0.3, 1000)):
        q = _random_q(rng, n, spread)
        q[::5] *= -1.0
        all_pairs = np.min(np.abs(q @ q.T), axis=1)
        expect = q[int(np.argmax(all_pairs))]
        for block, sample in ((17, 23), (256, 64), (2048, 2048)):
            np.testing.assert_array_equal(reference_orientation(q, block, sample), expect)
        # among a spread of candidates, still measured against every orientation
        np.testing.assert_array_equal(reference_orientation(q, candidates=n), expect)
        pool = np.unique(np.linspace(0, n - 1, 97).round().astype(np.int64))
        among = pool[int(np.argmax(all_pairs[pool]))]
        np.testing.assert_array_equal(reference_orientation(q, 17, 23, candidates=97), q[among])


def test_orientation_distance_is_half_the_angle() -> None:
    a = np.array([1.0, 0.0, 0.0, 0.0])
    b = qexp(np.array([0.0, 1.0, 0.0]))  # 1 rad about Y
    assert orientation_distance(a, b) == pytest.approx(0.5)
    assert orientation_distance(a, -b) == pytest.approx(0.5)


def test_state_vectors_follow_eq4(walk_lib: Library) -> None:
    feat = frame_features(walk_lib.clips, "fixed")
    x, q_hat = state_vectors(feat)
    k = weighted_joints(walk_lib.clips[0].motion.skeleton).size
    assert x.shape == (feat.n, 3 + 3 + 3 * k)
    np.testing.assert_allclose(x[:, :3], feat.root_p)
    # the reference orientation is one of the frames': its own root term is zero
    i = int(np.argmin(np.linalg.norm(x[:, 3:6], axis=1)))
    assert np.linalg.norm(x[i, 3:6]) < 1e-9
    assert abs(abs(float(np.dot(feat.root_q[i], q_hat))) - 1.0) < 1e-12
    # joint terms: half angles
    np.testing.assert_allclose(
        np.linalg.norm(x[:, 6:9], axis=1),
        orientation_distance(np.array([1.0, 0.0, 0.0, 0.0]), feat.joint_q[:, 0]),
        atol=1e-9,
    )
    xr, _ = state_vectors(frame_features(walk_lib.clips, "relative"))
    np.testing.assert_allclose(xr[:, [0, 2]], 0.0)  # no horizontal position


def _blobs(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    centres = np.array([[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, 4.0, 4.0]])
    truth = rng.integers(0, 3, 600)
    return centres[truth] + rng.normal(scale=0.5, size=(600, 3)), truth


def test_mixture_finds_known_clusters_and_bic_picks_three(rng: np.random.Generator) -> None:
    x, truth = _blobs(rng)
    best, fits, curve = select_by_bic(x, [1, 2, 3, 4, 5, 6])
    assert best.k == 3 and curve["chosen_k"] == 3 and curve["bic_effective"] is None
    # the clusters are the blobs, up to naming
    pairs = {(int(a), int(b)) for a, b in zip(best.labels, truth, strict=True)}
    assert len(pairs) == 3
    np.testing.assert_allclose(np.sort(best.variances), 0.25, rtol=0.2)
    assert best.sizes().sum() == 600 and np.all(best.posterior > 0.3)
    assert [f.k for f in fits] == [1, 2, 3, 4, 5, 6]
    # the paper's sign: larger is better; m = k d + k + k - 1 for spherical
    assert best.n_params == 3 * 3 + 3 + 2
    ll = best.log_likelihood
    assert best.bic == pytest.approx(2 * ll - best.n_params * np.log(600))


def test_the_bic_search_on_a_two_worker_cluster_is_the_local_one(
    rng: np.random.Generator, dask_cluster: str
) -> None:
    x, _ = _blobs(rng)
    cs = np.array([0, 250, 600])
    here = select_by_bic(x, [2, 3, 4, 5], clip_start=cs)
    there = select_by_bic(x, [2, 3, 4, 5], clip_start=cs, cluster=dask_cluster)
    assert there[0].k == here[0].k and there[2] == here[2]
    for a, b in zip(here[1], there[1], strict=True):
        np.testing.assert_array_equal(a.labels, b.labels)
        np.testing.assert_array_equal(a.means, b.means)
        assert a.log_likelihood == b.log_likelihood and a.bic == b.bic


def test_squared_distances_in_passes_equal_the_whole_array(rng: np.random.Generator) -> None:
    from control.clusters._gmm import _squared_distances

    x, centres = rng.normal(size=(301, 17)), rng.normal(size=(7, 17))
    whole = ((x[:, None, :] - centres[None]) ** 2).sum(-1)
    for elems in (1, 7 * 17 * 3, 7 * 17 * 50, 1 << 23):  # 1, 3, 50 and all rows a pass
        np.testing.assert_array_equal(_squared_distances(x, centres, elems), whole)


def test_seeding_is_reproducible_and_from_real_frames(rng: np.random.Generator) -> None:
    x, _ = _blobs(rng)
    s1 = keyframe_seeds(x, 5, seed=3)
    assert np.array_equal(s1, keyframe_seeds(x, 5, seed=3)) and len(set(s1.tolist())) == 5
    a = fit_mixture(x, 3, seeding="keyframes", seed=1)
    b = fit_mixture(x, 3, seeding="keyframes", seed=1)
    assert np.array_equal(a.labels, b.labels) and a.log_likelihood == b.log_likelihood
    r = fit_mixture(x, 3, seeding="random", seed=1)
    assert r.log_likelihood == pytest.approx(a.log_likelihood, rel=1e-3)
    with pytest.raises(ValueError, match="seeding"):
        fit_mixture(x, 3, seeding="by hand")


def test_decorrelation_of_smooth_and_white_signals(rng: np.random.Generator) -> None:
    white = rng.normal(size=(400, 4))
    assert decorrelation_frames(white, np.array([0, 400])) == 1
    t = np.arange(400)[:, None]
    smooth = np.sin(t / 20.0 + np.arange(4)) + 0.01 * white
    d = decorrelation_frames(smooth, np.array([0, 200, 400]))
    assert 10 < d < 60


def test_a_sample_of_the_states_chooses_the_k_the_whole_would_and_the_fit_labels_all(
    rng: np.random.Generator,
) -> None:
    # smooth runs of frames (each 40 frames long, one blob a run), as motion is
    centres = np.array([[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, 4.0, 4.0]])
    truth = np.repeat(rng.integers(0, 3, 60), 40)
    x = centres[truth] + rng.normal(scale=0.5, size=(truth.size, 3))
    cs = np.arange(0, truth.size + 1, 400)
    whole = select_by_bic(x, [1, 2, 3, 4, 5], clip_start=cs)
    n_eff = x.shape[0] / decorrelation_frames(x, cs)
    sample = np.unique(np.linspace(0, x.shape[0] - 1, 300).round().astype(np.int64))
    got = select_by_bic(x[sample], [1, 2, 3, 4, 5], n_eff=n_eff)
    assert got[0].k == whole[0].k == 3 and got[2]["effective_states"] == n_eff
    refit = fit_mixture(x, 3, means_init=got[0].means)
    assert refit.labels.size == x.shape[0] and refit.seeds.size == 0
    same = {(int(a), int(b)) for a, b in zip(refit.labels, whole[0].labels, strict=True)}
    assert len(same) == 3  # the same clusters, up to naming
    with pytest.raises(ValueError, match="means_init must be"):
        fit_mixture(x, 2, means_init=got[0].means)
