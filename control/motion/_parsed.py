"""Finding a library's clips and parsing them, each parsed file cached as ``.npz`` (no
pickle, with a checksum) under a key hashed from the file's bytes (and its ASF's), the
reader version and settings."""

from __future__ import annotations

import hashlib
import json
import logging
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from ..artifacts import (
    atomic_write,
    checksum,
    read_npz,
    touch,
    verify_checksum,
)
from ._amc import read_amc
from ._arrays import ARRAYS_SUFFIX, read_motion_arrays
from ._asf import read_asf
from ._bvh import read_bvh
from ._errors import MotionFormatError
from ._text import read_bytes
from ._types import Motion, Skeleton

__all__ = [
    "READER_VERSION",
    "Source",
    "cache_key",
    "discover",
    "is_arrays",
    "load_cached",
    "load_entry",
    "parse",
    "parse_job",
]

log = logging.getLogger(__name__)

T = TypeVar("T")

#: Bump when a reader's output changes, so stale cache entries are never used.
READER_VERSION = "2"  # 2: cache entries carry a checksum


@dataclass(frozen=True)
class Source:
    name: str
    path: Path
    asf: Path | None  # for AMC


def library_files(root: Path) -> list[Path]:
    """Every file under ``root``. A folder that cannot be read is an error naming it:
    ``Path.rglob`` skipped it without a word, and the library silently lacked its clips.
    Symbolic links to folders are followed (the usual way to point a library at data kept
    elsewhere), each folder read once however many links lead to it, so that a link
    back up the tree ends rather than loops and no clip is found twice."""

    def unreadable(exc: OSError) -> None:
        raise MotionFormatError(
            Path(exc.filename or root),
            f"cannot read this folder of the library ({exc.strerror or exc})",
        )

    seen: set[tuple[int, int]] = set()
    found = []
    for folder, subfolders, names in os.walk(root, onerror=unreadable, followlinks=True):
        st = os.stat(folder)
        if (st.st_dev, st.st_ino) in seen:
            subfolders[:] = []  # (reached before, by another path: a loop or a second link)
            continue
        seen.add((st.st_dev, st.st_ino))
        found += [p for p in (Path(folder) / n for n in names) if p.is_file()]
    return sorted(found)


def discover(root: Path, prefer: str) -> list[Source]:
    files = library_files(root)
    by_suffix: dict[str, list[Path]] = {}
    for p in files:
        by_suffix.setdefault(p.suffix.lower(), []).append(p)
    amc: list[Source] = []
    for p in by_suffix.get(".amc", []):
        asfs = sorted(q for q in p.parent.iterdir() if q.suffix.lower() == ".asf")
        if len(asfs) == 1:
            asf = asfs[0]
        else:
            matches = [q for q in asfs if p.stem.startswith(q.stem)]
            if not matches:
                raise MotionFormatError(p, f"no ASF skeleton for this AMC in {p.parent}")
            asf = max(matches, key=lambda q: len(q.stem))
        amc.append(Source(p.stem, p, asf))
    bvh = [Source(p.stem, p, None) for p in by_suffix.get(".bvh", [])]
    arrays = [
        Source(p.name[: -len(ARRAYS_SUFFIX)], p, None)
        for p in by_suffix.get(".npz", [])
        if p.name.endswith(ARRAYS_SUFFIX) and len(p.name) > len(ARRAYS_SUFFIX)
    ]
    first, second = (amc, bvh) if prefer == "amc" else (bvh, amc)
    taken = {s.name for s in first}
    sources = first + [s for s in second if s.name not in taken]
    taken |= {s.name for s in sources}
    sources += [s for s in arrays if s.name not in taken]
    names = [s.name for s in sources]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise MotionFormatError(root, f"clip names occur twice: {', '.join(dupes)}")
    return sorted(sources, key=lambda s: s.name)


