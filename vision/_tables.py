"""The matcher's whole-library window tables and shape statistics, stored beside the bank
they are made from, so that a ``perform`` on a large bank starts without reading it.

Both are made from every frame of the bank: the statistics (``shape_stats``) from a
sample spread over all of it, the tables (``window_tables``) from all of it. A bank read
from its folder (``silhouette_bank.load_bank``: memory-mapped, with its manifest's
checksum) keeps them there, keyed by that checksum and what else they are made from:

    windows-stats.npz           the statistics, with the bank checksum they belong to
    windows-<hash>.json         a table pair's manifest: what it was made from, its
                                shapes and the SHA-256 of every block of frames
    windows-<hash>-shape.npy    the mapped shape numbers ``(N, V, d)``, float32, and
    windows-<hash>-centre.npy   the accumulated centre ``(N, V, 2)``, float64, opened
                                memory-mapped (``silhouette_bank.open_mapped``: checked
                                in full once, then trusted while unchanged)

The first run that needs them writes them (each file to a temporary one, then renamed),
and checks them in a background thread a moment later (``_check_later``); the next maps
them, without reading them when that check was recorded. A damaged or mismatched file
is made again with a warning naming it; a folder that cannot be written is only read. At
most ``KEEP_TABLES`` table pairs are kept per bank (the least recently used go first),
and the window indexes made from them (``vision._index``) go with them
(``prune_indexes``). Tables that a process has open are not removed: it holds a shared
``flock`` on their manifest while their arrays live (``hold_while``), so that another
performer's run beside it cannot prune them, and with them the index stored for them.
"""

from __future__ import annotations

import atexit
import contextlib
import json
import logging
import os
import shutil
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

import silhouette_bank
from control.artifacts import (
    atomic_write,
    checksum,
    hold_while,
    is_held,
    read_checked_npz,
    verify_checksum,
    write_checked_npz,
)
from control.dtw import SHAPE_DTYPE, ShapeTable
from silhouette_bank import Bank, block_hashes, npy_file, open_mapped

from ._windows import shape_stats, window_tables

log = logging.getLogger(__name__)

