"""Artifacts on disk: written atomically (``atomic_write``), read without pickle
(``read_npz``), a checksum of their contents checked on load, and the cache that holds
them (its folders, size, eviction and clearing).

Every file mimic writes for itself (parsed motion, graphs, higher layers, banks, motion
arrays) carries ``checksum``: a SHA-256 over its manifest (all of it but the checksum)
and over every array's name, type, shape and bytes. A file whose checksum does not match
was damaged or edited after it was written, and is never used: a cache entry is rebuilt
with a warning naming it, anything else is an error naming it.

The cache lives in ``$MIMIC_CACHE`` (else ``$XDG_CACHE_HOME/mimic``, else
``~/.cache/mimic``)::

    motion/<hash>.npz        one parsed motion file
    graph/graph-<hash>.npz   one motion graph
    graph/graph-<hash>.parts/  the finished jobs of a graph build stopped midway
    graph/layer-<hash>.parts/  those of a higher layer's build
    graph/layer-<hash>.npz   one higher layer (cluster forest)
    bank/<hash>/             one silhouette bank (manifest.json, bank.npz, features.npy, ...)

An entry is touched when it is used, and after each new entry the least recently used
ones are removed until the cache holds at most ``$MIMIC_CACHE_MAX_GB`` (default 8 GB).
``mimic cache`` shows and clears it.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import logging
import os
import shutil
import tempfile
import time
from collections.abc import Callable, Collection, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, TypeVar

import numpy as np

from ._locks import LOCK_NAME, build_lock, hold_while, is_held, is_locked

__all__ = [
    "CACHE_KINDS",
    "LOCK_NAME",
    "CacheEntry",
    "array_digest",
    "atomic_write",
    "bound_cache",
    "build_lock",
    "cache_entries",
    "cache_limit",
    "cache_root",
    "cached_entry",
    "cached_in_parts",
    "checksum",
    "clear_cache",
    "current_umask",
    "hold_while",
    "is_held",
    "is_locked",
    "read_checked_npz",
    "read_npz",
    "touch",
    "verify_checksum",
    "write_checked_npz",
]

log = logging.getLogger(__name__)

T = TypeVar("T")

ENV_CACHE = "MIMIC_CACHE"
ENV_LIMIT = "MIMIC_CACHE_MAX_GB"
DEFAULT_LIMIT_GB = 8.0
#: what the cache holds, and how each kind is found in it
CACHE_KINDS = ("motion", "graph", "layer", "bank")
#: a temporary file older than this was left by a killed process
STALE_TMP_S = 3600.0


def array_digest(text: str, arrays: Sequence[np.ndarray]) -> str:
    """SHA-256 (hex) of ``text`` and of each of ``arrays``' dtype, shape and bytes, in
    order: the name a stored artifact made from those arrays is found under."""
    h = hashlib.sha256(text.encode())
    for table in arrays:
        a = np.ascontiguousarray(table)
        h.update(f"{a.dtype}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def checksum(manifest: Mapping[str, Any], arrays: Mapping[str, np.ndarray]) -> str:
    """SHA-256 of ``manifest`` (less its ``checksum``, as JSON would read it back) and of
    each array's name, dtype, shape and bytes, in name order."""
    body = {k: v for k, v in manifest.items() if k != "checksum"}
    text = json.dumps(json.loads(json.dumps(body)), sort_keys=True)
    h = hashlib.sha256(text.encode())
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"\0{name}\0{a.dtype.str}\0{a.shape}\0".encode())
        h.update(a.reshape(-1).view(np.uint8).data if a.size else b"")
    return h.hexdigest()


def verify_checksum(
    manifest: Mapping[str, Any],
    arrays: Mapping[str, np.ndarray],
    path: str | Path,
    error: Callable[[Path, str], Exception],
) -> None:
    """Raise ``error(path, problem)`` unless ``manifest["checksum"]`` matches."""
    stored = manifest.get("checksum")
    if not isinstance(stored, str):
        raise error(Path(path), "no checksum (written by an older mimic, or edited)")
    if stored != checksum(manifest, arrays):
        raise error(Path(path), "checksum mismatch: damaged or edited since it was written")


