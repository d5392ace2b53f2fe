"""A motion library: a directory of clips (ASF/AMC, BVH or both) with metadata, cached.

Discovery: every ``*.amc`` (paired with the ``*.asf`` in its folder: the only one, or the
one whose name is the longest prefix of the AMC's), every ``*.bvh`` and every
``*.motion.npz`` (motion arrays, the embedded default library's format) under the root.
A take present in both formats is loaded once, from ``prefer`` (motion arrays only when
neither exists). Metadata:

- descriptions from ``descriptions.csv`` (``clip,description``) or from a Markdown table
  with ``clip`` and ``description`` columns in a ``README.md`` under the root;
- labels from ``<clip>.csv`` files in a ``labels`` folder (``first_frame,last_frame,action``,
  1-based inclusive source frames; a range running past the clip's end is clamped).

Parsing dominates a cold load, so each parsed file is cached as ``.npz`` (no pickle) under
a key hashed from the file's bytes (and its ASF's), the reader version and settings.
"""

from __future__ import annotations

import csv
import fnmatch
import hashlib
import io
import json
import logging
import os
import re
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..artifacts import (
    atomic_write,
    bound_cache,
    cache_root,
    checksum,
    read_npz,
    touch,
    verify_checksum,
)
from ._amc import read_amc
from ._arrays import ARRAYS_SUFFIX, read_motion_arrays
from ._asf import read_asf
from ._bvh import read_bvh
from ._contacts import Contacts, detect_contacts
from ._embedded import EMBEDDED_LIBRARY
from ._errors import MotionFormatError
from ._fk import forward_kinematics
from ._ops import mirror as mirror_motion
from ._ops import resample, resample_positions
from ._quat import FloatArray
from ._text import decode, read_bytes
from ._types import Motion, Skeleton

__all__ = [
    "Clip",
    "Library",
    "default_cache_dir",
    "default_library_path",
    "load_library",
    "read_labels",
]

log = logging.getLogger(__name__)

#: Bump when a reader's output changes, so stale cache entries are never used.
READER_VERSION = "2"  # 2: cache entries carry a checksum
ENV_LIBRARY = "MIMIC_MOCAP"


@dataclass(frozen=True, eq=False)
class Clip:
    """One clip of the library at the library's frame rate.

    Attributes
    ----------
    motion : the clip.
    contacts : foot contacts per frame.
    description : human text, ``""`` when none is known.
    labels : (F,) int index into ``label_names`` per frame, -1 where unlabelled.
    label_names : the action names of this clip's label file.
    source_frames : (F,) float, the 0-based frame of the source file each frame comes from.
    path : the source file.
    mirrored : True for a left/right mirrored copy.
    """

    motion: Motion
    contacts: Contacts
    description: str
    labels: NDArray[np.int64]
    label_names: tuple[str, ...]
    source_frames: FloatArray
    path: str
    mirrored: bool = False

    @property
    def name(self) -> str:
        return self.motion.name

    def label_at(self, frame: int) -> str | None:
        k = int(self.labels[frame])
        return None if k < 0 else self.label_names[k]


@dataclass(frozen=True, eq=False)
class Library:
    """The clips of a library, all at ``fps`` frames/s (``None``: each at its own rate)."""

    root: str
    fps: float | None
    clips: tuple[Clip, ...]

    @property
    def n_frames(self) -> int:
        return sum(c.motion.n_frames for c in self.clips)

    @property
    def duration(self) -> float:
        return sum(c.motion.n_frames / c.motion.fps for c in self.clips)

    def clip(self, name: str) -> Clip:
        for c in self.clips:
            if c.name == name:
                return c
        raise KeyError(f"no clip named {name!r} in {self.root}")

    def skeletons(self) -> list[Skeleton]:
        """The distinct skeletons, in order of first use."""
        out: list[Skeleton] = []
        for c in self.clips:
            if not any(c.motion.skeleton is s or c.motion.skeleton.same_as(s) for s in out):
                out.append(c.motion.skeleton)
        return out


def shared_library_candidates() -> tuple[Path, ...]:
    """Where a full library is looked for: ``../shared/mocap`` beside the checkout, then
    beside the working directory."""
    here = Path(__file__).resolve()
    return (here.parents[3] / "shared" / "mocap", Path.cwd().parent / "shared" / "mocap")


