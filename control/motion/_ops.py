"""Operations that make new clips from clips: resampling, mirroring, cutting."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from ._names import mirror_map
from ._quat import FloatArray, slerp
from ._types import Motion, Skeleton

__all__ = ["cut", "mirror", "mirrored_rotations", "resample", "resample_positions"]


def resample_positions(n_frames: int, fps: float, target_fps: float) -> FloatArray:
    """Fractional source frame of every output frame, ``(K,)``.

    Output frame ``k`` is at time ``k / target_fps``; the last one is the latest that does
    not run past the source's last frame. Positions within 1e-9 of a whole frame are
    snapped to it, so 120 -> 15 frames/s picks every 8th source frame exactly.
    """
    if n_frames < 1:
        raise ValueError("cannot resample an empty clip")
    if not (np.isfinite(target_fps) and target_fps > 0):
        raise ValueError(f"target fps must be positive, got {target_fps}")
    last = n_frames - 1
    count = int(np.floor(last * target_fps / fps + 1e-9)) + 1
    pos = np.arange(count) * (fps / target_fps)
    snapped = np.round(pos)
    pos = np.where(np.abs(pos - snapped) < 1e-9, snapped, pos)
    return np.minimum(pos, last)


def resample(motion: Motion, fps: float = 15.0) -> Motion:
    """The clip at ``fps`` frames/s: root positions interpolated linearly, joint rotations
    with slerp. Default 15 frames/s, the rate of Lee et al."""
    if fps == motion.fps:
        return motion
    pos = resample_positions(motion.n_frames, motion.fps, fps)
    i0 = np.floor(pos).astype(np.int64)
    i1 = np.minimum(i0 + 1, motion.n_frames - 1)
    w = pos - i0
    root = motion.root_pos[i0] * (1 - w)[:, None] + motion.root_pos[i1] * w[:, None]
    quats = slerp(
        motion.quats[i0],
        motion.quats[i1],
        np.broadcast_to(w[:, None], (*i0.shape, motion.skeleton.n_joints)),
    )
    return replace(motion, root_pos=root, quats=quats, fps=float(fps))


def _reflect_q(q: FloatArray, axis: int) -> FloatArray:
    """Quaternion of ``S R S`` for the reflection ``S`` that negates world axis ``axis``."""
    out = np.array(q, copy=True)
    for a in range(3):
        if a != axis:
            out[..., 1 + a] *= -1.0
    return out


def mirrored_rotations(
    motion: Motion, joints: NDArray[np.int64] | None = None, axis: int = 0
) -> FloatArray:
    """The rotations ``(F, len(joints), 4)`` of ``mirror(motion, axis)``'s ``joints``
    (default all), without making the mirrored skeleton or copying the other joints."""
    if axis not in (0, 1, 2):
        raise ValueError("axis must be 0, 1 or 2")
    partner = mirror_map(motion.skeleton)
    return _reflect_q(motion.quats[:, partner if joints is None else partner[joints]], axis)


def mirror(motion: Motion, axis: int = 0) -> Motion:
    """The clip reflected in the plane ``x[axis] = 0`` with left and right swapped.

    Every joint takes its partner's rotation (reflected) and its partner's offset
    (reflected), so the result's joint positions are exactly the reflected positions of
    the partners: mirroring twice gives back the original. Left/right partners are found
    by name (``mirror_map``); joints on the midline are their own partners.
    """
    if axis not in (0, 1, 2):
        raise ValueError("axis must be 0, 1 or 2")
    sk = motion.skeleton
    partner = mirror_map(sk)
    flip = np.ones(3)
    flip[axis] = -1.0
    end_offsets = np.empty_like(sk.end_offsets)
    for e, p in enumerate(sk.end_parents):
        mine = np.flatnonzero(sk.end_parents == p)
        theirs = np.flatnonzero(sk.end_parents == partner[p])
        if mine.size != theirs.size:
            raise ValueError(
                f"joints {sk.names[p]!r} and {sk.names[partner[p]]!r} have different end sites"
            )
        end_offsets[e] = sk.end_offsets[theirs[np.searchsorted(mine, e)]] * flip
    skeleton = Skeleton(
        names=sk.names,
        parents=sk.parents,
        offsets=sk.offsets[partner] * flip,
        channels=sk.channels,
        end_parents=sk.end_parents,
        end_offsets=end_offsets,
    )
    return Motion(
        skeleton,
        motion.root_pos * flip,
        mirrored_rotations(motion, axis=axis),
        motion.fps,
        name=f"{motion.name}_mirror" if not motion.name.endswith("_mirror") else motion.name[:-7],
        source=motion.source,
    )


def cut(motion: Motion, start: int, stop: int | None = None) -> Motion:
    """Frames ``start`` (inclusive) to ``stop`` (exclusive; the end by default)."""
    n = motion.n_frames
    stop = n if stop is None else stop
    if not (0 <= start < stop <= n):
        raise ValueError(f"frame range [{start}, {stop}) is not inside the clip's 0..{n}")
    return replace(motion, root_pos=motion.root_pos[start:stop], quats=motion.quats[start:stop])