# --- writing and reading -------------------------------------------------------------------


def current_umask() -> int:
    """The process's file-mode creation mask (read without changing it where Linux allows)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


@contextmanager
def atomic_write(path: str | Path, mode: str = "w") -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path``; on success it replaces ``path`` in one step,
    on failure it is removed and ``path`` is untouched."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        os.chmod(fd, 0o666 & ~current_umask())  # as open() would make it, not mkstemp's 0600
        newline = None if "b" in mode else "\n"
        with os.fdopen(fd, mode, newline=newline) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        if exc.errno in (errno.ENOSPC, errno.EDQUOT):  # (a bare "[Errno 28]" named nothing)
            raise OSError(exc.errno, disk_full(path), str(path)) from None
        raise
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def disk_full(path: Path) -> str:
    """What a write of ``path`` that found its disk full says: the file, and the room
    that was left (the file needs more)."""
    return (
        f"{path}: the disk is full: writing it needs more room than the "
        f"{room_left(path.parent)} left there"
    )


def room_left(folder: Path) -> str:
    """The free space of ``folder``'s disk, said in MB ("no room" when unknown)."""
    try:
        return f"{shutil.disk_usage(folder).free / 1e6:.1f} MB"
    except OSError:
        return "no room"


def read_npz(
    path: Path, keys: Sequence[str], error: Callable[[Path, str], Exception], what: str
) -> dict[str, np.ndarray]:
    """The arrays ``keys`` of an ``.npz`` file, read without pickle.

    Raises ``error(path, problem)`` when the file cannot be read (missing, truncated,
    not a zip of arrays) or lacks one of ``keys`` (``"not a {what} (missing ...)"``).
    """
    try:
        with path.open("rb") as fh, np.load(fh, allow_pickle=False) as z:
            missing = [k for k in keys if k not in z.files]
            arrays = {} if missing else {k: z[k] for k in keys}
    except Exception as exc:
        # a damaged zip or array header raises many kinds of exception (zlib's errors,
        # an early end of file, a bad zip, a header that does not parse, an array format
        # numpy does not support, an absurd size): whichever it is, the file is named
        raise error(
            path, f"unreadable, truncated or damaged ({type(exc).__name__}: {exc})"
        ) from exc
    if missing:
        raise error(path, f"not a {what} (missing {', '.join(missing)})")
    return arrays


def write_checked_npz(path: str | Path, arrays: Mapping[str, np.ndarray]) -> None:
    """``arrays`` as an ``.npz`` file with their ``checksum``, written whole or not at all
    (``atomic_write``); ``read_checked_npz`` reads it back."""
    with atomic_write(path, "wb") as fh:
        np.savez(fh, checksum=np.array(checksum({}, arrays)), **arrays)  # type: ignore[arg-type]


def read_checked_npz(
    path: Path, keys: Sequence[str], error: Callable[[Path, str], Exception], what: str
) -> dict[str, np.ndarray]:
    """The arrays ``keys`` of a ``write_checked_npz`` file (``read_npz``), its checksum
    verified: ``error(path, problem)`` when it does not match."""
    d = read_npz(path, ("checksum", *keys), error, what)
    verify_checksum({"checksum": str(d.pop("checksum"))}, d, path, error)
    return d


# --- the cache -------------------------------------------------------------------------------


def cache_root() -> Path:
    """``$MIMIC_CACHE``, else ``$XDG_CACHE_HOME/mimic``, else ``~/.cache/mimic``."""
    env = os.environ.get(ENV_CACHE)
    if env:
        root = Path(env)
        if root.exists() and not root.is_dir():
            raise NotADirectoryError(
                f"${ENV_CACHE}={env}: is a file, not a folder (point it at a folder, or unset "
                "it for the default)"
            )
        return root
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "mimic"


