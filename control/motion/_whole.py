"""The whole library's clips as one cache entry (``library-<key>.npz``), beside the parsed
files' entries: every clip as made (resampled to the library's rate, mirrored, its foot
contacts), so that a warm load reads one file instead of every clip's entry, and neither
resamples nor detects contacts again (at 200,000 frames in 494 files, the per-clip work
was most of a warm load).

The key is hashed from this format's version, the readers' version, the options that
make the clips (rate, mirror, BVH units, the contact detector's options) and every
source's name, path and content key (``cache_key``: its bytes, and its ASF's). Labels and
descriptions are not stored: they are read from their small files on every load. The
entry carries a checksum; a damaged or stale one is said and the clips are made again.
"""

from __future__ import annotations

import hashlib
import json
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..artifacts import atomic_write, checksum
from ._contacts import Contacts
from ._errors import MotionFormatError
from ._parsed import READER_VERSION, Source, load_entry
from ._quat import FloatArray
from ._types import Motion, Skeleton

__all__ = ["MadeClip", "load_whole", "save_whole", "whole_key"]

log = logging.getLogger(__name__)

#: Bump when the way clips are made (resampling, mirroring, contacts) changes.
WHOLE_VERSION = "1"

_ARRAYS = (
    "parents",
    "offsets",
    "end_parents",
    "end_offsets",
    "root_pos",
    "quats",
    "states",
    "source_frames",
)


@dataclass(frozen=True, eq=False)
class MadeClip:
    """A clip's costly part: its motion at the library's rate, its contacts, the source
    frame each frame comes from and the source's length in frames; and whether it is a
    mirrored copy."""

    motion: Motion
    contacts: Contacts
    source_frames: FloatArray
    source_length: int
    mirrored: bool


def whole_key(sources: list[Source], keys: list[str], options: dict[str, Any]) -> str:
    """The entry's key: the version, ``options`` (JSON) and each source's name, path and
    content key."""
    h = hashlib.sha256(f"mimic-library/{WHOLE_VERSION}/{READER_VERSION}\0".encode())
    h.update(json.dumps(options, sort_keys=True, default=str).encode())
    for src, key in zip(sources, keys, strict=True):
        h.update(f"\0{src.name}\0{src.path}\0{key}".encode())
    return h.hexdigest()[:32]


def save_whole(path: Path, made: list[MadeClip]) -> None:
    """Write ``made`` to ``path`` atomically (a stop leaves the old file or none)."""
    clips: list[dict[str, Any]] = []
    parts: dict[str, list[np.ndarray]] = {k: [] for k in _ARRAYS}
    for c in made:
        m, sk = c.motion, c.motion.skeleton
        clips.append(
            {
                "name": m.name,
                "source": m.source,
                "fps": m.fps,
                "names": list(sk.names),
                "channels": [list(ch) for ch in sk.channels],
                "frames": m.n_frames,
                "source_length": c.source_length,
                "ends": int(sk.end_parents.size),
                "ankle_rest": c.contacts.ankle_rest,
                "toe_rest": c.contacts.toe_rest,
                "mirrored": c.mirrored,
            }
        )
        rows: list[np.ndarray] = [sk.parents, sk.offsets, sk.end_parents, sk.end_offsets]
        rows += [m.root_pos, m.quats.reshape(-1, 4), c.contacts.states, c.source_frames]
        for name, a in zip(_ARRAYS, rows, strict=True):
            parts[name].append(np.asarray(a))
    arrays = {k: np.concatenate(v) for k, v in parts.items()}  # (a library has a clip)
    meta: dict[str, Any] = {"version": WHOLE_VERSION, "clips": clips}
    meta["checksum"] = checksum(meta, arrays)
    with atomic_write(path, "wb") as fh:
        np.savez(fh, meta=np.array(json.dumps(meta)), **arrays)  # type: ignore[arg-type]


def load_whole(path: Path) -> list[MadeClip] | None:
    """The clips of the entry at ``path``, or ``None`` (with a warning naming the file)
    when it is unreadable, inconsistent or fails its checksum: they are made again."""

    def make(meta: dict[str, Any], z: dict[str, np.ndarray]) -> list[MadeClip]:
        if meta.get("version") != WHOLE_VERSION:
            raise MotionFormatError(path, "not a library entry of this version")
        return _clips_of(meta["clips"], z)

    return load_entry(
        path, ("meta", *_ARRAYS), "library cache entry", make, "making the clips again"
    )


def _clips_of(clips: list[dict[str, Any]], z: dict[str, NDArray[Any]]) -> list[MadeClip]:
    joint = end = frame = row = 0  # where the next clip's rows begin in each array
    made = []
    for c in clips:
        j, e, f = len(c["names"]), int(c["ends"]), int(c["frames"])
        sk = Skeleton(
            tuple(c["names"]),
            z["parents"][joint : joint + j],
            z["offsets"][joint : joint + j],
            tuple(tuple(ch) for ch in c["channels"]),
            z["end_parents"][end : end + e],
            z["end_offsets"][end : end + e],
        )
        quats = z["quats"][row : row + f * j].reshape(f, j, 4)
        motion = Motion(
            sk, z["root_pos"][frame : frame + f], quats, c["fps"], c["name"], c["source"]
        )
        states = z["states"][frame : frame + f]
        contacts = Contacts(states, float(c["ankle_rest"]), float(c["toe_rest"]))
        frames = z["source_frames"][frame : frame + f]
        made.append(
            MadeClip(motion, contacts, frames, int(c["source_length"]), bool(c["mirrored"]))
        )
        joint, end, frame, row = joint + j, end + e, frame + f, row + f * j
    sizes = {"parents": joint, "end_parents": end, "root_pos": frame, "quats": row}
    sizes |= {"states": frame, "source_frames": frame}
    if any(z[k].shape[0] != n for k, n in sizes.items()):
        raise ValueError("the entry's arrays do not hold the rows its clips name")
    return made
