"""Artifacts on disk: a checksum of their contents, checked on load, and the cache that
holds them (its folders, size, eviction and clearing).

Every file mimic writes for itself (parsed motion, graphs, higher layers, banks, motion
arrays) carries ``checksum``: a SHA-256 over its manifest (all of it but the checksum)
and over every array's name, type, shape and bytes. A file whose checksum does not match
was damaged or edited after it was written, and is never used: a cache entry is rebuilt
with a warning naming it, anything else is an error naming it.

The cache lives in ``$MIMIC_CACHE`` (else ``$XDG_CACHE_HOME/mimic``, else
``~/.cache/mimic``)::

    motion/<hash>.npz        one parsed motion file
    graph/graph-<hash>.npz   one motion graph
    graph/layer-<hash>.npz   one higher layer (cluster forest)
    bank/<hash>/             one silhouette bank (manifest.json, bank.npz)

An entry is touched when it is used, and after each new entry the least recently used
ones are removed until the cache holds at most ``$MIMIC_CACHE_MAX_GB`` (default 8 GB).
``mimic cache`` shows and clears it.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import os
import shutil
import time
from collections.abc import Callable, Collection, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "CACHE_KINDS",
    "CacheEntry",
    "bound_cache",
    "cache_entries",
    "cache_limit",
    "cache_root",
    "checksum",
    "clear_cache",
    "touch",
    "verify_checksum",
]

log = logging.getLogger(__name__)

ENV_CACHE = "MIMIC_CACHE"
ENV_LIMIT = "MIMIC_CACHE_MAX_GB"
DEFAULT_LIMIT_GB = 8.0
#: what the cache holds, and how each kind is found in it
CACHE_KINDS = ("motion", "graph", "layer", "bank")
#: a temporary file older than this was left by a killed process
STALE_TMP_S = 3600.0


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


# --- the cache -------------------------------------------------------------------------------


def cache_root() -> Path:
    """``$MIMIC_CACHE``, else ``$XDG_CACHE_HOME/mimic``, else ``~/.cache/mimic``."""
    env = os.environ.get(ENV_CACHE)
    if env:
        return Path(env)
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
        if e.path.resolve() in kept:
            continue
        _remove(e.path)
        total -= e.bytes
        removed.append(e)
        log.info("cache over %.1f GB: removed %s (%.1f MB)", limit / 1e9, e.path, e.bytes / 1e6)
    return removed


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