__all__ = [
    "KEEP_TABLES",
    "TABLES_VERSION",
    "WindowTablesError",
    "cached_shape_stats",
    "cached_window_tables",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: the stored tables' format (2: the shape numbers in float32)
TABLES_VERSION = 2
#: each stored table's number type
_DTYPES = {"shape": SHAPE_DTYPE, "centre": np.float64}
#: table pairs kept in a bank's folder
KEEP_TABLES = 3
#: window indexes kept per set of window tables (``prune_indexes``)
KEEP_INDEXES = 3
#: frames of a stored table hashed as one block
_ROWS = 4096


class WindowTablesError(ValueError):
    """A stored window table or statistics file that cannot be used (names the file)."""

    def __init__(self, path: str | Path, problem: str) -> None:
        self.path = Path(path)
        self.problem = problem
        super().__init__(f"{path}: {problem}")


def _stored(bank: Bank) -> Path | None:
    """The bank's folder when its arrays are the ones mapped from there (so that its
    checksum says what they hold), else ``None``."""
    if not bank.path or not bank.checksum:
        return None
    folder = Path(bank.path)
    for a, name in ((bank.features, "features.npy"), (bank.root_motion, "root_motion.npy")):
        if not isinstance(a, np.memmap) or a.filename is None:
            return None
        if Path(a.filename).resolve() != (folder / name).resolve():
            return None
    return folder


def cached_shape_stats(bank: Bank) -> tuple[FloatArray, FloatArray]:
    """``shape_stats(bank)``, kept in the bank's folder (``windows-stats.npz``)."""
    folder = _stored(bank)
    if folder is None:
        return shape_stats(bank)
    path = folder / "windows-stats.npz"
    if path.is_file():
        try:
            d = read_checked_npz(path, ("bank", "mean", "proj"), WindowTablesError, "stats")
            if str(d["bank"]) == bank.checksum:
                return d["mean"].astype(np.float64), d["proj"].astype(np.float64)
        except WindowTablesError as exc:
            log.warning("making the shape statistics again: %s", exc)
    mean, proj = shape_stats(bank)
    arrays = {"bank": np.array(bank.checksum), "mean": mean, "proj": proj}
    with contextlib.suppress(OSError):  # (a read-only folder)
        write_checked_npz(path, arrays)
    return mean, proj


def _key(
    bank: Bank,
    frames: IntArray,
    clip_start: IntArray,
    mean: FloatArray,
    proj: FloatArray,
    centre_weight: float,
) -> str:
    made_of = {
        "version": TABLES_VERSION,
        "bank": bank.checksum,
        "centre_weight": float(centre_weight),
    }
    arrays = {"frames": frames, "clip_start": clip_start, "mean": mean, "proj": proj}
    return checksum(made_of, arrays)


def cached_window_tables(
    bank: Bank,
    frames: IntArray,
    clip_start: IntArray,
    mean: FloatArray,
    proj: FloatArray,
    centre_weight: float,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[ShapeTable, FloatArray, str]:
    """``(*window_tables(...), key)``: stored in (and mapped from) the bank's folder
    when the bank was read from one; ``key`` (a hash of the bank's checksum and the other
    arguments) names them, ``""`` when they are made in memory. ``progress(done,
    total)`` counts the frames of tables made (none when they are read)."""
    frames = np.asarray(frames, dtype=np.int64)
    clip_start = np.asarray(clip_start, dtype=np.int64)
    folder = _stored(bank)
    if folder is None:
        made = window_tables(bank, frames, clip_start, mean, proj, centre_weight, None, progress)
        return (*made, "")
    key = _key(bank, frames, clip_start, mean, proj, centre_weight)
    stem = folder / f"windows-{key[:24]}"
    shapes: dict[str, tuple[int, ...]] = {
        "shape": (frames.size, bank.features.shape[1], proj.shape[1]),
        "centre": (frames.size, bank.features.shape[1], 2),
    }
    manifest = Path(f"{stem}.json")
    if manifest.is_file():
        try:
            shape, centre = _open(manifest, stem, key, shapes)
            with contextlib.suppress(OSError):
                os.utime(manifest)  # (used: the last to be pruned)
            hold_while(manifest, shape)
            return shape, centre, key
        except WindowTablesError as exc:
            log.warning("making the window tables again: %s", exc)
    try:
        shape, centre = _write(
            bank, frames, clip_start, mean, proj, centre_weight, stem, key, progress
        )
    except OSError as exc:  # a bank folder that is only ours to read
        log.info("the window tables are not stored: %s", exc)
        made = window_tables(bank, frames, clip_start, mean, proj, centre_weight, None, progress)
        return (*made, key)
    hold_while(manifest, shape)
    _prune(folder)
    _check_later(manifest, stem, key, shapes)
    return shape, centre, key


#: the background checks of tables just written (``_check_later``) still running
CHECKING: list[threading.Thread] = []


def _check_later(manifest: Path, stem: Path, key: str, shapes: dict[str, tuple[int, ...]]) -> None:
    """Check the tables just written as the next run would (``open_mapped``, which records
    them as checked), in a background thread, once a change within the file system's
    clock tick could no longer hide behind the record (``RACY_NS`` after the write): the
    next run then maps them without reading them (at 500,000 frames the first warm
    start-up spent about 2 s checking them). A process that ends first leaves the check
    to the next run, as before (but for large tables, ``WAIT_BYTES``, which it waits
    for); a failed check leaves it to the next run too, which says what is wrong."""

    def check() -> None:
        time.sleep(silhouette_bank.RACY_NS / 1e9 + 0.05)
        with contextlib.suppress(Exception):
            _open(manifest, stem, key, shapes)

    CHECKING[:] = [t for t in CHECKING if t.is_alive()]
    thread = threading.Thread(target=check, name="mimic-check-tables", daemon=True)
    thread.start()
    CHECKING.append(thread)
    size = sum(np.dtype(_DTYPES[name]).itemsize * int(np.prod(s)) for name, s in shapes.items())
    if size >= WAIT_BYTES:  # worth a short wait at the exit: the next run saves more
        atexit.register(thread.join)


#: tables this large are checked before the process that wrote them exits (a wait of
#: ``RACY_NS`` at most, then the check: about 2 s for a 500k library's 3.6 GB of float64
#: tables, before the shape numbers were float32); smaller ones only if it runs on long
#: enough
WAIT_BYTES = 256 * 2**20


def _open(
    manifest: Path, stem: Path, key: str, shapes: dict[str, tuple[int, ...]]
) -> tuple[ShapeTable, FloatArray]:
    try:
        m = json.loads(manifest.read_bytes().decode("utf-8"))
        ok = isinstance(m, dict) and isinstance(m.get("blocks"), dict)
    except (OSError, ValueError):
        ok = False
    if not ok or m.get("format") != "mimic-window-tables":
        raise WindowTablesError(manifest, "unreadable, or not a window tables manifest")
    verify_checksum(m, {}, manifest, WindowTablesError)
    if m.get("version") != TABLES_VERSION or m.get("key") != key:
        raise WindowTablesError(manifest, "made by another version or from another bank")
    out = []
    for name in ("shape", "centre"):
        path = Path(f"{stem}-{name}.npy")
        out.append(
            open_mapped(
                path, shapes[name], _DTYPES[name], m["blocks"].get(name), _ROWS, WindowTablesError
            )
        )
    return out[0], out[1]


def _write(
    bank: Bank,
    frames: IntArray,
    clip_start: IntArray,
    mean: FloatArray,
    proj: FloatArray,
    centre_weight: float,
    stem: Path,
    key: str,
    progress: Callable[[int, int], None] | None,
) -> tuple[ShapeTable, FloatArray]:
    n, v = frames.size, bank.features.shape[1]
    blocks: dict[str, Any] = {}
    with (
        npy_file(Path(f"{stem}-shape.npy"), _DTYPES["shape"], (n, v, proj.shape[1])) as shape,
        npy_file(Path(f"{stem}-centre.npy"), _DTYPES["centre"], (n, v, 2)) as centre,
    ):
        window_tables(
            bank, frames, clip_start, mean, proj, centre_weight, (shape, centre), progress
        )
        blocks["shape"] = block_hashes(shape, _ROWS)
        blocks["centre"] = block_hashes(centre, _ROWS)
    m: dict[str, Any] = {
        "format": "mimic-window-tables",
        "version": TABLES_VERSION,
        "key": key,
        "bank": bank.checksum,
        "blocks": blocks,
    }
    m["checksum"] = checksum(m, {})
    with atomic_write(Path(f"{stem}.json")) as fh:
        json.dump(m, fh, indent=1)
    # (mapped as written: the next run checks them, ``open_mapped``)
    return (
        np.load(f"{stem}-shape.npy", mmap_mode="r", allow_pickle=False),
        np.load(f"{stem}-centre.npy", mmap_mode="r", allow_pickle=False),
    )


def _prune(folder: Path) -> None:
    """Remove all but the ``KEEP_TABLES`` most recently used table pairs of ``folder``,
    and never a pair that a process has open (``hold_while``)."""
    sets = []
    for m in folder.glob("windows-*.json"):
        with contextlib.suppress(OSError):
            sets.append((m.stat().st_mtime_ns, m))
    for _, m in sorted(sets, reverse=True)[KEEP_TABLES:]:
        if is_held(m):  # (open in a run: ``hold_while``)
            continue
        stem = str(m)[: -len(".json")]
        with contextlib.suppress(OSError):
            m.unlink()
            for name in ("shape", "centre"):
                Path(f"{stem}-{name}.npy").unlink(missing_ok=True)


def prune_indexes(folder: Path) -> None:
    """Remove from a bank's ``folder`` the window indexes (and the parts of stopped index
    builds) of window tables no longer there (``cached_window_tables`` keeps the few last
    used), and all but the ``KEEP_INDEXES`` most recently used of each set of tables that
    is: other performers' leave-outs and options each make an index of their own. An index
    of unnamed tables in a folder of named ones is an older version's, never read again."""
    tables = {m.name[len("windows-") : -len(".json")] for m in folder.glob("windows-*.json")}
    groups: dict[str, list[tuple[int, Path]]] = {}
    for f in folder.glob("index-*"):
        name = f.name.split(".")[0][len("index-") :]
        key = name.split("-")[0] if "-" in name else ""  # ("": an index of unnamed tables)
        if key not in tables and (key or tables):
            _remove(f)
        elif f.suffix == ".npz":
            with contextlib.suppress(OSError):
                groups.setdefault(key, []).append((f.stat().st_mtime_ns, f))
    for files in groups.values():
        for _, f in sorted(files, reverse=True)[KEEP_INDEXES:]:
            _remove(f)
            _remove(f.with_suffix(".parts"))


def _remove(path: Path) -> None:
    """Remove a file or a folder, or leave it where the folder is only ours to read."""
    if path.is_dir():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(OSError):
            path.unlink(missing_ok=True)
