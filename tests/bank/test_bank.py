"""The bank on disk: shards, parallel build, resume, staleness, bad files, the CLI."""

from __future__ import annotations

import dataclasses
import json
import threading
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest

from control.artifacts import build_lock, is_locked
from control.motion import Library
from mimic.cli import main
from silhouette_bank import (
    POSE_JOINTS,
    BankFileError,
    BankSettings,
    BodyShape,
    StaleBankError,
    build_bank,
    capsule_body,
    ensure_bank,
    lda_directions,
    learn_metric,
    load_bank,
    motion_features,
    robust_settings,
)
from silhouette_bank._bank import FEATURE_DTYPE
from silhouette_bank._descriptor import SHIN_RATIO, THIGH_RATIO
from silhouette_bank._features import feature_size
from tests.bank.conftest import SMALL


def test_bank_holds_every_frame_and_view(lib: Library, tmp_path: Path) -> None:
    bank = build_bank(lib.clips, SMALL, tmp_path / "b", shard_frames=40, workers=1)
    assert bank.features.shape == (103, 6, 9) and bank.root_motion.shape == (103, 6, 2)
    assert bank.clip_names == ("02_01", "02_02", "02_03")
    # the same numbers as rendering one clip directly, stored at half precision
    clip = lib.clip("02_02")
    f, m = motion_features(clip.motion, capsule_body(clip.motion.skeleton), SMALL.ring)
    k = bank.frame_of("02_02", 0)
    assert bank.features.dtype == np.float16 == FEATURE_DTYPE and f.dtype == np.float32
    np.testing.assert_array_equal(bank.features[k : k + clip.motion.n_frames], f.astype(np.float16))
    np.testing.assert_array_equal(bank.root_motion[k : k + clip.motion.n_frames], m)
    # two processes give the same bank
    par = build_bank(lib.clips, SMALL, tmp_path / "p", shard_frames=40, workers=2)
    np.testing.assert_array_equal(par.features, bank.features)


class _Interrupt(Exception):
    pass


def _stop_at(n: int) -> Callable[[int, int], None]:
    """A progress callback that stops a build once ``n`` shards are done (it is called
    once before the first, then once a job)."""
    calls = [0]

    def progress(done: int, total: int) -> None:
        calls[0] += 1
        if calls[0] == n + 1:
            raise _Interrupt

    return progress


def test_resume_only_redoes_missing_or_broken_shards(lib: Library, tmp_path: Path) -> None:
    folder = tmp_path / "b"
    with pytest.raises(_Interrupt):  # a stop in the middle of the build
        build_bank(lib.clips, SMALL, folder, shard_frames=30, workers=1, progress=_stop_at(3))
    shards = sorted(folder.glob("shard-*.npz"))
    assert len(shards) == 3
    with pytest.raises(BankFileError, match="incomplete"):
        load_bank(folder)
    shards[1].unlink()
    shards[2].write_bytes(shards[2].read_bytes()[:100])  # truncated by a crash
    seen: list[int] = []
    build_bank(
        lib.clips, SMALL, folder, shard_frames=30, workers=1, progress=lambda d, t: seen.append(d)
    )
    manifest = json.loads((folder / "manifest.json").read_text())
    assert manifest["complete"] and manifest["built"]["rendered_shards"] == 3
    assert seen[0] == 30 * SMALL.n_views  # shard 0 (30 frames) was kept
    assert not list(folder.glob("shard-*.npz"))  # merged, then removed
    fresh = build_bank(lib.clips, SMALL, tmp_path / "fresh", shard_frames=30, workers=1)
    np.testing.assert_array_equal(load_bank(folder).features, fresh.features)


def test_a_shard_with_a_flipped_byte_is_rendered_again(lib: Library, tmp_path: Path) -> None:
    folder = tmp_path / "b"
    with pytest.raises(_Interrupt):
        build_bank(lib.clips, SMALL, folder, shard_frames=30, workers=1, progress=_stop_at(2))
    shard = sorted(folder.glob("shard-*.npz"))[0]
    data = bytearray(shard.read_bytes())
    data[len(data) - 200] ^= 0x10  # inside the root motion: still a valid zip of arrays
    shard.write_bytes(bytes(data))
    build_bank(lib.clips, SMALL, folder, shard_frames=30, workers=1)
    manifest = json.loads((folder / "manifest.json").read_text())
    assert manifest["built"]["rendered_shards"] == 3  # of 4: the damaged one again
    fresh = build_bank(lib.clips, SMALL, tmp_path / "fresh", shard_frames=30, workers=1)
    np.testing.assert_array_equal(load_bank(folder).root_motion, fresh.root_motion)


