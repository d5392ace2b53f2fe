"""A bank's large arrays on disk: plain ``.npy`` files written through a memory map into a
temporary file that replaces the old one in one step (``npy_file``), hashed a block of
rows at a time (``block_hashes``, kept in the bank's manifest), and opened memory-mapped
with every block checked (``open_mapped``): the check streams through the file once, and
nothing of it is held in memory but the pages the reader uses."""

from __future__ import annotations

import hashlib
import os
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from control.artifacts import current_umask

__all__ = ["block_hash", "block_hashes", "npy_file", "open_mapped"]


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


def open_mapped(
    path: Path,
    shape: tuple[int, ...],
    dtype: Any,
    hashes: Any,
    rows: int,
    error: Callable[[Path, str], Exception],
) -> np.ndarray:
    """``path`` memory-mapped (read-only), its type, shape and the hash of every block of
    ``rows`` rows checked; else ``error(path, problem)``, naming it (and the frames of a
    damaged block)."""
    if not path.is_file():
        raise error(path, "missing (a bank's arrays are stored beside its manifest)")
    try:
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
    for k, want in enumerate(hashes):
        if block_hash(a, k, rows) != want:
            a0, b0 = k * rows, min(shape[0], (k + 1) * rows)
            raise error(
                path,
                f"frames {a0}-{b0 - 1}: checksum mismatch: damaged or edited since it was written",
            )
    return a