def default_library_path() -> Path:
    """``$MIMIC_MOCAP``, else ``../shared/mocap`` beside the checkout (or the working
    directory), else the embedded default library shipped in the package."""
    env = os.environ.get(ENV_LIBRARY)
    if env:
        return Path(env)
    for candidate in shared_library_candidates():
        if candidate.is_dir():
            return candidate
    if EMBEDDED_LIBRARY.is_dir():
        return EMBEDDED_LIBRARY
    raise FileNotFoundError(
        f"no motion library found: set {ENV_LIBRARY} or pass a directory "
        f"(the default is ../shared/mocap beside the repository, then {EMBEDDED_LIBRARY})"
    )


def default_cache_dir() -> Path:
    """The parsed-motion folder of the cache: ``cache_root() / "motion"``."""
    return cache_root() / "motion"


# --- discovery -----------------------------------------------------------------------------


@dataclass(frozen=True)
class _Source:
    name: str
    path: Path
    asf: Path | None  # for AMC


def _discover(root: Path, prefer: str) -> list[_Source]:
    files = sorted(p for p in root.rglob("*") if p.is_file())
    by_suffix: dict[str, list[Path]] = {}
    for p in files:
        by_suffix.setdefault(p.suffix.lower(), []).append(p)
    amc: list[_Source] = []
    for p in by_suffix.get(".amc", []):
        asfs = sorted(q for q in p.parent.iterdir() if q.suffix.lower() == ".asf")
        if len(asfs) == 1:
            asf = asfs[0]
        else:
            matches = [q for q in asfs if p.stem.startswith(q.stem)]
            if not matches:
                raise MotionFormatError(p, f"no ASF skeleton for this AMC in {p.parent}")
            asf = max(matches, key=lambda q: len(q.stem))
        amc.append(_Source(p.stem, p, asf))
    bvh = [_Source(p.stem, p, None) for p in by_suffix.get(".bvh", [])]
    arrays = [
        _Source(p.name[: -len(ARRAYS_SUFFIX)], p, None)
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


# --- metadata ------------------------------------------------------------------------------


def _expand(cell: str, names: set[str]) -> list[str]:
    """Clip names a table cell refers to: ``02_01``, ``03_01..03_04``, ``09_01 (BVH only)``."""
    cell = re.sub(r"\(.*?\)", "", cell).strip()
    m = re.fullmatch(r"(\S+)\.\.(\S+)", cell)
    if m:
        lo, hi = m.groups()
        return sorted(n for n in names if lo <= n <= hi and len(n) == len(lo))
    return [cell] if cell in names else []


def _descriptions(root: Path, names: set[str]) -> dict[str, str]:
    out: dict[str, str] = {}
    for readme in sorted(root.rglob("README.md")):
        text = readme.read_text(encoding="utf-8", errors="replace")
        header: list[str] | None = None
        for line in text.splitlines():
            cells = (
                [c.strip() for c in line.strip().strip("|").split("|")]
                if line.lstrip().startswith("|")
                else None
            )
            if cells is None:
                header = None
                continue
            low = [c.lower() for c in cells]
            if "clip" in low and "description" in low:
                header = low
                continue
            if header is None or len(cells) != len(header) or set(cells[0]) <= set("-: "):
                continue
            for n in _expand(cells[header.index("clip")], names):
                out.setdefault(n, cells[header.index("description")])
    for table in sorted(root.rglob("descriptions.csv")):
        try:
            data = table.read_bytes()
        except OSError as exc:
            raise MotionFormatError(table, f"cannot read: {exc.strerror or exc}") from None
        if not data.strip():
            continue
        text = decode(table, data)  # not UTF-8: an error naming the file
        try:
            for row in csv.DictReader(io.StringIO(text)):
                if row.get("clip") in names and row.get("description"):
                    out[row["clip"]] = row["description"]
        except csv.Error as exc:
            raise MotionFormatError(table, f"not a descriptions CSV ({exc})") from None
    return out


def _label_files(root: Path) -> dict[str, Path]:
    return {p.stem: p for p in sorted(root.rglob("*.csv")) if p.parent.name == "labels"}


def read_labels(path: Path, n_frames: int) -> tuple[NDArray[np.int64], tuple[str, ...]]:
    """Per source frame ``(n_frames,)`` label index (-1 unlabelled) and the label names."""
    text = decode(path, read_bytes(path))
    try:
        rows = list(csv.reader(io.StringIO(text)))
    except csv.Error as exc:  # a huge field, a stray quote
        raise MotionFormatError(path, f"not a labels CSV ({exc})") from None
    if not rows or [c.strip() for c in rows[0]] != ["first_frame", "last_frame", "action"]:
        raise MotionFormatError(path, "header must be first_frame,last_frame,action", 1)
    labels = np.full(n_frames, -1, dtype=np.int64)
    names: list[str] = []
    for n, row in enumerate(rows[1:], start=2):
        if not row or not "".join(row).strip():
            continue
        if len(row) != 3:
            raise MotionFormatError(path, f"expected 3 fields, got {len(row)}", n)
        try:
            first, last = int(row[0]), int(row[1])
        except ValueError:
            raise MotionFormatError(
                path, f"frame numbers must be whole numbers: {row[:2]}", n
            ) from None
        action = row[2].strip()
        if not action:
            raise MotionFormatError(path, "empty action name", n)
        if first < 1 or last < first:
            raise MotionFormatError(path, f"bad frame range {first}..{last}", n)
        if first > n_frames:
            raise MotionFormatError(
                path, f"range starts at frame {first}, the clip has {n_frames}", n
            )
        if action not in names:
            names.append(action)
        k = names.index(action)
        span = labels[first - 1 : min(last, n_frames)]
        clash = (span >= 0) & (span != k)
        if clash.any():
            raise MotionFormatError(path, f"range {first}..{last} overlaps another action", n)
        span[:] = k
    return labels, tuple(names)


# --- cache ---------------------------------------------------------------------------------


def _cache_key(src: _Source, bvh_units: str | float, asf_digests: dict[Path, bytes]) -> str:
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


def _load(path: Path) -> Motion | None:
    """The motion in a cache entry, or ``None`` (with a warning naming the file) when it
    is unreadable, inconsistent, or fails its checksum: it is then parsed again."""
    try:
        z = read_npz(path, _CACHED, MotionFormatError, "motion cache entry")
        meta = json.loads(str(z.pop("meta")))
        if not isinstance(meta, dict):
            raise MotionFormatError(path, "meta is not a JSON object")
        verify_checksum(meta, z, path, MotionFormatError)
        sk = Skeleton(
            tuple(meta["names"]),
            z["parents"],
            z["offsets"],
            tuple(tuple(c) for c in meta["channels"]),
            z["end_parents"],
            z["end_offsets"],
        )
        motion = Motion(sk, z["root_pos"], z["quats"], meta["fps"], meta["name"], meta["source"])
    except (MotionFormatError, ValueError, KeyError, TypeError, IndexError) as exc:
        said = str(exc) if isinstance(exc, MotionFormatError) else f"{path}: {exc!r}"
        log.warning("ignoring a bad cache entry (parsing again): %s", said)
        return None
    touch(path)
    return motion


def _is_arrays(src: _Source) -> bool:
    return src.path.name.endswith(ARRAYS_SUFFIX)


def _parse(src: _Source, bvh_units: str | float) -> Motion:
    if _is_arrays(src):
        return read_motion_arrays(src.path, name=src.name)
    if src.asf is not None:
        return read_amc(src.path, read_asf(src.asf), name=src.name)
    return read_bvh(src.path, units=bvh_units, name=src.name)


def _parse_job(args: tuple[_Source, str | float, str | None]) -> Motion:
    src, bvh_units, cache_file = args
    motion = _parse(src, bvh_units)
    if cache_file is not None:
        try:
            _save(Path(cache_file), motion)
        except OSError as exc:  # a read-only or full cache only costs speed
            log.warning("cannot write cache entry %s: %s", cache_file, exc)
    return motion


# --- loading -------------------------------------------------------------------------------


def load_library(
    root: str | Path | None = None,
    fps: float | None = 15.0,
    mirror: bool = False,
    prefer: str = "amc",
    bvh_units: str | float = "auto",
    cache_dir: str | Path | None = None,
    use_cache: bool = True,
    workers: int | None = None,
    contact_options: dict[str, float | str] | None = None,
    progress: Callable[[str], None] | None = None,
    clips: Sequence[str] | None = None,
) -> Library:
    """Load every clip under ``root`` at ``fps`` frames/s.

    Parameters
    ----------
    root : the library folder; ``default_library_path()`` when ``None``.
    fps : target rate (Lee et al. use 15); ``None`` keeps each clip's own rate.
    mirror : also add a left/right mirrored copy of every clip (``<name>_mirror``).
    prefer : ``"amc"`` or ``"bvh"``, which format to take when a take exists in both.
    bvh_units : passed to ``read_bvh``.
    cache_dir : where parsed files are cached; ``default_cache_dir()`` when ``None``.
    use_cache : set False to neither read nor write the cache.
    workers : processes for parsing on a cold load (default: CPU count, at most 4).
    contact_options : keyword arguments for ``detect_contacts``.
    progress : called with a short message per clip parsed.
    clips : keep only clips whose name matches one of these shell patterns (``"01_*"``).

    Raises
    ------
    MotionFormatError
        for the first file that cannot be read, naming it.
    """
    if prefer not in ("amc", "bvh"):
        raise ValueError("prefer must be 'amc' or 'bvh'")
    root = Path(root) if root is not None else default_library_path()
    if not root.is_dir():
        raise FileNotFoundError(f"motion library {root} is not a directory")
    sources = _discover(root, prefer)
    if not sources:
        raise MotionFormatError(root, "no .amc, .bvh or .motion.npz clips found")
    if clips is not None:
        patterns = list(clips)
        sources = [s for s in sources if any(fnmatch.fnmatchcase(s.name, p) for p in patterns)]
        if not sources:
            raise MotionFormatError(root, f"no clip matches {', '.join(patterns)}")
    cache = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    motions: dict[str, Motion] = {}
    todo: list[tuple[_Source, str | float, str | None]] = []
    asf_digests: dict[Path, bytes] = {}
    used: list[Path] = []  # this library's cache entries, never evicted for it
    for src in sources:
        if _is_arrays(src):  # already compact arrays: read directly, never cached
            motions[src.name] = _parse(src, bvh_units)
            continue
        if not use_cache:
            todo.append((src, bvh_units, None))
            continue
        cache_file = cache / f"{_cache_key(src, bvh_units, asf_digests)}.npz"
        used.append(cache_file)
        hit = _load(cache_file) if cache_file.is_file() else None
        if hit is not None:
            motions[src.name] = hit
        else:
            todo.append((src, bvh_units, str(cache_file)))
    n_workers = min(workers or min(os.cpu_count() or 1, 4), len(todo))
    if n_workers > 1:
        try:
            with ProcessPoolExecutor(n_workers) as pool:
                for (src, _, _), motion in zip(todo, pool.map(_parse_job, todo), strict=True):
                    motions[src.name] = motion
                    if progress:
                        progress(f"parsed {src.path.name}")
        except BrokenProcessPool:
            # A forked worker can die at birth, e.g. when numba's OpenMP threads already
            # run in this process; parse what is left here instead.
            log.warning("parsing worker processes failed; parsing in this process")
    for job in todo:
        if job[0].name not in motions:
            motions[job[0].name] = _parse_job(job)
            if progress:
                progress(f"parsed {job[0].path.name}")
    if cache_dir is None and any(job[2] for job in todo):  # new entries: bound the cache
        bound_cache(keep=used)

    names = {s.name for s in sources}
    descriptions = _descriptions(root, names)
    label_files = _label_files(root)
    kept: list[Clip] = []
    for src in sources:
        raw = motions[src.name]
        labels, label_names = (
            read_labels(label_files[src.name], raw.n_frames)
            if src.name in label_files
            else (np.full(raw.n_frames, -1, dtype=np.int64), ())
        )
        variants = [(raw, False)]
        if mirror:
            variants.append((mirror_motion(raw), True))
        for motion, mirrored in variants:
            kept.append(
                _make_clip(
                    motion,
                    fps,
                    descriptions.get(src.name, ""),
                    labels,
                    label_names,
                    str(src.path),
                    mirrored,
                    contact_options or {},
                )
            )
    return Library(str(root), None if fps is None else float(fps), tuple(kept))


def _make_clip(
    motion: Motion,
    fps: float | None,
    description: str,
    labels: NDArray[np.int64],
    label_names: tuple[str, ...],
    path: str,
    mirrored: bool,
    contact_options: dict[str, float | str],
) -> Clip:
    if fps is None or fps == motion.fps:
        source_frames = np.arange(motion.n_frames, dtype=np.float64)
    else:
        source_frames = resample_positions(motion.n_frames, motion.fps, fps)
        motion = resample(motion, fps)
    contacts = detect_contacts(motion, forward_kinematics(motion), **contact_options)  # type: ignore[arg-type]
    frame_labels = labels[np.rint(source_frames).astype(np.int64)]
    return Clip(
        motion, contacts, description, frame_labels, label_names, source_frames, path, mirrored
    )
