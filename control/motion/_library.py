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
a key hashed from the file's bytes (and its ASF's), the reader version and settings; and
the clips as made from them (resampled, mirrored, their contacts) are cached as one entry
(``_whole``), which a warm load reads instead.
"""

from __future__ import annotations

import fnmatch
import logging
import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..artifacts import (
    bound_cache,
    cache_root,
)
from ._clean_labels import clean_labels
from ._contacts import Contacts, detect_contacts
from ._embedded import EMBEDDED_LIBRARY
from ._errors import MotionFormatError
from ._fk import forward_kinematics
from ._metadata import descriptions, label_files, read_labels
from ._ops import mirror as mirror_motion
from ._ops import resample, resample_positions
from ._parsed import Source, cache_key, discover, is_arrays, load_cached, parse, parse_job
from ._quat import FloatArray
from ._types import Motion, Skeleton
from ._whole import MadeClip, load_whole, save_whole, whole_key

__all__ = [
    "Clip",
    "Library",
    "LibrarySpec",
    "action_keys",
    "default_cache_dir",
    "default_library_path",
    "load_library",
    "load_spec",
    "read_labels",
]

log = logging.getLogger(__name__)

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


def action_keys(clips: Sequence[Clip]) -> NDArray[np.int64] | None:
    """The action of every frame of ``clips`` (joined in order) as a number: frames with
    the same label share one, in whichever clip; an unlabelled frame is its clip's own
    action. ``None`` when no frame is labelled (the library names no actions)."""
    if not any((c.labels >= 0).any() for c in clips):
        return None
    names: dict[str, int] = {}
    for c in clips:
        for name in c.label_names:
            names.setdefault(name, len(names))
    out = []
    for i, c in enumerate(clips):
        ids = np.array([names[n] for n in c.label_names] + [len(names) + i], dtype=np.int64)
        out.append(ids[c.labels])  # -1 (unlabelled) picks the clip's own, the last
    return np.concatenate(out) if out else np.zeros(0, dtype=np.int64)


def action_names(clips: Sequence[Clip]) -> list[str]:
    """The name of each of ``action_keys``' numbers: the labels, then each clip's own
    name (its unlabelled frames' action)."""
    names: dict[str, None] = {}
    for c in clips:
        names.update(dict.fromkeys(c.label_names))
    return [*names, *(c.name for c in clips)]


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


# --- loading -------------------------------------------------------------------------------


@dataclass(frozen=True)
class LibrarySpec:
    """What to load (``load_library``'s arguments but the cache, workers and progress):
    the folder, the clips, the rate, mirrored copies, the format preferred, BVH units and
    the contact detector's options, and whether the labels are cleaned."""

    root: Path
    fps: float | None = 15.0
    mirror: bool = False
    prefer: str = "amc"
    bvh_units: str | float = "auto"
    clips: tuple[str, ...] | None = None
    contact_options: dict[str, float | str] = field(default_factory=dict)
    clean_labels: bool = True

    def __post_init__(self) -> None:
        if self.prefer not in ("amc", "bvh"):
            raise ValueError("prefer must be 'amc' or 'bvh'")
        if not self.root.is_dir():
            raise FileNotFoundError(f"motion library {self.root} is not a directory")

    def sources(self) -> list[Source]:
        """The files to load, in order (``MotionFormatError`` when none)."""
        sources = discover(self.root, self.prefer)
        if not sources:
            raise MotionFormatError(self.root, "no .amc, .bvh or .motion.npz clips found")
        if self.clips is not None:
            patterns = list(self.clips)
            sources = [s for s in sources if any(fnmatch.fnmatchcase(s.name, p) for p in patterns)]
            if not sources:
                raise MotionFormatError(self.root, f"no clip matches {', '.join(patterns)}")
        return sources


def load_library(
    root: str | Path | None = None,
    fps: float | None = 15.0,
    mirror: bool | str = False,
    prefer: str = "amc",
    bvh_units: str | float = "auto",
    cache_dir: str | Path | None = None,
    use_cache: bool = True,
    workers: int | None = None,
    contact_options: dict[str, float | str] | None = None,
    progress: Callable[[str], None] | None = None,
    clips: Sequence[str] | None = None,
    clean_labels: bool = True,
) -> Library:
    """Load every clip under ``root`` at ``fps`` frames/s.

    Parameters
    ----------
    root : the library folder; ``default_library_path()`` when ``None``.
    fps : target rate (Lee et al. use 15); ``None`` keeps each clip's own rate.
    mirror : also add a left/right mirrored copy of every clip (``<name>_mirror``);
        ``"labelled"``: of every clip with labels only (``mimic perform``'s library for
        landmarks: the same actions done with the other arm and leg; an unlabelled
        clip's copy would only be one more unnamed action to its vote).
    prefer : ``"amc"`` or ``"bvh"``, which format to take when a take exists in both.
    bvh_units : passed to ``read_bvh``.
    cache_dir : where parsed files are cached; ``default_cache_dir()`` when ``None``.
    use_cache : set False to neither read nor write the cache.
    workers : processes for parsing on a cold load (default: CPU count, at most 4).
    contact_options : keyword arguments for ``detect_contacts``.
    progress : called with a short message per clip parsed.
    clips : keep only clips whose name matches one of these shell patterns (``"01_*"``).
    clean_labels : each boundary between two labelled actions moved to where the motion
        changes (``control.motion.clean_labels``); False: the label files' own
        boundaries, as a ground truth is read.

    The first group of arguments is the ``LibrarySpec`` (what to load), the second how
    (the cache, processes, progress): ``load_spec(spec, ...)`` takes them so.

    Raises
    ------
    MotionFormatError
        for the first file that cannot be read, naming it.
    """
    if mirror not in (False, True, "labelled"):
        raise ValueError(f"mirror must be True, False or 'labelled', not {mirror!r}")
    spec = LibrarySpec(
        Path(root) if root is not None else default_library_path(),
        fps,
        bool(mirror),
        prefer,
        bvh_units,
        tuple(clips) if clips is not None else None,
        dict(contact_options or {}),
        clean_labels,
    )
    library = load_spec(spec, cache_dir, use_cache, workers, progress)
    if mirror == "labelled":
        kept = tuple(c for c in library.clips if not c.mirrored or (c.labels >= 0).any())
        library = replace(library, clips=kept)
    return library


def load_spec(
    spec: LibrarySpec,
    cache_dir: str | Path | None = None,
    use_cache: bool = True,
    workers: int | None = None,
    progress: Callable[[str], None] | None = None,
) -> Library:
    """The library ``spec`` names: its clips made (parsed or read from the cache, then
    resampled, mirrored, their contacts found) or read whole from the cache, with their
    labels and descriptions."""
    sources = spec.sources()
    if not use_cache:
        motions = _parse_all(spec, sources, [None] * len(sources), workers, progress)
        return _library_of(spec, sources, _made(spec, sources, motions))
    cache = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    asf_digests: dict[Path, bytes] = {}
    keys = [cache_key(src, spec.bvh_units, asf_digests) for src in sources]
    options = {
        "fps": spec.fps,
        "mirror": spec.mirror,
        "bvh_units": spec.bvh_units,
        "contacts": spec.contact_options,
    }
    whole = cache / f"library-{whole_key(sources, keys, options)}.npz"
    made = load_whole(whole) if whole.is_file() else None
    if made is None:
        entries = [cache / f"{k}.npz" for k in keys]
        motions = _parse_all(spec, sources, entries, workers, progress)
        made = _made(spec, sources, motions)
        try:
            save_whole(whole, made)
        except OSError as exc:  # a read-only or full cache only costs speed
            log.warning("cannot write cache entry %s: %s", whole, exc)
        if cache_dir is None:  # new entries: bound the cache (never this library's)
            bound_cache(keep=[whole, *entries])
    return _library_of(spec, sources, made)


def _parse_all(
    spec: LibrarySpec,
    sources: list[Source],
    entries: Sequence[Path | None],
    workers: int | None,
    progress: Callable[[str], None] | None,
) -> dict[str, Motion]:
    """Every source's motion: from its cache entry (``entries``, ``None``: no cache) where
    that holds a good one, else parsed (in ``workers`` processes) and cached there."""
    bvh_units = spec.bvh_units
    motions: dict[str, Motion] = {}
    todo: list[tuple[Source, str | float, str | None]] = []
    for src, entry in zip(sources, entries, strict=True):
        if is_arrays(src):  # already compact arrays: read directly, never cached
            motions[src.name] = parse(src, bvh_units)
            continue
        hit = load_cached(entry) if entry is not None and entry.is_file() else None
        if hit is not None:  # (two files of the same bytes share an entry: the name and
            # the path are this file's, not those of the file that made the entry)
            motions[src.name] = replace(hit, name=src.name, source=str(src.path))
        else:
            todo.append((src, bvh_units, None if entry is None else str(entry)))
    n_workers = min(workers or min(os.cpu_count() or 1, 4), len(todo))
    if n_workers > 1:
        try:
            with ProcessPoolExecutor(n_workers) as pool:
                for (src, _, _), motion in zip(todo, pool.map(parse_job, todo), strict=True):
                    motions[src.name] = motion
                    if progress:
                        progress(f"parsed {src.path.name}")
        except BrokenProcessPool:
            # A forked worker can die at birth, e.g. when numba's OpenMP threads already
            # run in this process; parse what is left here instead.
            log.warning("parsing worker processes failed; parsing in this process")
    for job in todo:
        if job[0].name not in motions:
            motions[job[0].name] = parse_job(job)
            if progress:
                progress(f"parsed {job[0].path.name}")
    return motions


def _made(spec: LibrarySpec, sources: list[Source], motions: dict[str, Motion]) -> list[MadeClip]:
    """Each source's clip (and its mirrored copy) at the library's rate, with contacts."""
    made = []
    for src in sources:
        raw = motions[src.name]
        variants = [(raw, False)] + ([(mirror_motion(raw), True)] if spec.mirror else [])
        for motion, mirrored in variants:
            made.append(_make(motion, spec.fps, mirrored, spec.contact_options))
    return made


def _library_of(spec: LibrarySpec, sources: list[Source], made: list[MadeClip]) -> Library:
    """The library of the ``made`` clips (each source's, then its mirrored copy's), with
    their labels and descriptions."""
    described = descriptions(spec.root, {s.name for s in sources})
    labelled = label_files(spec.root)
    per_source = 2 if spec.mirror else 1
    if len(made) != per_source * len(sources):
        raise ValueError("one made clip per source (and mirrored copy) is needed")
    kept: list[Clip] = []
    for i, src in enumerate(sources):
        for m in made[per_source * i : per_source * (i + 1)]:
            labels, label_names = (
                read_labels(labelled[src.name], m.source_length)
                if src.name in labelled
                else (np.full(m.source_length, -1, dtype=np.int64), ())
            )
            frame_labels = labels[np.rint(m.source_frames).astype(np.int64)]
            if spec.clean_labels:
                rate = m.motion.fps if spec.fps is None else float(spec.fps)
                frame_labels, _ = clean_labels(m.motion.quats, frame_labels, rate)
            kept.append(
                Clip(
                    m.motion,
                    m.contacts,
                    described.get(src.name, ""),
                    frame_labels,
                    label_names,
                    m.source_frames,
                    str(src.path),
                    m.mirrored,
                )
            )
    fps = None if spec.fps is None else float(spec.fps)
    return Library(str(spec.root), fps, tuple(kept))


def _make(
    motion: Motion, fps: float | None, mirrored: bool, contact_options: dict[str, float | str]
) -> MadeClip:
    source_length = motion.n_frames
    if fps is None or fps == motion.fps:
        source_frames = np.arange(motion.n_frames, dtype=np.float64)
    else:
        source_frames = resample_positions(motion.n_frames, motion.fps, fps)
        motion = resample(motion, fps)
    contacts = detect_contacts(motion, forward_kinematics(motion), **contact_options)  # type: ignore[arg-type]
    return MadeClip(motion, contacts, source_frames, source_length, mirrored)
