"""Resampling, mirroring, cutting and foot contacts."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from control.motion import (
    Motion,
    contact_events,
    cut,
    detect_contacts,
    forward_kinematics,
    mirror,
    mirror_map,
    mirrored_rotations,
    qconj,
    qlog,
    qmul,
    read_amc,
    read_asf,
    read_bvh,
    resample,
    resample_positions,
)
from tests.conftest import BVH_DIR, amc_path, asf_path


@pytest.fixture(scope="module")
def walk() -> Motion:
    return read_amc(amc_path("02_01"), read_asf(asf_path("02_01")))


def test_resample_positions_by_hand() -> None:
    np.testing.assert_array_equal(resample_positions(17, 120, 15), [0, 8, 16])
    np.testing.assert_allclose(resample_positions(3, 15, 30), [0, 0.5, 1, 1.5, 2])
    with pytest.raises(ValueError):
        resample_positions(0, 120, 15)


def test_resample_120_to_15_picks_every_eighth_frame(walk: Motion) -> None:
    low = resample(walk, 15)
    assert low.fps == 15 and low.n_frames == 43
    np.testing.assert_allclose(low.quats, walk.quats[::8], atol=1e-12)
    np.testing.assert_allclose(low.root_pos, walk.root_pos[::8], atol=1e-12)


def test_resample_120_15_120_stays_close(walk: Motion) -> None:
    back = resample(resample(walk, 15), 120)
    n = back.n_frames
    assert n == 337  # whole 15 frames/s steps of the 343-frame clip
    pos = forward_kinematics(back).positions
    ref = forward_kinematics(walk).positions[:n]
    err = np.linalg.norm(pos - ref, axis=-1)
    # Walking at 15 frames/s loses little: a few centimetres at the fastest joints.
    assert np.mean(err) < 0.01 and np.max(err) < 0.06, (np.mean(err), np.max(err))


def test_mirroring_twice_is_identity_and_once_reflects(walk: Motion) -> None:
    once = mirror(walk)
    twice = mirror(once)
    assert twice.skeleton.same_as(walk.skeleton, atol=0)
    np.testing.assert_array_equal(twice.quats, walk.quats)
    np.testing.assert_array_equal(twice.root_pos, walk.root_pos)
    partner = mirror_map(walk.skeleton)
    names = walk.skeleton.names
    assert names[partner[names.index("lfemur")]] == "rfemur"
    assert names[partner[names.index("lowerback")]] == "lowerback"
    p0 = forward_kinematics(walk).positions
    p1 = forward_kinematics(once).positions
    np.testing.assert_allclose(p1, p0[:, partner] * [-1, 1, 1], atol=1e-12)
    # a few joints' mirrored rotations, without the rest of the mirrored clip
    some = np.array([names.index("lfemur"), names.index("lowerback")])
    np.testing.assert_array_equal(mirrored_rotations(walk, some), once.quats[:, some])


def test_mirror_bvh_names(mocap: Path) -> None:
    m = read_bvh(BVH_DIR / "02_03.bvh")
    names = m.skeleton.names
    partner = mirror_map(m.skeleton)
    assert names[partner[names.index("lShin")]] == "rShin"
    assert names[partner[names.index("leftEye")]] == "rightEye"
    np.testing.assert_allclose(mirror(mirror(m)).quats, m.quats)


def test_cut(walk: Motion) -> None:
    part = cut(walk, 10, 20)
    assert part.n_frames == 10
    np.testing.assert_array_equal(part.quats, walk.quats[10:20])
    for bad in ((5, 5), (-1, 3), (0, 999)):
        with pytest.raises(ValueError):
            cut(walk, *bad)


def test_contact_events_by_hand() -> None:
    states = np.array([[1, 0], [1, 0], [0, 1], [0, 1], [1, 1]], dtype=bool)
    np.testing.assert_array_equal(contact_events(states), [[2, 0, -1], [2, 1, 1], [4, 0, 1]])


@pytest.mark.parametrize("clip", ["02_01", "02_02", "03_03"])
def test_walking_contacts_alternate_with_the_gait_period(mocap: Path, clip: str) -> None:
    m = resample(read_amc(amc_path(clip), read_asf(asf_path(clip))), 15)
    contacts = detect_contacts(m)
    ev = contacts.events()
    downs = ev[ev[:, 2] == 1]
    assert len(downs) >= 3
    # Touch-downs alternate feet (a long terrain walk with turns may repeat a foot once) ...
    assert np.mean(np.diff(downs[:, 1]) != 0) >= 0.95, downs
    # ... once per gait cycle, whose period we read independently off the ankle height
    # (the foot lifts once per stride): its autocorrelation's first peak past 0.6 s.
    period = _stride_period(m)
    assert 0.8 < period < 2.0
    for foot in (0, 1):
        t = downs[downs[:, 1] == foot, 0] / m.fps
        if len(t) >= 2:
            assert abs(np.median(np.diff(t)) / period - 1) < 0.15, (foot, np.diff(t), period)
    # And every frame of a walk has a foot down, except short flight-like gaps.
    assert contacts.states.any(axis=1).mean() > 0.75


def _stride_period(m: Motion) -> float:
    ankle = forward_kinematics(m).positions[:, m.skeleton.index("lfoot"), 1]
    x = ankle - ankle.mean()
    ac = np.correlate(x, x, mode="full")[x.size - 1 :]
    lo = int(0.6 * m.fps)
    k = lo + int(np.argmax(ac[lo : int(2.5 * m.fps)]))
    return k / m.fps


def test_standing_still_is_in_contact(walk: Motion) -> None:
    still = Motion(
        walk.skeleton, np.repeat(walk.root_pos[:1], 60, 0), np.repeat(walk.quats[:1], 60, 0), 120.0
    )
    assert detect_contacts(still).states.all()


def test_quats_are_local_relative_rotations(walk: Motion) -> None:
    # Global orientation of a child = parent's global * child's local.
    pose = forward_kinematics(walk)
    j = walk.skeleton.index("ltibia")
    p = walk.skeleton.parents[j]
    rel = qmul(qconj(pose.orientations[:, p]), pose.orientations[:, j])
    assert np.allclose(qlog(qmul(qconj(rel), walk.quats[:, j])), 0, atol=1e-9)


def test_the_kinematics_kernel_is_the_numpy_reference_bit_for_bit(
    walk: Motion, rng: np.random.Generator
) -> None:
    from control.motion._fk import _fk, _fk_numpy

    # a real clip, and random rotations (every joint turning, none of them unit-length)
    quats = rng.normal(size=walk.quats.shape)
    for q in (walk.quats, quats):
        got = _fk(walk.skeleton, walk.root_pos, q)
        want = _fk_numpy(walk.skeleton, walk.root_pos, q)
        for a, b in zip(got, want, strict=True):
            assert a.shape == b.shape and np.array_equal(a, b)


@pytest.mark.parametrize("percentile", [0.0, 5.0, 37.5, 50.0, 97.5, 100.0])
def test_group_percentiles_are_numpys(percentile: float) -> None:
    """The contacts' resting heights per ground cell, all cells at once: each group's
    ``np.percentile``, bit for bit; groups under 3 values left out."""
    from control.motion._contacts import _group_percentiles

    rng = np.random.default_rng(int(percentile * 10))
    groups = np.r_[rng.integers(0, 60, 3000), 70, 70, 80, 90, 90, 90]  # 70, 80: too few
    values = np.round(rng.normal(0.1, 0.05, groups.size), 3)  # ties, as heights in mm have
    labels, got = _group_percentiles(groups, values, percentile)
    want = {g: np.percentile(values[groups == g], percentile) for g in np.unique(groups)}
    assert sorted(labels.tolist()) == sorted(g for g in want if (groups == g).sum() >= 3)
    for g, v in zip(labels.tolist(), got.tolist(), strict=True):
        assert np.float64(v).tobytes() == np.float64(want[g]).tobytes(), (g, v, want[g])