def cache_limit() -> int:
    """The most bytes the cache may hold: ``$MIMIC_CACHE_MAX_GB`` (default 8)."""
    text = os.environ.get(ENV_LIMIT, "")
    try:
        gb = float(text) if text else DEFAULT_LIMIT_GB
    except ValueError:
        raise ValueError(f"${ENV_LIMIT}={text!r} is not a number of gigabytes") from None
    if not gb >= 0:
        raise ValueError(f"${ENV_LIMIT}={text!r} must be 0 or more")
    return int(gb * 1e9)


@dataclass(frozen=True)
class CacheEntry:
    """One entry of the cache: a file, or a bank's folder."""

    kind: str
    path: Path
    bytes: int
    used: float  # last use (modification time), seconds since the epoch


def _size(path: Path) -> int:
    if path.is_dir():
        return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())
    return path.stat().st_size


def cache_entries(root: Path | None = None) -> list[CacheEntry]:
    """Every entry of the cache at ``root``, least recently used first. Temporary files
    left by a killed process (older than an hour) count as entries of their kind."""
    root = root or cache_root()
    found: list[tuple[str, Path]] = []
    now = time.time()

    def files(folder: Path, pattern: str) -> Iterable[Path]:
        return sorted(folder.glob(pattern)) if folder.is_dir() else []

    for p in files(root / "motion", "*.npz"):
        found.append(("motion", p))
    for p in files(root / "graph", "graph-*.npz"):
        found.append(("graph", p))
    for kind in ("graph", "layer"):  # (a build stopped midway: its finished jobs)
        for p in files(root / "graph", f"{kind}-*.parts"):
            if p.is_dir():
                found.append((kind, p))
    for p in files(root / "graph", "layer-*.npz"):
        found.append(("layer", p))
    for p in files(root / "bank", "*"):
        if p.is_dir():
            found.append(("bank", p))
    for kind, folder in (("motion", "motion"), ("graph", "graph")):
        for p in files(root / folder, ".*.tmp"):
            with contextlib.suppress(OSError):
                if now - p.stat().st_mtime > STALE_TMP_S:
                    found.append((kind, p))
    entries = []
    for kind, p in found:
        try:
            entries.append(CacheEntry(kind, p, _size(p), p.stat().st_mtime))
        except OSError:  # removed meanwhile by another process
            continue
    return sorted(entries, key=lambda e: (e.used, str(e.path)))


def touch(path: str | Path) -> None:
    """Mark a cache entry as just used (its modification time); a read-only cache only
    loses the order of eviction."""
    with contextlib.suppress(OSError):
        os.utime(path)


def _remove(path: Path) -> None:
    if path.is_dir():
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.unlink(missing_ok=True)


@contextmanager
def _cache_lock(folder: Path) -> Iterator[None]:
    """``build_lock`` of a cache folder, or none where the folder cannot hold one (a
    read-only cache only costs speed: two processes may then build the same entry, and
    the atomic writes leave one good file)."""
    try:
        lock = build_lock(folder)
        lock.__enter__()
    except OSError as exc:
        log.info("building without a lock in %s: %s", folder, exc)
        yield
        return
    try:
        yield
    finally:
        lock.__exit__(None, None, None)


def _stamp(path: Path) -> int | None:
    """``path``'s ``st_mtime_ns`` (``None``: no such file)."""
    try:
        return path.stat().st_mtime_ns
    except OSError:
        return None


