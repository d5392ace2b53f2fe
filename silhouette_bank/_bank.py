"""The bank on disk: features of every library frame from every view.

Layout of a bank folder::

    manifest.json          format, version, library digest, settings and their hash,
                           clips, shard table, complete flag
    shard-00003.npz        features (n, V, F) float32, root_motion (n, V, 2) float32,
                           for the frames [start, stop) of the library (one file a shard)
    features.npy           all shards' features merged, at half precision
                           (``FEATURE_DTYPE``), and
    root_motion.npy        their root motion: plain ``.npy`` files, opened memory-mapped
                           (a bank is not copied into memory)
    bank.npz               the small arrays (clip starts, key, the learned metric)
    index-<t>-<hash>.npz   the matcher's window index of these features (``<t>``: its
                           window tables' key)
                           (``vision.cached_window_index``: made by the first run that
                           needs it, loaded by the next)
    windows-<hash>.*       the matcher's window tables and shape statistics made from
                           these features (``vision.cached_window_tables``: likewise)
    checked.json           which ``.npy`` files were checked, as the file system saw
                           them (``open_mapped``: an unchanged file is not read again)
    .building.lock         held while a process builds the bank (``cached_bank``)

Everything is written to a temporary file and renamed; ``manifest.json`` is written last
(the bank is complete). One checksum covers the manifest and ``bank.npz``; the manifest
holds a SHA-256 of every block of ``BLOCK_ROWS`` frames of the two ``.npy`` files, checked
block by block when the bank is first opened (streamed: the check reads the pages once
and holds none of them); later opens trust a file the file system says is unchanged
since (``_arrays``), so a large bank opens without being read. Shards are independent, so they
can be built by several processes (``workers``) or on a Dask cluster (``cluster``:
``control.jobs``) and merged; an interrupted build finds its finished shards (checked
against the manifest's key) and does only the rest. A bank whose library or settings
differ from the requested ones is stale: it is rebuilt, never used. Files are read
without pickle; a corrupt or truncated file is a ``BankFileError`` that names it.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from control.artifacts import (
    atomic_write,
    cache_root,
    checksum,
    read_checked_npz,
    read_npz,
    verify_checksum,
    write_checked_npz,
)
from control.jobs import run_jobs
from control.motion import Clip, clips_digest

from ._arrays import block_hashes, npy_file, open_mapped
from ._descriptor import get_descriptor
from ._metric import MetricJob, fit_metric, metric_jobs, metric_samples
from ._settings import BANK_VERSION, BankSettings
from ._shard import ShardJob, shard_job

__all__ = [
    "FEATURE_DTYPE",
    "Bank",
    "BankFileError",
    "StaleBankError",
    "bank_cache_dir",
    "bank_key",
    "build_bank",
    "load_bank",
]

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float32]

#: a complete bank's features: half precision (half the size). Rounding moves a feature by
#: at most 0.07% of its spread, any descriptor, and changed no decision of the following
#: folds (``accuracy_float16.json``). Shards and the root motion stay float32.
FEATURE_DTYPE = np.float16

#: frames of ``features.npy`` and ``root_motion.npy`` hashed as one block when a bank is
#: written (the manifest's ``blocks``; a bank is read with its own)
BLOCK_ROWS = 4096
#: the bank's arrays stored as memory-mapped ``.npy`` files, and their types
_MAPPED = {"features": FEATURE_DTYPE, "root_motion": np.float32}


class BankFileError(ValueError):
    """A bank file that cannot be used; the message names the file and the problem."""

    def __init__(self, path: str | Path, problem: str) -> None:
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{path}: {problem}")


class StaleBankError(BankFileError):
    """A bank built from another library or with other settings."""


@dataclass(frozen=True, eq=False)
class Bank:
    """A complete bank.

    Attributes
    ----------
    features : (n, V, F) per library frame and view (``F`` is
        ``settings.features.size``; the descriptor object knows the layout), stored as
        ``FEATURE_DTYPE``.
    root_motion : (n, V, 2) the root's image motion since the previous frame.
    clip_names, clip_start : which frames belong to which clip.
    settings : how it was rendered. library_digest : what it was rendered from.
    path : the folder.
    checksum : the manifest's checksum (it covers every array): what the bank's derived
        files (window tables, index) are keyed by; ``""`` for a bank not read from disk.
    metric : ``(mean (S,), projection (S, d))`` of the learned metric, or ``None``: shape
        numbers ``x`` are compared as ``(x - mean) @ projection``.
    """

    features: NDArray[np.float16]
    root_motion: FloatArray
    clip_names: tuple[str, ...]
    clip_start: NDArray[np.int64]
    settings: BankSettings
    library_digest: str
    path: str
    metric: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
    checksum: str = ""

    @property
    def n_frames(self) -> int:
        return int(self.clip_start[-1])

    def frame_of(self, clip: str, frame: int) -> int:
        if clip not in self.clip_names:
            raise ValueError(f"the bank has no clip {clip!r}")
        c = self.clip_names.index(clip)
        if not 0 <= frame < self.clip_start[c + 1] - self.clip_start[c]:
            raise ValueError(f"clip {clip} has no frame {frame}")
        return int(self.clip_start[c] + frame)


def bank_cache_dir() -> Path:
    """The banks' folder of the cache: ``cache_root() / "bank"``."""
    return cache_root() / "bank"


