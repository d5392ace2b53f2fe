"""Acclaim AMC motion reader, for a skeleton read by ``_asf.read_asf``.

A one-pass numba scan (``_amc_scan``) reads strictly regular files, the vectorised parse
here regular ones (every frame lists the same bones in the same order, one value per
dof); anything irregular is read line by line from the first frame the scan could not
read, which either accepts it or says exactly where it is wrong.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ._amc_scan import dof_columns, scan_amc_prefix
from ._asf import ROT_DOFS, TRANS_DOFS, AsfSkeleton
from ._errors import MotionFormatError
from ._quat import FloatArray, euler_to_q, qconj, qmul
from ._text import decode, is_int, parse_floats, parse_floats_fast, read_bytes
from ._types import Motion

__all__ = ["read_amc"]

_NAME_RE = re.compile(r"(?m)^[ \t]*([A-Za-z_][^ \t\r\n]*)")


#: the farthest a root may be from the origin, metres (after the units are applied)
MAX_ROOT_M = 10_000.0


def read_amc(
    path: str | Path, asf: AsfSkeleton, fps: float = 120.0, name: str | None = None
) -> Motion:
    """Read an AMC motion for the skeleton ``asf``.

    Parameters
    ----------
    path : the ``.amc`` file (any line endings).
    asf : its skeleton.
    fps : frame rate; AMC files do not store one (CMU captures are 120 frames/s).
    name : the clip name; the file's stem by default.

    Frames must be numbered consecutively and give every bone that has dofs, with one
    value per dof.

    Raises
    ------
    MotionFormatError
        naming the file and line for anything malformed or not matching ``asf``.
    """
    text = decode(path, read_bytes(path))
    header_lines, body_start = _amc_header(text)
    body = text[body_start:]
    moving = [j for j, d in enumerate(asf.dofs) if d]
    done, rest = scan_amc_prefix(body, asf, moving)
    values = done if rest == len(body) and done.shape[0] else _amc_fast(body, asf, moving)
    if values is None:
        values = _amc_slow(path, body, header_lines, asf, moving, done, rest)
    if values.shape[0] == 0:
        raise MotionFormatError(path, "no frames")
    return _to_motion(path, values, asf, moving, fps, name or Path(path).stem)


def _amc_header(text: str) -> tuple[int, int]:
    """Number of header lines (comments, ``:FULLY-SPECIFIED``...) and where the body starts."""
    pos = 0
    n = 0
    while pos < len(text):
        end = text.find("\n", pos)
        end = len(text) if end < 0 else end + 1
        s = text[pos:end].strip()
        if s and not s.startswith(("#", ":")):
            break
        pos = end
        n += 1
    return n, pos


def _amc_fast(body: str, asf: AsfSkeleton, moving: list[int]) -> FloatArray | None:
    """Vectorised parse of a regular AMC body, or ``None`` if it is not regular."""
    parts = _NAME_RE.split(body)
    names = parts[1::2]
    if not names or len(parts[0].split()) != 1:
        return None
    # The first frame's bone order; every frame must repeat it exactly.
    try:
        k = names.index(names[0], 1)
    except ValueError:
        k = len(names)
    per_frame = names[:k]
    n_frames, rem = divmod(len(names), k)
    if rem or names != per_frame * n_frames:
        return None
    if sorted(per_frame) != sorted(asf.skeleton.names[j] for j in moving):
        return None
    widths = [len(asf.dofs[asf.skeleton.index(nm)]) for nm in per_frame]
    # Each bone's line holds exactly its dofs (the frame's last line also precedes the
    # next frame number).
    counts = np.fromiter(map(len, map(str.split, parts[2::2])), np.int64, len(names))
    want = np.tile(widths, n_frames)
    want[k - 1 :: k][:-1] += 1
    if not np.array_equal(counts, want):
        return None
    flat = parse_floats_fast("".join(parts[0::2]))
    width = 1 + sum(widths)
    if flat is None or flat.size != n_frames * width:
        return None
    table = flat.reshape(n_frames, width)
    numbers = table[:, 0]
    if not np.array_equal(numbers, numbers[0] + np.arange(n_frames)):
        return None
    # Reorder the columns to the skeleton's joint order.
    starts = dict(zip(per_frame, np.cumsum([1, *widths[:-1]]).tolist(), strict=True))
    cols: list[int] = []
    for j in moving:
        a = starts[asf.skeleton.names[j]]
        cols.extend(range(a, a + len(asf.dofs[j])))
    return np.ascontiguousarray(table[:, cols])


def _amc_slow(
    path: str | Path,
    body: str,
    header_lines: int,
    asf: AsfSkeleton,
    moving: list[int],
    done: FloatArray | None = None,
    rest: int = 0,
) -> FloatArray:
    """The body read line by line, from ``rest`` (a line's start) when the frames before
    it are read already (``done``, by ``scan_amc_prefix``); an error names its line."""
    names = asf.skeleton.names
    expected = {names[j]: len(asf.dofs[j]) for j in moving}
    col_start, width = dof_columns(asf, moving)
    frames: list[list[float]] = []
    seen: set[str] = set()
    frame_no: int | None = None
    frame_line = 0
    if done is not None and done.shape[0] and rest > 0:
        frame_no = int(body.split(maxsplit=1)[0]) + done.shape[0] - 1
        seen = set(expected)  # the last frame read is whole
        header_lines += len(body[:rest].splitlines())
        body = body[rest:]
    else:
        done = np.empty((0, width))

    def close_frame(at_line: int) -> None:
        _check_frame(path, expected, seen, frame_no, frame_line, at_line)

    lines = body.splitlines()
    for n, raw in enumerate(lines, start=header_lines + 1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        tokens = line.split()
        if len(tokens) == 1 and is_int(tokens[0]):
            number = int(tokens[0])
            if frame_no is not None:
                close_frame(n)
                if number != frame_no + 1:
                    raise MotionFormatError(
                        path, f"frame number {number} does not follow frame {frame_no}", n
                    )
            frame_no = number
            frame_line = n
            frames.append([0.0] * width)
            seen = set()
            continue
        if frame_no is None:
            raise MotionFormatError(path, f"expected a frame number, got {line[:40]!r}", n)
        bone = tokens[0]
        if bone in seen:
            raise MotionFormatError(path, f"bone {bone!r} appears twice in frame {frame_no}", n)
        vals = _bone_values(path, tokens, n, asf, expected)
        if vals is not None:
            s = col_start[bone]
            frames[-1][s : s + len(vals)] = vals
            seen.add(bone)
    if frame_no is not None:
        close_frame(header_lines + len(lines))
    return np.concatenate([done, np.array(frames, dtype=np.float64).reshape(-1, width)])


def _check_frame(
    path: str | Path,
    expected: dict[str, int],
    seen: set[str],
    frame_no: int | None,
    frame_line: int,
    at_line: int,
) -> None:
    """Frame ``frame_no`` (from line ``frame_line``), ended at ``at_line``, gave every
    moving bone (``expected``) its values (``seen``)."""
    missing = ", ".join(b for b in expected if b not in seen)
    if missing:
        raise MotionFormatError(
            path, f"frame {frame_no} (line {frame_line}) lacks bone(s) {missing}", at_line
        )


def _bone_values(
    path: str | Path, tokens: list[str], n: int, asf: AsfSkeleton, expected: dict[str, int]
) -> list[float] | None:
    """The values of a bone's line ``tokens`` (line ``n``), checked against the skeleton
    (``expected``: each moving bone's count of values); ``None`` for a bone without
    dofs, whose line holds its name alone."""
    bone = tokens[0]
    if bone not in asf.skeleton.names:
        raise MotionFormatError(path, f"bone {bone!r} is not in the skeleton {asf.path}", n)
    if bone not in expected:
        if len(tokens) > 1:
            raise MotionFormatError(path, f"bone {bone!r} has no dofs in {asf.path}", n)
        return None
    want = expected[bone]
    if len(tokens) - 1 != want:
        dofs = " ".join(asf.dofs[asf.skeleton.index(bone)])
        raise MotionFormatError(
            path, f"bone {bone!r} expects {want} values ({dofs}), got {len(tokens) - 1}", n
        )
    return parse_floats(path, tokens[1:], n, f"bone {bone!r}")


def _to_motion(
    path: str | Path, values: FloatArray, asf: AsfSkeleton, moving: list[int], fps: float, name: str
) -> Motion:
    sk = asf.skeleton
    n_frames = values.shape[0]
    quats = np.zeros((n_frames, sk.n_joints, 4))
    quats[..., 0] = 1.0
    root_pos = np.zeros((n_frames, 3))
    col = 0
    for j in moving:
        dofs = asf.dofs[j]
        block = values[:, col : col + len(dofs)]
        col += len(dofs)
        rot_idx = [k for k, d in enumerate(dofs) if d in ROT_DOFS]
        for k, d in enumerate(dofs):
            if d in TRANS_DOFS:
                root_pos[:, TRANS_DOFS.index(d)] = block[:, k] * asf.metres_per_unit
        if not rot_idx:
            continue
        angles = block[:, rot_idx]
        if asf.degrees:
            angles = np.deg2rad(angles)
        seq = "".join(dofs[k][1] for k in rot_idx)  # extrinsic, applied in dof order
        m = euler_to_q(angles, seq)
        c = asf.axis_q[j]
        quats[:, j] = qmul(qmul(c, m), qconj(c))
    if not np.all(np.isfinite(root_pos)):
        raise MotionFormatError(path, "root translation overflows")
    far = np.abs(root_pos).max(axis=1) > MAX_ROOT_M
    if far.any():  # checked after the units: a capture volume, not 3e7 m
        f = int(np.argmax(far))
        raise MotionFormatError(
            path,
            f"frame {f + 1}: the root is {np.abs(root_pos[f]).max():.3g} m from the origin "
            f"after the units (over {MAX_ROOT_M:g} m): wrong units or a broken file",
        )
    norms = np.linalg.norm(quats, axis=-1, keepdims=True)
    return Motion(sk, root_pos, quats / norms, fps, name=name, source=str(path))