def cache_key(src: Source, bvh_units: str | float, asf_digests: dict[Path, bytes]) -> str:
    h = hashlib.sha256()
    h.update(f"mimic-motion/{READER_VERSION}/{src.path.suffix.lower()}/{bvh_units}\0".encode())
    h.update(read_bytes(src.path))
    if src.asf is not None:
        if src.asf not in asf_digests:  # one ASF serves many AMC files
            asf_digests[src.asf] = hashlib.sha256(read_bytes(src.asf)).digest()
        h.update(b"\0asf\0" + asf_digests[src.asf])
    return h.hexdigest()[:32]


_CACHED = ("meta", "parents", "offsets", "end_parents", "end_offsets", "root_pos", "quats")


def _save(path: Path, m: Motion) -> None:
    sk = m.skeleton
    arrays = {
        "parents": np.asarray(sk.parents),
        "offsets": np.asarray(sk.offsets),
        "end_parents": np.asarray(sk.end_parents),
        "end_offsets": np.asarray(sk.end_offsets),
        "root_pos": np.asarray(m.root_pos),
        "quats": np.asarray(m.quats),
    }
    meta: dict[str, Any] = {
        "names": sk.names,
        "channels": sk.channels,
        "fps": m.fps,
        "name": m.name,
        "source": m.source,
    }
    meta["checksum"] = checksum(meta, arrays)
    with atomic_write(path, "wb") as fh:
        np.savez(fh, meta=np.array(json.dumps(meta)), **arrays)  # type: ignore[arg-type]


def load_entry(
    path: Path,
    keys: tuple[str, ...],
    what: str,
    make: Callable[[dict[str, Any], dict[str, np.ndarray]], T],
    again: str,
) -> T | None:
    """``make(meta, arrays)`` of the cache entry at ``path`` (its JSON ``meta`` and its
    arrays ``keys``, checksum verified), or ``None`` with a warning naming the file when
    it is unreadable, inconsistent or fails its checksum (``again``: what is done instead)."""
    try:
        z = read_npz(path, keys, MotionFormatError, what)
        meta = json.loads(str(z.pop("meta")))
        if not isinstance(meta, dict):
            raise MotionFormatError(path, "meta is not a JSON object")
        verify_checksum(meta, z, path, MotionFormatError)
        made = make(meta, z)
    except (MotionFormatError, ValueError, KeyError, TypeError, IndexError) as exc:
        said = str(exc) if isinstance(exc, MotionFormatError) else f"{path}: {exc!r}"
        log.warning("ignoring a bad %s (%s): %s", what, again, said)
        return None
    touch(path)
    return made


def load_cached(path: Path) -> Motion | None:
    """The motion in a cache entry, or ``None`` (with a warning naming the file) when it
    is unreadable, inconsistent, or fails its checksum: it is then parsed again."""

    def make(meta: dict[str, Any], z: dict[str, np.ndarray]) -> Motion:
        sk = Skeleton(
            tuple(meta["names"]),
            z["parents"],
            z["offsets"],
            tuple(tuple(c) for c in meta["channels"]),
            z["end_parents"],
            z["end_offsets"],
        )
        return Motion(sk, z["root_pos"], z["quats"], meta["fps"], meta["name"], meta["source"])

    return load_entry(path, _CACHED, "motion cache entry", make, "parsing again")


def is_arrays(src: Source) -> bool:
    return src.path.name.endswith(ARRAYS_SUFFIX)


def parse(src: Source, bvh_units: str | float) -> Motion:
    if is_arrays(src):
        return read_motion_arrays(src.path, name=src.name)
    if src.asf is not None:
        return read_amc(src.path, read_asf(src.asf), name=src.name)
    return read_bvh(src.path, units=bvh_units, name=src.name)


def parse_job(args: tuple[Source, str | float, str | None]) -> Motion:
    src, bvh_units, cache_file = args
    motion = parse(src, bvh_units)
    if cache_file is not None:
        try:
            _save(Path(cache_file), motion)
        except OSError as exc:  # a read-only or full cache only costs speed
            log.warning("cannot write cache entry %s: %s", cache_file, exc)
    return motion
