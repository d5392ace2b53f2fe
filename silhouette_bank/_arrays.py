"""A bank's large arrays on disk: plain ``.npy`` files written through a memory map into a
temporary file that replaces the old one in one step (``npy_file``), hashed a block of
rows at a time (``block_hashes``, kept in the bank's manifest), and opened memory-mapped
(``open_mapped``) with every block checked: the check streams through the file once and
holds none of it.

A file checked once need not be read again to be opened: ``open_mapped`` records what the
file system says of it (device, inode, size, modification and change times) in
``checked.json`` beside it, and the next open trusts a file whose record is the same and
whose last change came well before its check (``RACY_NS``: a write within the file
system's clock tick of a check could leave every time the same, as git's "racily clean"
index entries). Every write through the file system changes the change time, which
cannot be set back, so only damage beneath it (the disk itself) goes unseen until a
write or a copy forces the next full check; a read-only folder is checked in full each
time."""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from control.artifacts import atomic_write, current_umask

__all__ = ["CHECKED_FILE", "RACY_NS", "block_hash", "block_hashes", "npy_file", "open_mapped"]

#: the record of checked files, one per folder
CHECKED_FILE = "checked.json"
#: a file changed less than this long (ns) before its check is checked again next time
RACY_NS = 2_000_000_000


@contextmanager
def npy_file(path: Path, dtype: Any, shape: tuple[int, ...]) -> Iterator[np.ndarray]:
    """A writable memory-mapped ``.npy`` file that replaces ``path`` in one step on
    success (a temporary file beside it until then; removed on failure)."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        out = np.lib.format.open_memmap(tmp, mode="w+", dtype=dtype, shape=shape)
        yield out
        out.flush()
        del out
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o666 & ~current_umask())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def block_hash(a: np.ndarray, k: int, rows: int) -> str:
    """SHA-256 of the bytes of block ``k`` (of ``rows`` rows) of ``a``."""
    block = np.ascontiguousarray(a[k * rows : (k + 1) * rows])
    return hashlib.sha256(block.reshape(-1).view(np.uint8).data).hexdigest()


def block_hashes(a: np.ndarray, rows: int) -> list[str]:
    """``block_hash`` of every block of ``rows`` rows of ``a``, in order."""
    return [block_hash(a, k, rows) for k in range(-(-a.shape[0] // rows))]


def _stat(path: Path) -> list[int]:
    st = path.stat()
    return [st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns]


def _record(hashes: list[str]) -> str:
    return hashlib.sha256("|".join(map(str, hashes)).encode()).hexdigest()


def _checked(path: Path) -> dict[str, Any]:
    """The folder's record of checked files (empty when missing or unreadable)."""
    try:
        got = json.loads((path.parent / CHECKED_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return got if isinstance(got, dict) else {}


def _trusted(path: Path, hashes: list[str]) -> bool:
    """Whether ``path`` was checked against ``hashes`` and is unchanged since."""
    entry = _checked(path).get(path.name)
    if not isinstance(entry, dict):
        return False
    try:
        stat = _stat(path)
    except OSError:
        return False
    changed = max(stat[3], stat[4])
    at = entry.get("at")
    return (
        entry.get("stat") == stat
        and entry.get("blocks") == _record(hashes)
        and isinstance(at, int)
        and at - changed > RACY_NS
    )


def _remember(path: Path, hashes: list[str], stat: list[int], at: int) -> None:
    """Record that ``path`` (as ``stat`` says, checked from time ``at``) matched
    ``hashes``; a folder that cannot be written keeps no record."""
    if _stat(path) != stat or at - max(stat[3], stat[4]) <= RACY_NS:
        return  # changed while it was checked, or too soon after a change to trust
    record = _checked(path)
    record[path.name] = {"stat": stat, "blocks": _record(hashes), "at": at}
    with contextlib.suppress(OSError), atomic_write(path.parent / CHECKED_FILE) as fh:
        json.dump(record, fh, indent=1)


def open_mapped(
    path: Path,
    shape: tuple[int, ...],
    dtype: Any,
    hashes: Any,
    rows: int,
    error: Callable[[Path, str], Exception],
) -> np.ndarray:
    """``path`` memory-mapped (read-only), its type, shape and the hash of every block of
    ``rows`` rows checked (or trusted from ``checked.json``: see the module's note); else
    ``error(path, problem)``, naming it (and the frames of a damaged block)."""
    if not path.is_file():
        raise error(path, "missing (it is stored beside its manifest)")
    try:
        stat, at = _stat(path), time.time_ns()
        a = np.load(path, mmap_mode="r", allow_pickle=False)
    except Exception as exc:  # a damaged header or a truncated file: whatever numpy raises
        raise error(
            path, f"unreadable, truncated or damaged ({type(exc).__name__}: {exc})"
        ) from exc
    if not isinstance(a, np.memmap) or a.dtype != np.dtype(dtype) or a.shape != shape:
        got = f"{getattr(a, 'dtype', '?')} {getattr(a, 'shape', '?')}"
        raise error(path, f"holds {got}, not {np.dtype(dtype)} {shape}")
    if not isinstance(hashes, list) or len(hashes) != -(-shape[0] // rows):
        raise error(path, "the manifest's block hashes do not fit it")
    if _trusted(path, hashes):
        return a
    for k, want in enumerate(hashes):
        if block_hash(a, k, rows) != want:
            a0, b0 = k * rows, min(shape[0], (k + 1) * rows)
            raise error(
                path,
                f"frames {a0}-{b0 - 1}: checksum mismatch: damaged or edited since it was written",
            )
    with contextlib.suppress(OSError):
        _remember(path, hashes, stat, at)
    return a