def cached_entry(
    path: Path, load: Callable[[], T | None], make: Callable[[], T], rebuild: bool = False
) -> tuple[T, bool]:
    """The cache entry at ``path``: ``load()`` it (``None``: missing, stale or damaged,
    said by ``load``), else ``make()`` it (which builds and stores it), under the lock of
    its folder, so that of two processes asking at once one builds it and the other
    waits and loads it. ``rebuild``: make it whatever is there. Returns ``(entry,
    built)``."""
    seen = _stamp(path)
    if seen is not None and not rebuild:
        got = load()
        if got is not None:
            return got, False
    with _cache_lock(path.parent):
        # written since it was looked at: another process built it meanwhile
        if not rebuild and _stamp(path) not in (None, seen):
            got = load()
            if got is not None:
                return got, False
        return make(), True


def cached_in_parts(
    path: Path,
    load: Callable[[], T | None],
    build: Callable[[Path], T],
    save: Callable[[T], object],
    rebuild: bool = False,
) -> tuple[T, bool]:
    """``cached_entry`` of an entry whose ``build(parts)`` keeps its finished jobs in the
    folder ``parts`` (``path`` with the suffix ``.parts``: ``control.jobs.JobStore``),
    so that a stopped build resumes from them: cleared first on ``rebuild`` (nothing of
    before kept), removed once ``save(entry)`` has stored the entry."""
    parts = path.with_suffix(".parts")

    def make() -> T:
        if rebuild:
            shutil.rmtree(parts, ignore_errors=True)
        entry = build(parts)
        save(entry)
        shutil.rmtree(parts, ignore_errors=True)
        return entry

    return cached_entry(path, load, make, rebuild)


def bound_cache(
    keep: Collection[str | Path] = (), limit: int | None = None, root: Path | None = None
) -> list[CacheEntry]:
    """Remove the least recently used entries until the cache holds at most ``limit``
    bytes (``cache_limit()``), never one of ``keep``. Returns what was removed."""
    limit = cache_limit() if limit is None else limit
    kept = {Path(p).resolve() for p in keep}
    entries = cache_entries(root)
    total = sum(e.bytes for e in entries)
    removed = []
    for e in entries:
        if total <= limit:
            break
        if e.path.resolve() in kept or (e.path.is_dir() and is_locked(e.path)):
            continue  # (a bank that another process is building)
        _remove(e.path)
        total -= e.bytes
        removed.append(e)
        log.info("cache over %.1f GB: removed %s (%.1f MB)", limit / 1e9, e.path, e.bytes / 1e6)
    _warn_if_too_small(limit, total, removed)
    return removed


#: an entry used this recently is taken to be one the running work still needs
RECENT_S = 3600.0


def _warn_if_too_small(limit: int, total: int, removed: Sequence[CacheEntry]) -> None:
    """Say when the limit is below what is in use: what this work kept is over it, or
    the entries removed were used within the hour (a large library's graph, say, removed
    for its bank: built again on every run)."""
    recent = [e for e in removed if time.time() - e.used < RECENT_S]
    if total <= limit and not recent:
        return
    said = [f"{total / 1e9:.1f} GB kept"] if total > limit else []
    if recent:
        names = ", ".join(e.path.name for e in recent[:3]) + (", ..." if len(recent) > 3 else "")
        said.append(f"removed {len(recent)} entries used within the hour ({names})")
    log.warning(
        "the cache's limit of %.1f GB ($%s) is below what this work uses: %s; they are "
        "built again when next needed: raise the limit",
        limit / 1e9,
        ENV_LIMIT,
        "; ".join(said),
    )


def clear_cache(
    kinds: Collection[str] = CACHE_KINDS,
    older_than_days: float = 0.0,
    root: Path | None = None,
) -> list[CacheEntry]:
    """Remove the entries of ``kinds`` unused for ``older_than_days``; returns them."""
    bad = set(kinds) - set(CACHE_KINDS)
    if bad:
        raise ValueError(f"unknown cache kinds {sorted(bad)}: the kinds are {CACHE_KINDS}")
    cutoff = time.time() - older_than_days * 86400.0
    removed = []
    for e in cache_entries(root):
        if e.kind in kinds and e.used <= cutoff:
            _remove(e.path)
            removed.append(e)
    return removed
