"""Motion arrays: one clip as a compact ``<name>.motion.npz`` (no pickle).

The format of the embedded default library (``control/motion/default_library``): the
skeleton's arrays, the root trajectory and the local rotations in float32 (0.1 mm and
about 1e-5 rad, well below what capture resolves), and a JSON ``meta`` entry with the
joint names, channels, rate, name, source and the format version. Quaternions are
renormalised on reading.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from ..artifacts import atomic_write, checksum, read_npz, verify_checksum
from ._errors import MotionFormatError
from ._quat import qnormalize
from ._types import Motion, Skeleton

__all__ = ["ARRAYS_SUFFIX", "read_motion_arrays", "write_motion_arrays"]

ARRAYS_SUFFIX = ".motion.npz"
FORMAT = "mimic-motion-arrays/2"  # 2: the checksum
_KEYS = ("meta", "parents", "offsets", "end_parents", "end_offsets", "root_pos", "quats")


def write_motion_arrays(path: str | Path, motion: Motion) -> None:
    """Write ``motion`` to ``path`` (atomically: a stop leaves the old file or none)."""
    sk = motion.skeleton
    arrays: dict[str, np.ndarray] = {
        "parents": np.asarray(sk.parents, dtype=np.int16),
        "offsets": np.asarray(sk.offsets, dtype=np.float32),
        "end_parents": np.asarray(sk.end_parents, dtype=np.int16),
        "end_offsets": np.asarray(sk.end_offsets, dtype=np.float32),
        "root_pos": np.asarray(motion.root_pos, dtype=np.float32),
        "quats": np.asarray(motion.quats, dtype=np.float32),
    }
    meta: dict[str, Any] = {
        "format": FORMAT,
        "names": list(sk.names),
        "channels": [list(c) for c in sk.channels],
        "fps": motion.fps,
        "name": motion.name,
        "source": motion.source,
    }
    meta["checksum"] = checksum(meta, arrays)
    with atomic_write(path, "wb") as fh:
        np.savez_compressed(fh, meta=np.array(json.dumps(meta)), **arrays)  # type: ignore[arg-type]


def read_motion_arrays(path: str | Path, name: str | None = None) -> Motion:
    """The clip in a ``.motion.npz`` file.

    Raises
    ------
    MotionFormatError
        naming the file, when it is unreadable, of another format, or inconsistent.
    """
    path = Path(path)
    z = read_npz(path, _KEYS, MotionFormatError, "motion arrays file")
    try:
        meta = json.loads(str(z["meta"]))
    except ValueError as exc:
        raise MotionFormatError(path, f"meta is not JSON ({exc})") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        got = meta.get("format") if isinstance(meta, dict) else type(meta).__name__
        raise MotionFormatError(path, f"format {got!r}, expected {FORMAT!r}")
    verify_checksum(meta, {k: v for k, v in z.items() if k != "meta"}, path, MotionFormatError)
    try:
        sk = Skeleton(
            tuple(str(n) for n in meta["names"]),
            z["parents"].astype(np.int64),
            z["offsets"].astype(np.float64),
            tuple(tuple(str(x) for x in c) for c in meta["channels"]),
            z["end_parents"].astype(np.int64),
            z["end_offsets"].astype(np.float64),
        )
        quats = z["quats"].astype(np.float64)
        if not np.all(np.isfinite(quats)):
            raise ValueError("rotations are not finite")
        norms = np.linalg.norm(quats, axis=-1)
        if quats.size and (norms.min() < 0.99 or norms.max() > 1.01):
            raise ValueError(
                f"rotations are not unit quaternions (norms {norms.min():.3g}..{norms.max():.3g})"
            )
        return Motion(
            sk,
            z["root_pos"].astype(np.float64),
            qnormalize(quats),
            float(meta["fps"]),
            name or str(meta["name"]),
            str(meta.get("source", "")),
        )
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        raise MotionFormatError(path, f"inconsistent motion arrays: {exc}") from None