def bank_key(digest: str, settings: BankSettings) -> str:
    """The cache key of a bank of the library ``digest`` with ``settings``."""
    return hashlib.sha256(f"{digest}|{settings.digest()}".encode()).hexdigest()[:24]


def _write_shard(path: str, arrays: dict[str, np.ndarray]) -> None:
    write_checked_npz(path, arrays)


def _read_npz(path: Path, keys: Sequence[str]) -> dict[str, np.ndarray]:
    return read_npz(path, keys, BankFileError, "bank file")


def _shard_ok(path: Path, n: int, views: int, size: int) -> bool:
    if not path.is_file():
        return False
    try:
        d = read_checked_npz(path, ("features", "root_motion"), BankFileError, "bank file")
    except BankFileError:
        return False
    return d["features"].shape == (n, views, size) and d["root_motion"].shape == (n, views, 2)


def build_bank(
    clips: Sequence[Clip],
    settings: BankSettings,
    folder: str | Path,
    shard_frames: int = 1000,
    workers: int | None = None,
    progress: Callable[[int, int], None] | None = None,
    cluster: str | None = None,
) -> Bank:
    """Render every frame of ``clips`` into the bank at ``folder`` (resuming if possible).

    With ``workers`` > 1 the shards and the learned metric's renders (``metric_jobs``)
    are made in *spawned* processes (numba's OpenMP threads make fork unsafe), so a
    script that calls this must guard its entry point with ``if __name__ ==
    "__main__":``. With a ``cluster`` (or ``$MIMIC_CLUSTER``: ``control.jobs``)
    they are made on a Dask cluster instead; the bank is the same bit for bit.
    ``progress(done, total)`` counts the silhouettes of both as their jobs finish (a
    shard's frames times its views; a metric job's frames times its views, each with
    and without a shadow), so that its rate and time left hold from the first shard to
    the last metric job (tens of times smaller than a shard).
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    if shard_frames < 1:
        raise ValueError("shard_frames must be at least 1")
    manifest = _start_manifest(clips, settings, folder, shard_frames)
    shards: list[dict[str, Any]] = manifest["shards"]
    todo = _shards_to_render(clips, settings, folder, manifest)
    t0 = time.perf_counter()
    metric = []
    if settings.metric_dims:
        metric = metric_jobs(clips, settings.descriptor, settings.ring, settings.body)
    samples = _render(todo, shards, settings.n_views, workers, progress, metric, cluster)
    manifest["blocks"] = _merge(settings, folder, manifest)
    arrays: dict[str, np.ndarray] = {
        "clip_start": np.asarray(manifest["clip_start"], dtype=np.int64),
        "key": np.array(manifest["key"]),
    }
    if metric:
        mean, proj = fit_metric(metric, samples, settings.metric_dims)
        arrays.update(metric_mean=mean, metric=proj)
    manifest["complete"] = True
    manifest["built"] = {
        "seconds": round(time.perf_counter() - t0, 3),
        "rendered_shards": len(todo),
    }
    manifest["checksum"] = checksum(manifest, arrays)
    with atomic_write(folder / "bank.npz", "wb") as fh:
        np.savez(fh, **arrays)  # type: ignore[arg-type]  # (numpy's hints: allow_pickle)
    with atomic_write(folder / "manifest.json") as fh:
        json.dump(manifest, fh, indent=1)
    for s in shards:  # merged: the shards would only double the bank's size on disk
        (folder / str(s["file"])).unlink(missing_ok=True)
    return load_bank(folder)


def _start_manifest(
    clips: Sequence[Clip], settings: BankSettings, folder: Path, shard_frames: int
) -> dict[str, Any]:
    """The manifest of an incomplete bank with its shard table, written (the files of
    another library's or settings' bank in ``folder`` removed first)."""
    digest = clips_digest(clips)
    key = bank_key(digest, settings)
    sizes = [c.motion.n_frames for c in clips]
    starts = np.concatenate(([0], np.cumsum(sizes))).astype(np.int64)
    n = int(starts[-1])
    bounds = [*range(0, n, shard_frames), n]
    shards: list[dict[str, Any]] = [
        {"index": i, "start": a, "stop": b, "file": f"shard-{i:05d}-{key[:8]}.npz"}
        for i, (a, b) in enumerate(itertools.pairwise(bounds))
    ]
    manifest: dict[str, Any] = {
        "format": "mimic-bank",
        "version": BANK_VERSION,
        "key": key,
        "library_digest": digest,
        "settings": settings.to_dict(),
        "settings_digest": settings.digest(),
        "clip_names": [c.name for c in clips],
        "clip_start": starts.tolist(),
        "views": settings.n_views,
        "shards": shards,
        "complete": False,
        "built": None,
    }
    old = folder / "manifest.json"
    if old.is_file():
        try:
            previous = json.loads(old.read_bytes().decode("utf-8"))
        except (OSError, ValueError):
            previous = {}
        if (
            not isinstance(previous, dict) or previous.get("key") != key
        ):  # another library or settings: start afresh
            for p in [*folder.glob("shard-*.npz"), *folder.glob("index-*.npz")]:
                p.unlink()
            for name in ("bank.npz", *(f"{k}.npy" for k in _MAPPED)):
                (folder / name).unlink(missing_ok=True)
    with atomic_write(old) as fh:
        json.dump(manifest, fh, indent=1)
    return manifest


def _shards_to_render(
    clips: Sequence[Clip], settings: BankSettings, folder: Path, manifest: dict[str, Any]
) -> list[ShardJob]:
    """The jobs of the shards not yet (or not soundly) on disk."""
    starts = manifest["clip_start"]
    views, size = settings.n_views, settings.features.size
    todo: list[ShardJob] = []
    for s in manifest["shards"]:
        path = folder / str(s["file"])
        if _shard_ok(path, int(s["stop"]) - int(s["start"]), views, size):
            continue
        pieces = []
        for c, clip in enumerate(clips):
            a = max(int(s["start"]), int(starts[c]))
            b = min(int(s["stop"]), int(starts[c + 1]))
            if a < b:
                pieces.append((clip.motion, a - int(starts[c]), b - int(starts[c])))
        todo.append((int(s["index"]), pieces, settings, str(path)))
    return todo


def _run_job(
    job: ShardJob | MetricJob,
) -> tuple[int, dict[str, np.ndarray]] | NDArray[np.float32]:
    return metric_samples(job) if isinstance(job, MetricJob) else shard_job(job)


def _render(
    todo: list[ShardJob],
    shards: list[dict[str, Any]],
    views: int,
    workers: int | None,
    progress: Callable[[int, int], None] | None,
    metric: Sequence[MetricJob] = (),
    cluster: str | None = None,
) -> list[NDArray[np.float32]]:
    """Render the ``todo`` shards of the manifest's ``shards`` (each written as it comes
    back; ``views`` a frame), then the ``metric`` jobs (their samples returned, in
    order), where ``run_jobs`` says; ``progress(silhouettes done, silhouettes in all)``."""
    jobs: list[ShardJob | MetricJob] = [*todo, *metric]
    weight = [_silhouettes(job) for job in jobs]
    frames = sum(int(s["stop"]) - int(s["start"]) for s in shards)
    kept = frames * views - sum(weight[: len(todo)])  # (shards of a build stopped before)
    total = kept + sum(weight)
    done = kept
    if progress:
        progress(done, total)
    samples: dict[int, NDArray[np.float32]] = {}

    def take(i: int, out: Any) -> None:
        nonlocal done
        if i < len(todo):
            _write_shard(todo[i][3], out[1])
        else:
            samples[i] = out
        done += weight[i]
        if progress:
            progress(done, total)

    run_jobs(_run_job, jobs, take, workers, cluster)
    return [samples[i] for i in sorted(samples)]


def _silhouettes(job: ShardJob | MetricJob) -> int:
    """The silhouettes a job renders: its weight in the build's progress."""
    if isinstance(job, MetricJob):
        return int(job.frames.size) * sum(r.n_views for r in job.rings) * 2
    return sum(stop - first for _, first, stop in job[1]) * job[2].n_views


