"""Quaternion kernels against scipy's Rotation."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from control.motion import euler_to_q, q_to_euler, q_to_R, qconj, qlog, qmul, qrot, slerp


def _rand_q(rng: np.random.Generator, n: int) -> np.ndarray:
    q = Rotation.random(n, random_state=int(rng.integers(1 << 31))).as_quat()
    return np.concatenate((q[:, 3:], q[:, :3]), axis=1)  # (w, x, y, z)


def _rot(q: np.ndarray) -> Rotation:
    return Rotation.from_quat(np.concatenate((q[..., 1:], q[..., :1]), axis=-1))


def test_qmul_composes_like_matrices(rng: np.random.Generator) -> None:
    a, b = _rand_q(rng, 50), _rand_q(rng, 50)
    np.testing.assert_allclose(q_to_R(qmul(a, b)), q_to_R(a) @ q_to_R(b), atol=1e-12)
    np.testing.assert_allclose(q_to_R(a), _rot(a).as_matrix(), atol=1e-12)


def test_qrot_and_conjugate(rng: np.random.Generator) -> None:
    q = _rand_q(rng, 40)
    v = rng.normal(size=(40, 3))
    np.testing.assert_allclose(qrot(q, v), _rot(q).apply(v), atol=1e-12)
    np.testing.assert_allclose(qrot(qconj(q), qrot(q, v)), v, atol=1e-12)


def test_qlog_is_sign_invariant_rotation_vector(rng: np.random.Generator) -> None:
    q = _rand_q(rng, 40)
    np.testing.assert_allclose(qlog(q), _rot(q).as_rotvec(), atol=1e-9)
    np.testing.assert_allclose(qlog(-q), qlog(q), atol=1e-12)
    assert np.allclose(qlog(np.array([1.0, 0, 0, 0])), 0.0)


def test_slerp_matches_scipy(rng: np.random.Generator) -> None:
    a, b = _rand_q(rng, 1)[0], _rand_q(rng, 1)[0]
    t = np.linspace(0, 1, 11)
    ours = slerp(np.broadcast_to(a, (11, 4)), np.broadcast_to(b, (11, 4)), t)
    ref = Slerp([0, 1], _rot(np.stack((a, b))))(t).as_matrix()
    np.testing.assert_allclose(q_to_R(ours), ref, atol=1e-9)
    # Identical endpoints (sin(theta) = 0) stay finite.
    np.testing.assert_allclose(slerp(a, a, 0.3), a, atol=1e-12)


@pytest.mark.parametrize("seq", ["ZXY", "XYZ", "ZYX", "YXZ"])
def test_euler_roundtrip(rng: np.random.Generator, seq: str) -> None:
    q = _rand_q(rng, 30)
    back = euler_to_q(q_to_euler(q, seq), seq)
    assert np.all(np.abs(np.sum(back * q, axis=1)) > 1 - 1e-12)


def test_bvh_and_asf_euler_conventions_by_hand() -> None:
    # Intrinsic "ZX": R = Rz(90) Rx(90). Rx(90) takes y to z; then Rz(90) leaves z alone.
    q = euler_to_q(np.deg2rad([90.0, 90.0]), "ZX")
    np.testing.assert_allclose(qrot(q, [0.0, 1.0, 0.0]), [0.0, 0.0, 1.0], atol=1e-12)
    # Extrinsic "xz" (Acclaim dof order rx rz): x applied first, the same matrix.
    q2 = euler_to_q(np.deg2rad([90.0, 90.0]), "xz")
    np.testing.assert_allclose(q_to_R(q2), q_to_R(q), atol=1e-12)


def _sequences() -> list[str]:
    seqs = []
    for k in (1, 2, 3):
        for axes in itertools.product("xyz", repeat=k):
            if any(a == b for a, b in itertools.pairwise(axes)):
                continue  # scipy refuses an axis repeated in a row
            seqs += ["".join(axes), "".join(axes).upper()]
    return seqs


def test_euler_to_q_is_scipys_from_euler_sign_included(rng: np.random.Generator) -> None:
    for seq in _sequences():  # 1 to 3 axes, intrinsic and extrinsic, Tait-Bryan and proper
        angles = rng.uniform(-7.0, 7.0, size=(4, 50, len(seq)))
        ref = Rotation.from_euler(seq, angles.reshape(-1, len(seq))).as_quat()
        ref = np.concatenate((ref[:, 3:], ref[:, :3]), axis=1).reshape(4, 50, 4)
        np.testing.assert_allclose(euler_to_q(angles, seq), ref, atol=1e-14, err_msg=seq)
    for bad in ("xyzx", "xY", "xw", ""):
        with pytest.raises(ValueError, match="Euler sequence"):
            euler_to_q(np.zeros(len(bad) or 1), bad)
    with pytest.raises(ValueError, match=r"shape \(5, 2\)"):
        euler_to_q(np.zeros((5, 2)), "xyz")
