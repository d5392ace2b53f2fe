"""The embedded default library (issue 18): small, faithful to the CMU files, regenerable,
and the default where no other library exists."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import numpy as np
import pytest

from control.artifacts import atomic_write
from control.motion import (
    EMBEDDED_CLIPS,
    EMBEDDED_LIBRARY,
    EMBEDDED_MAX_BYTES,
    MotionFormatError,
    default_library_path,
    embed_library,
    forward_kinematics,
    load_library,
    read_motion_arrays,
    write_motion_arrays,
)
from control.motion import _library as library_module


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in root.rglob("*") if p.is_file()}


def test_the_embedded_library_is_small_and_labelled() -> None:
    files = _files(EMBEDDED_LIBRARY)
    assert sum(len(b) for b in files.values()) <= EMBEDDED_MAX_BYTES
    assert "mocap.cs.cmu.edu" in files["README.md"].decode()
    lib = load_library(EMBEDDED_LIBRARY)
    assert [c.name for c in lib.clips] == sorted(EMBEDDED_CLIPS)
    labelled = {c.name for c in lib.clips if (c.labels >= 0).any()}
    assert labelled == {"13_29", "13_30", "13_31"}
    assert lib.clip("13_29").description.startswith("exercise")


def test_the_embedded_library_is_the_cmu_motion(mocap: Path) -> None:
    ours = load_library(EMBEDDED_LIBRARY, fps=15)
    theirs = load_library(mocap, fps=15, clips=list(EMBEDDED_CLIPS))
    for a, b in zip(ours.clips, theirs.clips, strict=True):
        assert a.name == b.name and a.motion.n_frames == b.motion.n_frames
        pa = forward_kinematics(a.motion).positions
        pb = forward_kinematics(b.motion).positions
        assert np.abs(pa - pb).max() < 1e-5  # float32 storage: well under a millimetre
        np.testing.assert_array_equal(a.labels, b.labels)
        assert a.label_names == b.label_names


def test_the_embedded_library_regenerates_byte_for_byte(mocap: Path, tmp_path: Path) -> None:
    out = tmp_path / "lib"
    embed_library(mocap, out)
    assert _files(out) == _files(EMBEDDED_LIBRARY)
    embed_library(mocap, out, clips=["02_01"])  # regenerating replaces the whole folder
    assert sorted(_files(out)) == ["02_01.motion.npz", "README.md"]
    with pytest.raises(FileNotFoundError, match="no clip named 99_99"):
        embed_library(mocap, tmp_path / "other", clips=["02_01", "99_99"])


def test_it_is_the_default_where_no_other_library_exists(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.delenv("MIMIC_MOCAP", raising=False)
    monkeypatch.setattr(library_module, "shared_library_candidates", lambda: (tmp_path / "no",))
    assert default_library_path() == EMBEDDED_LIBRARY
    monkeypatch.setenv("MIMIC_MOCAP", str(tmp_path))
    assert default_library_path() == tmp_path


def test_bad_motion_arrays_name_the_file(tmp_path: Path) -> None:
    good = read_motion_arrays(EMBEDDED_LIBRARY / "02_01.motion.npz")
    path = tmp_path / "x.motion.npz"
    write_motion_arrays(path, good)
    again = read_motion_arrays(path)
    np.testing.assert_allclose(again.quats, good.quats, atol=1e-6)
    data = bytearray(path.read_bytes())
    path.write_bytes(bytes(data[: len(data) // 2]))
    with pytest.raises(MotionFormatError, match=r"x\.motion\.npz"):
        read_motion_arrays(path)
    np.savez(path, meta=np.array('{"format": "other"}'))
    with pytest.raises(MotionFormatError, match="missing"):
        read_motion_arrays(path)
    # a library folder with a broken arrays file names it
    (tmp_path / "lib").mkdir()
    path.rename(tmp_path / "lib" / "y.motion.npz")
    with pytest.raises(MotionFormatError, match=r"y\.motion\.npz"):
        load_library(tmp_path / "lib", use_cache=False)


def test_written_files_keep_the_umask(tmp_path: Path) -> None:
    old = os.umask(0o022)
    try:
        with atomic_write(tmp_path / "a.txt") as fh:
            fh.write("x")
        os.umask(0o077)
        with atomic_write(tmp_path / "b.txt") as fh:
            fh.write("x")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "a.txt").stat().st_mode) == 0o644
    assert stat.S_IMODE((tmp_path / "b.txt").stat().st_mode) == 0o600