def _merge(settings: BankSettings, folder: Path, manifest: dict[str, Any]) -> dict[str, Any]:
    """Every shard (checked again) copied into ``features.npy`` and ``root_motion.npy``,
    one shard at a time; returns the manifest's ``blocks`` (their hashes)."""
    views, size = settings.n_views, settings.features.size
    n = int(manifest["clip_start"][-1])
    shapes = {"features": (n, views, size), "root_motion": (n, views, 2)}
    blocks: dict[str, Any] = {"rows": BLOCK_ROWS}
    with (
        npy_file(folder / "features.npy", _MAPPED["features"], shapes["features"]) as feats,
        npy_file(
            folder / "root_motion.npy", _MAPPED["root_motion"], shapes["root_motion"]
        ) as moves,
    ):
        for s in manifest["shards"]:  # checked again: a shard may have been damaged since
            path = folder / str(s["file"])
            a, b = int(s["start"]), int(s["stop"])
            if not _shard_ok(path, b - a, views, size):
                raise BankFileError(path, "a shard damaged during the build: build again")
            part = _read_npz(path, ("features", "root_motion"))
            feats[a:b] = part["features"]
            moves[a:b] = part["root_motion"]
        blocks["features"] = block_hashes(feats, BLOCK_ROWS)
        blocks["root_motion"] = block_hashes(moves, BLOCK_ROWS)
    return blocks


