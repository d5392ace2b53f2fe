"""The matcher's window tables and shape statistics, stored beside the bank."""

from __future__ import annotations

import dataclasses
import gc
import json
import logging
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

import vision._tables as tables_module
from silhouette_bank import load_bank
from vision import (
    Matcher,
    MatchSettings,
    cached_shape_stats,
    cached_window_tables,
    shape_stats,
    window_tables,
)
from vision._tables import KEEP_TABLES


def _copy(bank, tmp_path: Path):
    """The session's bank copied to a folder of its own (its derived files left out)."""
    folder = tmp_path / "bank"
    keep = ("manifest.json", "bank.npz", "features.npy", "root_motion.npy")
    folder.mkdir()
    for name in keep:
        shutil.copy(Path(bank.path) / name, folder / name)
    return load_bank(folder)


def test_stored_tables_are_the_made_ones_and_are_mapped_next_time(
    setup, tmp_path, caplog, monkeypatch
) -> None:
    _, layer, session_bank = setup
    bank = _copy(session_bank, tmp_path)
    folder = Path(bank.path)
    mean, proj = cached_shape_stats(bank)
    want_mean, want_proj = shape_stats(bank)
    np.testing.assert_array_equal(mean, want_mean)
    np.testing.assert_array_equal(proj, want_proj)
    assert (folder / "windows-stats.npz").is_file()
    m = Matcher(layer, bank, MatchSettings())
    frames, cs, w = m.windows.to_bank, layer.graph.clip_start, m.settings.centre_weight
    want = window_tables(bank, frames, cs, mean, proj, w)
    shape, centre, key = cached_window_tables(bank, frames, cs, mean, proj, w)
    assert key and isinstance(shape, np.memmap) and isinstance(centre, np.memmap)
    # the shape numbers stored at the bank's precision and more (float32: half the disk
    # of float64), the centre, a running sum along each clip, in float64
    assert shape.dtype == want[0].dtype == np.float32 and centre.dtype == np.float64
    np.testing.assert_array_equal(shape, want[0])
    np.testing.assert_array_equal(centre, want[1])

    # next time they are mapped from the folder, not made
    def made(*_a, **_k):
        raise AssertionError("made again")

    monkeypatch.setattr(tables_module, "window_tables", made)
    monkeypatch.setattr(tables_module, "shape_stats", made)
    assert cached_shape_stats(bank)[0].tolist() == mean.tolist()
    again = cached_window_tables(bank, frames, cs, mean, proj, w)
    assert again[2] == key
    np.testing.assert_array_equal(again[0], want[0])
    # the matcher's index is keyed by them, and found again by a second matcher
    m.windows.index()
    (index,) = folder.glob("index-*.npz")
    Matcher(layer, bank, MatchSettings()).windows.index()
    assert list(folder.glob("index-*.npz")) == [index]
    monkeypatch.undo()
    # a damaged table is made again, with a warning naming it
    (shape_file,) = folder.glob("windows-*-shape.npy")
    data = bytearray(shape_file.read_bytes())
    data[len(data) // 2] ^= 0xFF
    shape_file.write_bytes(bytes(data))
    with caplog.at_level(logging.WARNING):
        fixed = cached_window_tables(bank, frames, cs, mean, proj, w)
    assert shape_file.name in caplog.text and "checksum mismatch" in caplog.text
    np.testing.assert_array_equal(fixed[0], want[0])


def test_at_most_a_few_tables_are_kept_and_never_ones_still_open(setup, tmp_path) -> None:
    """Other arguments make other tables, and at most ``KEEP_TABLES`` pairs are kept (the
    least recently used go), but never a pair a run still has open, in this process or
    another: that run would lose them, and the index stored for them."""
    _, layer, session_bank = setup
    bank = _copy(session_bank, tmp_path)
    folder = Path(bank.path)
    mean, proj = cached_shape_stats(bank)
    m = Matcher(layer, bank, MatchSettings())
    frames, cs, w = m.windows.to_bank, layer.graph.clip_start, m.settings.centre_weight
    held = cached_window_tables(bank, frames, cs, mean, proj, w)
    manifest = folder / f"windows-{held[2][:24]}.json"
    for k in range(KEEP_TABLES + 1):
        cached_window_tables(bank, frames, cs, mean, proj, w + 0.1 * (k + 1))
    assert manifest.is_file()
    assert len(list(folder.glob("windows-*.json"))) == KEEP_TABLES + 1
    assert len(list(folder.glob("windows-*-shape.npy"))) == KEEP_TABLES + 1
    # another process's prune leaves it too (the lock is the file's, not this process's)
    code = "import sys; from control.artifacts import is_held; print(is_held(sys.argv[1]))"
    out = subprocess.run([sys.executable, "-c", code, str(manifest)], capture_output=True)
    assert out.stdout.decode().strip() == "True", out.stderr.decode()[-2000:]
    del held
    gc.collect()  # closed: the next tables made prune them
    cached_window_tables(bank, frames, cs, mean, proj, w + 0.1 * (KEEP_TABLES + 2))
    assert len(list(folder.glob("windows-*.json"))) == KEEP_TABLES
    assert len(list(folder.glob("windows-*-shape.npy"))) == KEEP_TABLES
    assert not manifest.exists()


def test_tables_just_written_are_checked_in_the_background(setup, tmp_path, monkeypatch) -> None:
    """The run that writes the tables checks them once the file system's clock tick has
    passed (here 0.1 s, RACY_NS patched), and records it: the next run maps them without
    hashing a block. Large tables are waited for at the exit."""
    import silhouette_bank
    import silhouette_bank._arrays as arrays

    monkeypatch.setattr(arrays, "RACY_NS", 100_000_000)
    monkeypatch.setattr(silhouette_bank, "RACY_NS", 100_000_000)
    waited = []  # tables over WAIT_BYTES are waited for at the exit
    monkeypatch.setattr(tables_module, "WAIT_BYTES", 0)
    monkeypatch.setattr(tables_module.atexit, "register", waited.append)
    _, layer, session_bank = setup
    bank = _copy(session_bank, tmp_path)
    m = Matcher(layer, bank, MatchSettings())
    mean, proj = cached_shape_stats(bank)
    args = (bank, m.windows.to_bank, layer.graph.clip_start, mean, proj, m.settings.centre_weight)
    want = cached_window_tables(*args)
    assert [j.__self__.name for j in waited] == ["mimic-check-tables"]
    for thread in tables_module.CHECKING:
        thread.join(timeout=30)
    checked = json.loads((Path(bank.path) / "checked.json").read_text())
    stem = f"windows-{want[2][:24]}"
    assert {f"{stem}-shape.npy", f"{stem}-centre.npy"} <= set(checked)

    def hashed(*_a, **_k):
        raise AssertionError("read again")

    monkeypatch.setattr(arrays, "block_hash", hashed)
    again = cached_window_tables(*args)
    np.testing.assert_array_equal(again[0], want[0])


def test_a_bank_not_read_from_its_folder_keeps_its_tables_in_memory(setup, tmp_path) -> None:
    _, layer, session_bank = setup
    bank = _copy(session_bank, tmp_path)
    changed = dataclasses.replace(bank, features=np.array(bank.features) * 2)
    m = Matcher(layer, changed, MatchSettings())
    shape, centre, key = cached_window_tables(
        changed, m.windows.to_bank, layer.graph.clip_start, m.windows.mean, m.windows.proj, 1.0
    )
    assert key == "" and not isinstance(shape, np.memmap)
    assert not list(Path(bank.path).glob("windows-*"))
    want = window_tables(
        changed, m.windows.to_bank, layer.graph.clip_start, m.windows.mean, m.windows.proj, 1.0
    )
    np.testing.assert_array_equal(shape, want[0])
    np.testing.assert_array_equal(centre, want[1])