def test_stale_and_broken_banks(lib: Library, tmp_path: Path) -> None:
    folder = tmp_path / "b"
    build_bank(lib.clips, SMALL, folder, shard_frames=50, workers=1)
    other = dataclasses.replace(SMALL, body=BodyShape(width=1.2))
    with pytest.raises(StaleBankError, match="other render settings"):
        load_bank(folder, settings=other)
    with pytest.raises(StaleBankError, match="another motion library"):
        load_bank(folder, clips=lib.clips[:2])
    bank, built = ensure_bank(lib.clips, other, folder, shard_frames=50, workers=1)
    assert built and bank.settings == other  # rebuilt, not used
    bank, built = ensure_bank(lib.clips, other, folder, shard_frames=50, workers=1)
    assert not built
    np.testing.assert_array_equal(load_bank(folder).features, bank.features)
    assert isinstance(load_bank(folder).features, np.memmap)  # opened, not read in
    # a byte of a block changed: the frames of that block are named
    data = (folder / "features.npy").read_bytes()
    flipped = bytearray(data)
    flipped[-5] ^= 0x40
    (folder / "features.npy").write_bytes(bytes(flipped))
    n = bank.n_frames
    with pytest.raises(BankFileError, match=rf"features\.npy: frames 0-{n - 1}: checksum mismatch"):
        load_bank(folder)
    (folder / "features.npy").write_bytes(data[: len(data) // 2])
    with pytest.raises(BankFileError, match=r"features\.npy: unreadable, truncated or damaged"):
        load_bank(folder)
    (folder / "features.npy").write_bytes(data)
    (folder / "root_motion.npy").unlink()
    with pytest.raises(BankFileError, match=r"root_motion\.npy: missing"):
        load_bank(folder)
    data = (folder / "bank.npz").read_bytes()
    (folder / "bank.npz").write_bytes(data[: len(data) // 3])
    with pytest.raises(BankFileError, match=r"bank\.npz: unreadable, truncated or damaged"):
        load_bank(folder)
    manifest = json.loads((folder / "manifest.json").read_text())
    manifest["complete"] = False
    (folder / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(BankFileError, match="incomplete"):
        load_bank(folder)
    (folder / "manifest.json").write_text("{not json")
    with pytest.raises(BankFileError, match="unreadable manifest"):
        load_bank(folder)
    with pytest.raises(FileNotFoundError):
        load_bank(tmp_path / "nowhere")


@pytest.mark.gl
def test_gl_bank_agrees_with_raster(lib: Library, tmp_path: Path) -> None:
    gl = dataclasses.replace(SMALL, renderer="gl")
    a = build_bank(lib.clips[:1], gl, tmp_path / "gl", workers=1)
    b = build_bank(lib.clips[:1], SMALL, tmp_path / "r", workers=1)
    assert np.abs(a.features[..., :2] - b.features[..., :2]).mean() < 0.05
    assert np.abs(a.features[..., 7:] - b.features[..., 7:]).mean() < 0.01


@pytest.mark.slow
def test_cli_build_info_show(
    mocap: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = tmp_path / "bank"
    common = [str(mocap), "--clips", "02_03", "--views", "6", "--width", "80", "--height", "60"]
    assert main(["bank", "build", *common, "--bank", str(folder), "--workers", "1"]) == 0
    assert "(built)" in capsys.readouterr().out
    assert main(["bank", "build", *common, "--bank", str(folder), "--workers", "1"]) == 0
    assert "(up to date)" in capsys.readouterr().out
    assert main(["bank", "info", str(folder), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["frames"] == 22 and info["views"] == 6 and info["empty_silhouettes"] == 0
    out = tmp_path / "sheet.png"
    assert main(["bank", "show", "02_03:10", *common, "--out", str(out)]) == 0
    sheet = cv2.imread(str(out), cv2.IMREAD_GRAYSCALE)
    assert sheet.shape == (62, 6 * 82) and (sheet == 255).sum() > 100
    assert main(["bank", "show", "02_03:99", *common, "--out", str(out)]) == 2
    assert "no frame 99" in capsys.readouterr().err
    assert main(["bank", "info", str(tmp_path / "none")]) == 2


def test_variants_are_more_views_of_other_bodies_and_shadows(lib: Library, tmp_path: Path) -> None:
    settings = dataclasses.replace(SMALL, bodies=(BodyShape(width=1.25),), shadow=True)
    assert [(b.width, s) for b, s in settings.variants] == [
        (1.0, False),
        (1.25, False),
        (1.0, True),
        (1.25, True),
    ]
    bank = build_bank(lib.clips, settings, tmp_path / "v", shard_frames=60, workers=1)
    assert bank.features.shape == (103, 24, 9) and settings.n_views == 24
    plain = build_bank(lib.clips, SMALL, tmp_path / "p", shard_frames=60, workers=1)
    # the first block of views is the plain bank; the wider body is another silhouette
    np.testing.assert_array_equal(bank.features[:, :6], plain.features)
    assert not np.allclose(bank.features[:, 6:12, :7], plain.features[..., :7])
    # a shadow at the feet lowers the silhouette's centroid (y up) in every view
    drop = bank.features[:, 12:18, 8] - plain.features[..., 8]
    assert np.all(drop < 0)
    # the settings survive the manifest, and a plain bank's key is unchanged by them
    assert BankSettings.from_dict(settings.to_dict()) == settings
    assert "shadow" not in SMALL.to_dict() and "descriptor" not in SMALL.to_dict()
    assert robust_settings().n_views == 18 * 8
    with pytest.raises(ValueError, match="raster renderer only"):
        BankSettings(renderer="gl", shadow=True)


def test_a_grid_bank_holds_grid_features(lib: Library, tmp_path: Path) -> None:
    settings = dataclasses.replace(SMALL, descriptor="grid")
    bank = build_bank(lib.clips, settings, tmp_path / "g", shard_frames=60, workers=1)
    assert bank.features.shape == (103, 6, feature_size("grid")) and bank.settings == settings
    assert load_bank(tmp_path / "g", lib.clips, settings).features.shape[-1] == feature_size("grid")
    plain = build_bank(lib.clips, SMALL, tmp_path / "p", shard_frames=60, workers=1)
    # the same silhouettes: the centre is the same, the shape numbers are the grid's
    np.testing.assert_allclose(bank.features[..., -2:], plain.features[..., -2:])
    assert np.all((bank.features[..., :-2] >= 0) & (bank.features[..., :-2] <= 1))
    # the outline is the default; the descriptor is part of the key; a Hu bank's
    # settings do not name it (banks from before the grid keep their key)
    assert BankSettings().descriptor == "outline"
    assert settings.digest() != SMALL.digest() and "descriptor" not in SMALL.to_dict()
    assert BankSettings.from_dict(settings.to_dict()) == settings
    with pytest.raises(StaleBankError):
        load_bank(tmp_path / "g", lib.clips, SMALL)
    with pytest.raises(ValueError, match="descriptor must be one of"):
        BankSettings(descriptor="zernike")


@pytest.mark.parametrize("name", ["hu", "grid", "multigrid", "pose", "outline"])
def test_every_descriptor_round_trips_through_the_bank(
    lib: Library, tmp_path: Path, name: str
) -> None:
    settings = dataclasses.replace(SMALL, descriptor=name)
    clips = lib.clips[:1]  # one clip (43 frames): a learned metric renders it 24 times
    bank = build_bank(clips, settings, tmp_path / name, shard_frames=20, workers=1)
    again = load_bank(tmp_path / name, clips, settings)
    assert bank.settings.features.name == name == again.settings.descriptor
    assert again.features.shape == (clips[0].motion.n_frames, 6, feature_size(name))
    np.testing.assert_array_equal(again.features, bank.features)
    assert np.isfinite(bank.features).all() and np.isfinite(bank.root_motion).all()
    # the grids' banks hold their learned metric; the others none
    learned = name in ("multigrid", "outline")
    assert (again.metric is not None) == learned == (settings.metric_dims > 0)
    if again.metric is not None and bank.metric is not None:
        assert again.metric[1].shape == (settings.features.n_shape, settings.metric_dims)
        np.testing.assert_array_equal(again.metric[1], bank.metric[1])
    # the descriptor is part of the key: another one's bank is stale
    other = "hu" if name != "hu" else "grid"
    with pytest.raises(StaleBankError):
        load_bank(tmp_path / name, clips, dataclasses.replace(SMALL, descriptor=other))


def test_a_pose_bank_projects_the_joints(lib: Library, tmp_path: Path) -> None:
    from control.motion import forward_kinematics, role_point

    settings = dataclasses.replace(SMALL, descriptor="pose")
    bank = build_bank(lib.clips, settings, tmp_path / "pose", shard_frames=50, workers=1)
    clip = lib.clip("02_01")
    k = bank.frame_of("02_01", 10)
    pose = forward_kinematics(clip.motion)
    root = clip.motion.root_pos[10]
    cam_pose = settings.ring.poses(root)
    for v in (0, 3):  # front (camera on +Z) and back
        pts = np.stack(
            [pose.positions[10, role_point(clip.motion.skeleton, r)[1]] for r in POSE_JOINTS]
        )
        px = settings.ring.project(settings.ring.to_camera(pts, cam_pose[v]))
        hip = px[6:8].mean(axis=0)
        scale = max(
            [float(np.linalg.norm(px[:2].mean(axis=0) - hip))]
            + [float(np.linalg.norm(px[6 + i] - px[8 + i])) / THIGH_RATIO for i in (0, 1)]
            + [float(np.linalg.norm(px[8 + i] - px[10 + i])) / SHIN_RATIO for i in (0, 1)]
        )
        got = bank.features[k, v]
        # every joint relative to the mid-hip, in torso lengths, y up
        want = ((px - hip) / scale * [1, -1]).ravel()
        np.testing.assert_allclose(got[:24], want, atol=1e-3)  # (stored at half precision)
        # the root's image motion since the last frame, in the same torso lengths
        assert settings.features.scale(px) == pytest.approx(scale)
        now, before = (
            settings.ring.project(
                settings.ring.to_camera(clip.motion.root_pos[f][None], cam_pose[v])
            )[0]
            for f in (10, 9)
        )
        moved = (now - before) / scale * [1, -1]
        np.testing.assert_allclose(bank.root_motion[k, v], moved, atol=1e-4)
    # seen from the front (view 0: the camera on +Z, the subject facing it or not) and
    # from behind, left and right trade sides of the image
    assert np.sign(bank.features[k, 0, 0] - bank.features[k, 0, 2]) != np.sign(
        bank.features[k, 3, 0] - bank.features[k, 3, 2]
    )
    with pytest.raises(ValueError, match="pose bank projects joints"):
        BankSettings(descriptor="pose", shadow=True)


def test_the_learned_metric_discounts_the_body_and_keeps_the_pose(lib: Library) -> None:
    """Same frame and view, other body widths: near under the metric; other frames: far
    (measured against the plain standardised cells)."""
    ring = SMALL.ring
    clip = lib.clip("02_03")  # a run: every frame another pose
    mean, proj = learn_metric([clip], "multigrid", ring, BodyShape(), 24)
    assert proj.shape == (168, 24) and np.isfinite(proj).all()
    frames = np.arange(0, clip.motion.n_frames, 2)

    def cells(width: float) -> np.ndarray:
        body = capsule_body(clip.motion.skeleton, BodyShape(width=width))
        f, _ = motion_features(clip.motion, body, ring, frames, descriptor="multigrid")
        return f[..., :168].reshape(-1, 168).astype(float)

    a, b = cells(1.0), cells(1.2)  # the same poses, a heavier body

    def ratio(z: np.ndarray, w: np.ndarray) -> float:
        same = np.linalg.norm(z - w, axis=1).mean()
        other = np.linalg.norm(z - np.roll(z, 7, axis=0), axis=1).mean()
        return float(same / other)

    plain = ratio(a, b)
    learned = ratio((a - mean) @ proj, (b - mean) @ proj)
    assert learned < 0.7 * plain


@pytest.mark.parametrize(("classes", "numbers", "per"), [(40, 12, 5), (300, 30, 3)])
def test_lda_directions_are_scikit_learns(classes: int, numbers: int, per: int) -> None:
    """The one-pass solution against scikit-learn's LinearDiscriminantAnalysis (eigen
    solver, the same shrinkage), on classes of unequal sizes and correlated spread."""
    from sklearn.discriminant_analysis import LinearDiscriminantAnalysis

    rng = np.random.default_rng(classes)
    centres = rng.normal(size=(classes, numbers)) * rng.uniform(0.1, 3.0, size=numbers)
    y = np.repeat(np.arange(classes), per)
    y = np.concatenate((y, rng.integers(0, classes, size=classes)))  # unequal sizes
    x = centres[y] + 0.3 * rng.normal(size=(y.size, numbers)) @ rng.normal(size=(numbers,) * 2)
    want = LinearDiscriminantAnalysis(solver="eigen", shrinkage=1e-3).fit(x, y).scalings_[:, :6]
    got = lda_directions(x, rng.permutation(classes)[y], 6)  # the class names do not matter
    sign = np.sign((want * got).sum(axis=0))  # an eigenvector's sign is arbitrary
    np.testing.assert_allclose(got * sign, want, atol=1e-9 * np.abs(want).max())
    with pytest.raises(ValueError, match="dims must be in 1"):
        lda_directions(x, y, numbers + 1)


def test_a_bank_another_process_builds_is_waited_for_then_loaded(
    lib: Library, tmp_path: Path
) -> None:
    folder = tmp_path / "shared"
    got: dict[str, bool] = {}

    def meanwhile() -> None:
        got["built"] = ensure_bank(lib.clips, SMALL, folder, workers=1)[1]

    with build_lock(folder):  # the other process: building
        waiter = threading.Thread(target=meanwhile)
        waiter.start()
        build_bank(lib.clips, SMALL, folder, shard_frames=60, workers=1)
        time.sleep(0.1)
        assert waiter.is_alive() and is_locked(folder)  # waiting for the lock
    waiter.join(timeout=60)
    assert got == {"built": False} and not is_locked(folder)


def test_a_damaged_block_is_named_by_its_frames(
    lib: Library, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import silhouette_bank._bank as bank_module

    monkeypatch.setattr(bank_module, "BLOCK_ROWS", 16)
    folder = tmp_path / "b"
    bank = build_bank(lib.clips, SMALL, folder, shard_frames=50, workers=1)
    blocks = json.loads((folder / "manifest.json").read_text())["blocks"]
    assert blocks["rows"] == 16 and len(blocks["features"]) == -(-bank.n_frames // 16)
    feats = np.load(folder / "root_motion.npy", mmap_mode="r+")
    was = feats[40, 0, 0].copy()
    feats[40, 0, 0] += 1.0  # frame 40: the third block
    feats.flush()
    del feats
    with pytest.raises(BankFileError, match=r"root_motion\.npy: frames 32-47: checksum mismatch"):
        load_bank(folder)
    monkeypatch.setattr(bank_module, "BLOCK_ROWS", 4096)  # a bank is read with its own blocks
    feats = np.load(folder / "root_motion.npy", mmap_mode="r+")
    feats[40, 0, 0] = was
    feats.flush()
    del feats
    np.testing.assert_array_equal(load_bank(folder).root_motion, bank.root_motion)


def test_an_unchanged_bank_is_opened_without_reading_it(
    lib: Library, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import silhouette_bank._arrays as arrays

    folder = tmp_path / "b"
    bank = build_bank(lib.clips, SMALL, folder, shard_frames=50, workers=1)
    hashed: list[int] = []
    real = arrays.block_hash

    def counting(a: np.ndarray, k: int, rows: int) -> str:
        hashed.append(k)
        return real(a, k, rows)

    monkeypatch.setattr(arrays, "block_hash", counting)
    # just written: too soon after the change for its file times to be trusted
    load_bank(folder)
    assert hashed and not (folder / "checked.json").exists()
    # a check long after the last change (as when it comes seconds later) is remembered,
    # and the next open reads no block
    monkeypatch.setattr(arrays, "RACY_NS", -(10**18))
    load_bank(folder)
    assert (folder / "checked.json").is_file()
    hashed.clear()
    again = load_bank(folder)
    assert hashed == []
    np.testing.assert_array_equal(again.features, bank.features)
    # a write changes what the file system says of it: checked again, and the damage named
    feats = np.load(folder / "features.npy", mmap_mode="r+")
    feats[3, 0, 0] += 1.0
    feats.flush()
    del feats
    with pytest.raises(BankFileError, match=r"features\.npy: frames 0-.*checksum mismatch"):
        load_bank(folder)
    assert hashed
    # a damaged record is no record
    (folder / "checked.json").write_text("{not json")
    with pytest.raises(BankFileError, match="checksum mismatch"):
        load_bank(folder)