def load_bank(
    folder: str | Path,
    clips: Sequence[Clip] | None = None,
    settings: BankSettings | None = None,
) -> Bank:
    """Read a complete bank; with ``clips`` / ``settings``, refuse a stale one.

    Raises ``StaleBankError`` for a bank of another library, settings or version, and
    ``BankFileError`` naming the file for one that is incomplete, unreadable, or damaged
    or edited since it was written (its checksum covers the manifest and the arrays).
    """
    folder = Path(folder)
    mpath = folder / "manifest.json"
    if not mpath.is_file():
        raise FileNotFoundError(f"no bank at {folder} (no manifest.json)")
    try:
        manifest = json.loads(mpath.read_bytes().decode("utf-8"))
    except (OSError, ValueError) as exc:
        raise BankFileError(mpath, f"unreadable manifest ({exc})") from exc
    if not isinstance(manifest, dict) or manifest.get("format") != "mimic-bank":
        raise BankFileError(mpath, "not a mimic bank manifest")
    if manifest.get("version") != BANK_VERSION:
        raise StaleBankError(
            mpath, f"bank version {manifest.get('version')}, this mimic writes {BANK_VERSION}"
        )
    if not manifest.get("complete"):
        raise BankFileError(
            mpath, "the bank is incomplete (an interrupted build): build it again to resume"
        )
    try:
        return _bank_of(folder, manifest, clips, settings)
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as exc:
        if isinstance(exc, BankFileError):
            raise
        raise BankFileError(mpath, f"an inconsistent manifest ({exc!r})") from None


def _bank_of(
    folder: Path,
    manifest: dict[str, Any],
    clips: Sequence[Clip] | None,
    settings: BankSettings | None,
) -> Bank:
    mpath, npz = folder / "manifest.json", folder / "bank.npz"
    if clips is not None and clips_digest(clips) != manifest["library_digest"]:
        raise StaleBankError(mpath, "built from another motion library")
    if settings is not None and settings.digest() != manifest["settings_digest"]:
        raise StaleBankError(mpath, "built with other render settings")
    settings_read = BankSettings.from_dict(manifest["settings"])
    keys = ["clip_start", "key"]
    if settings_read.metric_dims:
        keys += ["metric_mean", "metric"]
    d = _read_npz(npz, keys)
    # one checksum covers manifest.json (with the blocks' hashes) and bank.npz: a
    # mismatch names the bank's folder
    verify_checksum(manifest, d, folder, BankFileError)
    n = int(manifest["clip_start"][-1])
    views = int(manifest["views"])
    if str(d["key"]) != manifest["key"]:
        raise BankFileError(npz, "does not belong to this manifest")
    size = get_descriptor(str(manifest["settings"].get("descriptor", "hu"))).size
    shapes = {"features": (n, views, size), "root_motion": (n, views, 2)}
    blocks = manifest["blocks"]
    rows = blocks.get("rows") if isinstance(blocks, dict) else None
    if not isinstance(rows, int) or rows < 1:
        raise BankFileError(mpath, f"blocks of {rows!r} frames")
    for name, dtype in _MAPPED.items():
        path = folder / f"{name}.npy"
        d[name] = open_mapped(path, shapes[name], dtype, blocks[name], rows, BankFileError)
    metric = None
    if settings_read.metric_dims:
        s = settings_read.features.n_shape
        mean, proj = d["metric_mean"], d["metric"]
        if mean.shape != (s,) or proj.ndim != 2 or proj.shape[0] != s:
            raise BankFileError(npz, "a metric of the wrong shape")
        if not (np.isfinite(mean).all() and np.isfinite(proj).all()):
            raise BankFileError(npz, "a metric that is not finite")
        metric = (mean.astype(np.float64), proj.astype(np.float64))
    return Bank(
        features=d["features"],
        root_motion=d["root_motion"],
        clip_names=tuple(manifest["clip_names"]),
        clip_start=np.asarray(manifest["clip_start"], dtype=np.int64),
        settings=settings_read,
        library_digest=str(manifest["library_digest"]),
        path=str(folder),
        metric=metric,
        checksum=str(manifest["checksum"]),
    )
