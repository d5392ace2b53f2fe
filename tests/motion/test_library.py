"""The library loader: discovery, metadata, labels, the cache; and `mimic library info`."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from control.motion import Library, MotionFormatError, _parsed, load_library, read_labels
from mimic.cli import main
from tests.conftest import BVH_DIR, SUBJECTS


@pytest.fixture
def small_lib(tmp_path: Path, mocap: Path) -> Path:
    """A private copy of a few small clips in both formats, with labels and a README."""
    root = tmp_path / "lib"
    (root / "asf").mkdir(parents=True)
    for name in ("02.asf", "02_03.amc", "02_04.amc"):
        shutil.copy(SUBJECTS / "02" / name, root / "asf" / name)
    (root / "bvh").mkdir()
    for name in ("02_03.bvh", "09_01.bvh"):
        shutil.copy(BVH_DIR / name, root / "bvh" / name)
    (root / "labels").mkdir()
    (root / "labels" / "02_03.csv").write_text(
        "first_frame,last_frame,action\n1,96,Jog\n97,180,Stop\n"  # runs past 173: clamped
    )
    (root / "README.md").write_text(
        "| clip | frames | description |\n|---|---|---|\n| 02_03..02_04 | 1, 2 | jog or jump |\n"
        "| 09_01 (BVH only) | | run |\n"
    )
    return root


def test_loads_both_formats_prefers_amc(small_lib: Path, tmp_path: Path) -> None:
    lib = load_library(small_lib, fps=15, cache_dir=tmp_path / "c", workers=1)
    assert [c.name for c in lib.clips] == ["02_03", "02_04", "09_01"]
    assert lib.clip("02_03").path.endswith(".amc")
    assert lib.clip("09_01").motion.skeleton.n_joints == 43
    assert lib.clip("02_04").description == "jog or jump"
    assert lib.clip("09_01").description == "run"
    assert all(c.motion.fps == 15 for c in lib.clips)
    jog = lib.clip("02_03")
    assert jog.label_names == ("Jog", "Stop")
    # Source frame 95 (0-based) is the last Jog frame; frame 96 the first Stop frame.
    k = int(np.searchsorted(jog.source_frames, 96))
    assert jog.label_at(k - 1) == "Jog" and jog.label_at(k) == "Stop"
    assert jog.label_at(jog.motion.n_frames - 1) == "Stop"
    bvh = load_library(small_lib, fps=None, prefer="bvh", cache_dir=tmp_path / "c", workers=1)
    assert bvh.clip("02_03").path.endswith(".bvh")
    assert bvh.clip("02_03").motion.n_frames == 174


def test_mirror_adds_copies(small_lib: Path, tmp_path: Path) -> None:
    lib = load_library(small_lib, mirror=True, cache_dir=tmp_path / "c", workers=1)
    names = [c.name for c in lib.clips]
    assert names == ["02_03", "02_03_mirror", "02_04", "02_04_mirror", "09_01", "09_01_mirror"]
    assert lib.clip("02_03_mirror").mirrored
    assert lib.clip("02_03_mirror").label_names == ("Jog", "Stop")
    # the matcher's library: the labelled clips' copies only (the same actions done with
    # the other arm and leg); an unlabelled copy would be one more unnamed action
    labelled = load_library(small_lib, mirror="labelled", cache_dir=tmp_path / "c", workers=1)
    assert [c.name for c in labelled.clips] == ["02_03", "02_03_mirror", "02_04", "09_01"]
    with pytest.raises(ValueError, match="mirror must be"):
        load_library(small_lib, mirror="some", cache_dir=tmp_path / "c", workers=1)


def _entries(cache: Path) -> list[Path]:
    """The parsed files' cache entries (not the whole library's)."""
    return [p for p in cache.glob("*.npz") if not p.name.startswith("library-")]


def test_cache_hit_skips_parsing_and_a_changed_file_is_reparsed(
    small_lib: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    cache = tmp_path / "c"
    first = load_library(small_lib, cache_dir=cache, workers=1)
    assert len(_entries(cache)) == 3 and len(list(cache.glob("library-*.npz"))) == 1

    def no_parse(*args: object) -> None:
        raise AssertionError("parsed although cached")

    monkeypatch.setattr(_parsed, "parse", no_parse)
    warm = load_library(small_lib, cache_dir=cache, workers=1)
    for a, b in zip(first.clips, warm.clips, strict=True):
        np.testing.assert_array_equal(a.motion.quats, b.motion.quats)
        assert a.motion.skeleton.same_as(b.motion.skeleton, atol=0)
    monkeypatch.undo()
    # Edit one value of one file: its entry is stale, the file is parsed again.
    amc = small_lib / "asf" / "02_04.amc"
    amc.write_bytes(amc.read_bytes().replace(b"\r\n1\r\nroot ", b"\r\n1\r\nroot 1", 1))
    parsed: list[str] = []
    real = _parsed.parse
    monkeypatch.setattr(_parsed, "parse", lambda src, u: parsed.append(src.name) or real(src, u))
    changed = load_library(small_lib, cache_dir=cache, workers=1)
    assert parsed == ["02_04"]
    assert not np.allclose(
        changed.clip("02_04").motion.root_pos[0], first.clip("02_04").motion.root_pos[0]
    )


def test_two_files_of_the_same_bytes_keep_their_own_names_from_the_cache(
    small_lib: Path, tmp_path: Path
) -> None:
    """A copy of a file under another name shares its cache entry (the key is the
    bytes), but a warm load names each clip by its own file, as the cold load did."""
    shutil.copy(small_lib / "bvh" / "09_01.bvh", small_lib / "bvh" / "99_01.bvh")
    cache = tmp_path / "c"
    cold = load_library(small_lib, cache_dir=cache, workers=1)
    warm = load_library(small_lib, cache_dir=cache, workers=1)
    assert len(_entries(cache)) == 3  # the two copies: one entry
    for lib in (cold, warm):
        assert [c.name for c in lib.clips] == ["02_03", "02_04", "09_01", "99_01"]
        assert lib.clip("99_01").motion.source.endswith("99_01.bvh")
        assert lib.clip("09_01").motion.source.endswith("09_01.bvh")


def test_corrupt_cache_entry_is_reparsed(
    small_lib: Path, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    cache = tmp_path / "c"
    load_library(small_lib, cache_dir=cache, workers=1)
    for p in cache.glob("*.npz"):
        p.write_bytes(p.read_bytes()[:100])
    lib = load_library(small_lib, cache_dir=cache, workers=1)
    assert len(lib.clips) == 3
    assert caplog.text.count("ignoring a bad motion cache entry") == 3
    assert caplog.text.count("ignoring a bad library cache entry") == 1
    # ... and rewritten whole.
    caplog.clear()
    assert len(load_library(small_lib, cache_dir=cache, workers=1).clips) == 3
    assert "ignoring" not in caplog.text


def _same(a: Library, b: Library) -> None:
    """Two libraries hold the same clips, array for array."""
    assert [c.name for c in a.clips] == [c.name for c in b.clips]
    for x, y in zip(a.clips, b.clips, strict=True):
        assert x.motion.skeleton.same_as(y.motion.skeleton, atol=0)
        assert x.motion.skeleton.channels == y.motion.skeleton.channels
        for f in ("root_pos", "quats"):
            np.testing.assert_array_equal(getattr(x.motion, f), getattr(y.motion, f))
        np.testing.assert_array_equal(x.contacts.states, y.contacts.states)
        assert (x.contacts.ankle_rest, x.contacts.toe_rest) == (
            y.contacts.ankle_rest,
            y.contacts.toe_rest,
        )
        np.testing.assert_array_equal(x.labels, y.labels)
        np.testing.assert_array_equal(x.source_frames, y.source_frames)
        assert (x.motion.fps, x.motion.source, x.path, x.mirrored, x.description) == (
            y.motion.fps,
            y.motion.source,
            y.path,
            y.mirrored,
            y.description,
        )
        assert x.label_names == y.label_names


def test_a_warm_load_reads_the_whole_library_as_made(
    small_lib: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from control.motion import _library

    cache = tmp_path / "c"
    made = load_library(small_lib, mirror=True, cache_dir=cache, workers=1)
    _same(made, load_library(small_lib, mirror=True, use_cache=False, workers=1))

    def no_work(*args: object) -> None:
        raise AssertionError("a clip was made again although the library is cached")

    for name in ("load_cached", "detect_contacts", "resample"):
        monkeypatch.setattr(_library, name, no_work)
    warm = load_library(small_lib, mirror=True, cache_dir=cache, workers=1)
    _same(made, warm)
    # labels are read from their files on every load: an edited label file is seen
    (small_lib / "labels" / "02_03.csv").write_text("first_frame,last_frame,action\n1,9,Walk\n")
    relabelled = load_library(small_lib, mirror=True, cache_dir=cache, workers=1)
    assert relabelled.clip("02_03").label_names == ("Walk",)
    monkeypatch.undo()
    # other options make other clips: another entry
    load_library(small_lib, fps=30, cache_dir=cache, workers=1)
    assert len(list(cache.glob("library-*.npz"))) == 2


def test_parallel_cold_load_matches_serial(small_lib: Path, tmp_path: Path) -> None:
    a = load_library(small_lib, use_cache=False, workers=1)
    b = load_library(small_lib, use_cache=False, workers=2)
    for x, y in zip(a.clips, b.clips, strict=True):
        np.testing.assert_array_equal(x.motion.quats, y.motion.quats)


def test_bad_library_inputs(tmp_path: Path, small_lib: Path) -> None:
    (tmp_path / "empty").mkdir()
    with pytest.raises(MotionFormatError, match=r"no \.amc, \.bvh or \.motion\.npz clips"):
        load_library(tmp_path / "empty")
    (small_lib / "asf" / "02.asf").unlink()
    with pytest.raises(MotionFormatError, match="no ASF skeleton"):
        load_library(small_lib, use_cache=False)


def test_a_library_folder_that_cannot_be_read_is_named(
    small_lib: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # (a folder of mode 000 for a user; root reads it anyway, so the refusal is made here)
    import os

    real = os.scandir

    def scandir(path: object) -> object:
        if Path(str(path)).name == "bvh":
            raise PermissionError(13, "Permission denied", str(path))
        return real(path)  # type: ignore[arg-type]

    monkeypatch.setattr(os, "scandir", scandir)
    with pytest.raises(MotionFormatError, match=r"bvh: cannot read this folder of the library"):
        load_library(small_lib, use_cache=False)


def test_folders_linked_into_a_library_are_read_once(small_lib: Path, tmp_path: Path) -> None:
    # the data kept elsewhere, linked in (twice, and with a link back up the tree): every
    # clip, label and description is found, none twice, and the loop ends
    root = tmp_path / "linked"
    root.mkdir()
    for name in ("asf", "bvh", "labels", "README.md"):
        (root / name).symlink_to(small_lib / name)
    (root / "again").symlink_to(small_lib / "asf")
    (small_lib / "asf" / "up").symlink_to(small_lib)  # a loop, reached through the link
    lib = load_library(root, fps=15, cache_dir=tmp_path / "c", workers=1)
    assert [c.name for c in lib.clips] == ["02_03", "02_04", "09_01"]
    jog = lib.clip("02_03")
    assert jog.label_names == ("Jog", "Stop") and jog.description == "jog or jump"


def test_label_file_errors(tmp_path: Path) -> None:
    p = tmp_path / "l.csv"
    for text, line, words in (
        ("first,last,action\n", 1, "header"),
        ("first_frame,last_frame,action\n1,x,Jog\n", 2, "whole numbers"),
        ("first_frame,last_frame,action\n5,2,Jog\n", 2, "bad frame range"),
        ("first_frame,last_frame,action\n1,10,Jog\n5,12,Squat\n", 3, "overlaps"),
        ("first_frame,last_frame,action\n500,510,Jog\n", 2, "starts at frame 500"),
    ):
        p.write_text(text)
        with pytest.raises(MotionFormatError, match=words) as info:
            read_labels(p, 100)
        assert info.value.line == line


def test_real_labels_clamp_the_last_block(mocap: Path) -> None:
    labels, names = read_labels(mocap / "cmu" / "labels" / "13_29.csv", 4592)
    assert names[0] == "JumpJack" and "Squat" in names
    assert labels[0] == 0 and labels[-1] == names.index("Squat")
    assert np.all(labels >= 0)


@pytest.mark.slow  # (a whole command)
def test_cli_library_info(small_lib: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["library", "info", str(small_lib), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["clips"] == 3 and out["fps"] == 15
    assert out["frames"] == sum(c["frames"] for c in out["per_clip"])
    assert 0 < out["contact_fraction"]["left"] < 1
    # how long mimic perform's cold build would take here, for the clips it would keep
    est = out["cold_build_estimate"]
    assert 0 < est["frames"] <= out["frames"] and est["render_rate"] > 0 and est["workers"] >= 1
    parts = ("graph", "higher layer", "bank", "search index")
    assert est["total"] == pytest.approx(sum(est[k] for k in parts), abs=0.3)
    assert main(["library", "info", str(small_lib)]) == 0
    text = capsys.readouterr().out
    assert "02_03" in text and "3 clips" in text
    assert f"a cold build here (mimic perform from an empty cache, {est['frames']} frames" in text
    assert main(["library", "info", str(small_lib), "--json", "--workers", "8"]) == 0
    assert json.loads(capsys.readouterr().out)["cold_build_estimate"]["workers"] == 8
    assert main(["library", "info", str(small_lib / "nowhere")]) == 2
    assert "is not a directory" in capsys.readouterr().err


def test_parse_error_in_a_worker_names_the_file(small_lib: Path) -> None:
    bad = small_lib / "asf" / "02_04.amc"
    bad.write_bytes(bad.read_bytes().replace(b"\r\nlowerback ", b"\r\nlowerback x", 1))
    with pytest.raises(MotionFormatError, match=r"02_04\.amc:6: bone 'lowerback'"):
        load_library(small_lib, use_cache=False, workers=2)


def test_unwritable_cache_only_warns(
    small_lib: Path, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    blocker = tmp_path / "not_a_dir"
    blocker.write_text("a file where the cache folder would be")
    lib = load_library(small_lib, cache_dir=blocker / "c", workers=1)
    assert len(lib.clips) == 3
    assert "cannot write cache entry" in caplog.text


def test_line_ends_byte_order_marks_and_bad_tables(small_lib: Path, tmp_path: Path) -> None:
    import csv as csv_module

    # CR-only and BOM-led files read as their CRLF/LF twins
    amc = small_lib / "asf" / "02_03.amc"
    text = amc.read_bytes().replace(b"\r\n", b"\n")
    amc.write_bytes(b"\xef\xbb\xbf" + text.replace(b"\n", b"\r"))
    labels = small_lib / "labels" / "02_03.csv"
    labels.write_bytes(b"\xef\xbb\xbffirst_frame,last_frame,action\r1,96,Jog\r97,180,Stop\r")
    lib = load_library(small_lib, fps=15, cache_dir=tmp_path / "c", workers=1)
    clip = lib.clip("02_03")
    assert clip.motion.n_frames > 0 and clip.label_names == ("Jog", "Stop")
    # a huge field and a Latin-1 descriptions.csv are errors naming the file
    labels.write_text(
        "first_frame,last_frame,action\n1,2," + "x" * (csv_module.field_size_limit() + 5) + "\n"
    )
    with pytest.raises(MotionFormatError, match=r"02_03\.csv.*not a labels CSV"):
        load_library(small_lib, fps=15, cache_dir=tmp_path / "c", workers=1)
    labels.write_text("first_frame,last_frame,action\n1,96,Jog\n")
    (small_lib / "descriptions.csv").write_bytes(
        "clip,description\n02_03,caf\xe9\n".encode("latin-1")
    )
    with pytest.raises(MotionFormatError, match=r"descriptions\.csv.*not UTF-8"):
        load_library(small_lib, fps=15, cache_dir=tmp_path / "c", workers=1)


def test_sketch_files_with_huge_numbers_or_deep_nesting_are_clear_errors(tmp_path: Path) -> None:
    from control.sketch import SketchFileError, read_sketch

    path = tmp_path / "s.json"
    path.write_text('{"points": [[' + "9" * 400 + ", 0], [1, 1]]}")
    with pytest.raises(SketchFileError, match=r"s\.json: a number of 400 digits"):
        read_sketch(path)
    path.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(SketchFileError, match=r"s\.json: nested too deeply"):
        read_sketch(path)
