"""BVH reader and writer.

BVH semantics: a joint's channels are listed outermost first, so ``CHANNELS 3 Zrotation
Xrotation Yrotation`` means ``R = Rz @ Rx @ Ry`` (scipy's intrinsic ``"ZXY"``). Offsets and
positions are in the file's length unit, which BVH does not record: the reader takes it as
an argument or infers it from the skeleton's rest height.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..artifacts import atomic_write
from ._errors import MotionFormatError
from ._fk import rest_positions
from ._quat import FloatArray, euler_to_q, q_to_euler
from ._text import decode, is_int, parse_floats, parse_floats_fast, read_bytes
from ._types import Motion, Skeleton

__all__ = ["UNITS", "read_bvh", "write_bvh"]

#: Metres per file unit for the names ``units=`` accepts.
UNITS = {"m": 1.0, "dm": 0.1, "cm": 0.01, "mm": 0.001, "in": 0.0254, "ft": 0.3048}
_TYPICAL_HEIGHT = 1.7  # metres, for ``units="auto"``
_CHANNELS = {
    f"{axis}{kind}".lower(): f"{axis}{kind}" for axis in "XYZ" for kind in ("position", "rotation")
}


def _unit_scale(units: str | float) -> float | None:
    if isinstance(units, str):
        if units == "auto":
            return None
        if units not in UNITS:
            raise ValueError(f"units must be 'auto', one of {sorted(UNITS)} or a number")
        return UNITS[units]
    if not (np.isfinite(units) and units > 0):
        raise ValueError("units must be a positive number of metres per file unit")
    return float(units)


def _auto_scale(skeleton: Skeleton) -> float:
    """The unit from ``UNITS`` that makes the rest pose closest to a person's height."""
    pos, ends = rest_positions(skeleton)
    pts = np.concatenate((pos, ends))
    height = float(np.ptp(pts[:, 1])) or float(np.max(np.ptp(pts, axis=0)))
    if height <= 0:
        return 1.0
    return min(UNITS.values(), key=lambda s: abs(np.log(height * s / _TYPICAL_HEIGHT)))


class _Tokens:
    """Whitespace tokens with their line numbers, for the hierarchy part."""

    def __init__(self, path: str | Path, lines: list[str]) -> None:
        self.path = path
        self.items: list[tuple[str, int]] = []
        self.end_line = 0
        for n, line in enumerate(lines, start=1):
            words = line.split()
            if words and words[0].upper() == "MOTION":
                self.end_line = n
                break
            self.items.extend((w, n) for w in words)
        self.k = 0

    def next(self, what: str) -> tuple[str, int]:
        if self.k >= len(self.items):
            last = self.items[-1][1] if self.items else 1
            raise MotionFormatError(self.path, f"file ends where {what} was expected", last)
        tok = self.items[self.k]
        self.k += 1
        return tok

    def expect(self, word: str) -> int:
        tok, n = self.next(repr(word))
        if tok.upper() != word.upper():
            raise MotionFormatError(self.path, f"expected {word!r}, got {tok!r}", n)
        return n

    def floats(self, count: int, what: str) -> list[float]:
        toks = [self.next(what) for _ in range(count)]
        return parse_floats(self.path, [t for t, _ in toks], toks[0][1], what)


def _read_channels(path: str | Path, tk: _Tokens, name: str, root: bool) -> tuple[str, ...]:
    """A joint's ``CHANNELS`` line: its count, then each channel's name (position channels
    on the root alone)."""
    tk.expect("CHANNELS")
    count_tok, cn = tk.next("channel count")
    if not is_int(count_tok) or not 0 <= int(count_tok) <= 6:
        raise MotionFormatError(path, f"bad channel count {count_tok!r}", cn)
    chans = []
    for _ in range(int(count_tok)):
        c, cl = tk.next("a channel name")
        if c.lower() not in _CHANNELS:
            raise MotionFormatError(path, f"unknown channel {c!r}", cl)
        chans.append(_CHANNELS[c.lower()])
    if len(set(chans)) != len(chans):
        raise MotionFormatError(path, f"joint {name!r} repeats a channel", cn)
    if not root and any(c.endswith("position") for c in chans):
        raise MotionFormatError(
            path, f"position channels on non-root joint {name!r} are not supported", cn
        )
    return tuple(chans)


def _parse_hierarchy(path: str | Path, tk: _Tokens) -> tuple[Skeleton, list[int]]:
    """Skeleton in file units, and per-joint the number of channels."""
    tk.expect("HIERARCHY")
    tok, n = tk.next("ROOT")
    if tok.upper() != "ROOT":
        raise MotionFormatError(path, f"expected ROOT, got {tok!r}", n)
    names: list[str] = []
    parents: list[int] = []
    offsets: list[list[float]] = []
    channels: list[tuple[str, ...]] = []
    end_parents: list[int] = []
    end_offsets: list[list[float]] = []
    # Iterative descent: the stack holds the joint index whose braces are open.
    name, n = tk.next("the root's name")
    pending: tuple[str, int, int] | None = (name, -1, n)
    stack: list[int] = []
    while True:
        if pending is not None:
            name, parent, n = pending
            pending = None
            if name in names:
                raise MotionFormatError(path, f"joint name {name!r} is used twice", n)
            tk.expect("{")
            tk.expect("OFFSET")
            offsets.append(tk.floats(3, f"OFFSET of {name!r}"))
            channels.append(_read_channels(path, tk, name, root=parent < 0))
            names.append(name)
            parents.append(parent)
            stack.append(len(names) - 1)
            continue
        tok, n = tk.next("JOINT, End Site or '}'")
        word = tok.upper()
        if word == "JOINT":
            child, cn = tk.next("a joint name")
            pending = (child, stack[-1], cn)
        elif word == "END":
            tk.expect("Site")
            tk.expect("{")
            tk.expect("OFFSET")
            end_offsets.append(tk.floats(3, "End Site OFFSET"))
            tk.expect("}")
            end_parents.append(stack[-1])
        elif word == "}":
            stack.pop()
            if not stack:
                break
        else:
            raise MotionFormatError(path, f"unexpected {tok!r} in the hierarchy", n)
    if tk.k != len(tk.items):
        raise MotionFormatError(
            path, f"unexpected {tk.items[tk.k][0]!r} after the root", tk.items[tk.k][1]
        )
    # The writer and readers guarantee DFS order, which is parents-first.
    skeleton = Skeleton(
        names=tuple(names),
        parents=np.array(parents, dtype=np.int64),
        offsets=np.array(offsets),
        channels=tuple(channels),
        end_parents=np.array(end_parents, dtype=np.int64),
        end_offsets=np.array(end_offsets).reshape(-1, 3),
    )
    return skeleton, [len(c) for c in channels]


def read_bvh(path: str | Path, units: str | float = "auto", name: str | None = None) -> Motion:
    """Read a BVH file (any channel order, end sites, any line endings).

    Parameters
    ----------
    path : the file.
    units : metres per file unit, a name from ``UNITS``, or ``"auto"``: the unit in
        ``UNITS`` that gives the rest skeleton a height nearest 1.7 m.
    name : the clip name; the file's stem by default.

    Raises
    ------
    MotionFormatError
        naming the file and line for anything malformed.
    """
    scale = _unit_scale(units)
    text = decode(path, read_bytes(path))
    lines = text.splitlines()
    tk = _Tokens(path, lines)
    skeleton, counts = _parse_hierarchy(path, tk)
    if tk.end_line == 0:
        raise MotionFormatError(path, "no MOTION section", len(lines))
    k = tk.end_line  # index of the line after MOTION
    n_frames, frame_time, k = _motion_header(path, lines, k)
    n_chan = sum(counts)
    data_lines = lines[k:]
    while data_lines and not data_lines[-1].strip():
        data_lines.pop()
    if len(data_lines) != n_frames:
        raise MotionFormatError(
            path, f"'Frames: {n_frames}' but {len(data_lines)} lines of frame data follow", k + 1
        )
    values = parse_floats_fast("\n".join(data_lines))
    # the total alone would let a frame of n-1 values and one of n+1 shift every channel
    # between them: every line must hold exactly n_chan values
    if values is not None and any(len(line.split()) != n_chan for line in data_lines):
        values = None
    if values is None or values.size != n_frames * n_chan:
        values = _frames_slow(path, data_lines, k + 1, n_chan)
    values = values.reshape(n_frames, n_chan)
    if n_frames == 0:
        raise MotionFormatError(path, "no frames", k)
    if scale is None:
        scale = _auto_scale(skeleton)
    return _to_motion(path, skeleton, values, frame_time, scale, name or Path(path).stem)


def _fps(frame_time: float) -> float:
    """Frames per second; snapped to a whole rate that the printed period rounds from
    (``Frame Time: 0.00833333`` is 120 frames/s)."""
    whole = round(1.0 / frame_time)
    if whole > 0 and abs(1.0 / whole - frame_time) <= 1e-5 * frame_time:
        return float(whole)
    return 1.0 / frame_time


def _motion_header(path: str | Path, lines: list[str], k: int) -> tuple[int, float, int]:
    def field(label: str) -> tuple[str, int]:
        nonlocal k
        while k < len(lines) and not lines[k].strip():
            k += 1
        if k >= len(lines):
            raise MotionFormatError(path, f"file ends before '{label}'", len(lines))
        line = lines[k]
        head, sep, rest = line.partition(":")
        if not sep or " ".join(head.split()).lower() != label.lower():
            raise MotionFormatError(
                path, f"expected '{label}: ...', got {line.strip()[:40]!r}", k + 1
            )
        k += 1
        return rest.strip(), k

    frames_txt, n1 = field("Frames")
    if not is_int(frames_txt) or int(frames_txt) < 0:
        raise MotionFormatError(path, f"frame count {frames_txt!r} is not a whole number", n1)
    time_txt, n2 = field("Frame Time")
    (frame_time,) = parse_floats(path, [time_txt] if time_txt else ["?"], n2, "Frame Time")
    if not 1e-5 <= frame_time <= 1e3:
        raise MotionFormatError(
            path, f"Frame Time {frame_time} is not a plausible frame period", n2
        )
    return int(frames_txt), frame_time, k


def _frames_slow(path: str | Path, lines: list[str], first_line: int, n_chan: int) -> FloatArray:
    out = np.empty((len(lines), n_chan))
    for i, line in enumerate(lines):
        toks = line.split()
        n = first_line + i
        if len(toks) != n_chan:
            raise MotionFormatError(path, f"frame {i} has {len(toks)} values, expected {n_chan}", n)
        out[i] = parse_floats(path, toks, n, f"frame {i}")
    return out


def _to_motion(
    path: str | Path, sk: Skeleton, values: FloatArray, frame_time: float, scale: float, name: str
) -> Motion:
    n_frames = values.shape[0]
    quats = np.zeros((n_frames, sk.n_joints, 4))
    root_pos = np.tile(sk.offsets[0], (n_frames, 1))
    col = 0
    for j, chans in enumerate(sk.channels):
        block = values[:, col : col + len(chans)]
        col += len(chans)
        rot = [k for k, c in enumerate(chans) if c.endswith("rotation")]
        for k, c in enumerate(chans):
            if c.endswith("position"):
                # A joint's transform is T(OFFSET) T(channels) R, so the root's position
                # channels add to its OFFSET (zero in almost every file).
                root_pos[:, "XYZ".index(c[0])] += block[:, k]
        if rot:
            seq = "".join(chans[k][0] for k in rot)  # intrinsic: outermost first
            quats[:, j] = euler_to_q(np.deg2rad(block[:, rot]), seq)
        else:
            quats[:, j, 0] = 1.0
    if not np.all(np.isfinite(root_pos * scale)):
        raise MotionFormatError(path, "root position overflows")
    skeleton = Skeleton(
        names=sk.names,
        parents=sk.parents,
        offsets=np.vstack((np.zeros((1, 3)), sk.offsets[1:])) * scale,
        channels=sk.channels,
        end_parents=sk.end_parents,
        end_offsets=sk.end_offsets * scale,
    )
    quats /= np.linalg.norm(quats, axis=-1, keepdims=True)
    return Motion(skeleton, root_pos * scale, quats, _fps(frame_time), name=name, source=str(path))


def _fmt(values: FloatArray) -> str:
    return " ".join(f"{v:.9g}" for v in values)


def write_bvh(
    motion: Motion,
    path: str | Path,
    units: str | float = "cm",
    order: str = "ZXY",
) -> None:
    """Write ``motion`` as BVH, atomically (a temporary file renamed into place).

    Parameters
    ----------
    units : file unit, a name from ``UNITS`` or metres per unit (default centimetres,
        which Blender's importer and most tools expect).
    order : rotation channel order for every joint, a permutation of ``"XYZ"``.

    Every joint gets 3 rotation channels, the root 3 position channels before them; a
    leaf joint without an end site gets a zero-length one, since BVH readers expect it.
    """
    scale = _unit_scale(units)
    if scale is None:
        raise ValueError("write_bvh needs explicit units")
    if sorted(order) != ["X", "Y", "Z"]:
        raise ValueError(f"order must be a permutation of XYZ, got {order!r}")
    sk = motion.skeleton
    for nm in sk.names:
        if not nm or any(ch.isspace() for ch in nm) or nm in "{}":
            raise ValueError(f"joint name {nm!r} cannot be written to BVH")
    rot_names = " ".join(f"{a}rotation" for a in order)
    out, written = _hierarchy(sk, scale, rot_names)
    out.append("MOTION")
    out.append(f"Frames: {motion.n_frames}")
    out.append(f"Frame Time: {1.0 / motion.fps:.9g}")
    eul = np.rad2deg(q_to_euler(motion.quats[:, written], order))
    table = np.concatenate((motion.root_pos / scale, eul.reshape(motion.n_frames, -1)), axis=1)
    with atomic_write(path) as fh:
        fh.write("\n".join(out) + "\n")
        for row in table:
            fh.write(_fmt(row) + "\n")


def _hierarchy(sk: Skeleton, scale: float, rot_names: str) -> tuple[list[str], list[int]]:
    """A BVH's ``HIERARCHY`` lines for ``sk`` (offsets divided by ``scale``, every joint
    with the rotation channels ``rot_names``), and the joints in the order written: the
    order of the channel data."""
    out: list[str] = ["HIERARCHY"]
    written: list[int] = []  # joints in file order; the channel data follows it
    ends: dict[int, list[int]] = {}
    for e, p in enumerate(sk.end_parents):
        ends.setdefault(int(p), []).append(e)

    # the hierarchy, depth first with an explicit stack (a chain of thousands of joints
    # would overflow Python's recursion)
    stack: list[tuple[bool, int, int]] = [(True, 0, 0)]
    while stack:
        enter, j, depth = stack.pop()
        pad = "  " * depth
        kids = sk.children(j)
        if enter:
            written.append(j)
            kind = "ROOT" if j == 0 else "JOINT"
            out.append(f"{pad}{kind} {sk.names[j]}")
            out.append(f"{pad}{{")
            off = np.zeros(3) if j == 0 else sk.offsets[j] / scale
            out.append(f"{pad}  OFFSET {_fmt(off)}")
            if j == 0:
                out.append(f"{pad}  CHANNELS 6 Xposition Yposition Zposition {rot_names}")
            else:
                out.append(f"{pad}  CHANNELS 3 {rot_names}")
            stack.append((False, j, depth))
            stack.extend((True, int(c), depth + 1) for c in reversed(list(kids)))
            continue
        end_list = ends.get(j, [])
        if not len(kids) and not end_list:
            out.append(f"{pad}  End Site\n{pad}  {{\n{pad}    OFFSET 0 0 0\n{pad}  }}")
        for e in end_list:
            out.append(f"{pad}  End Site\n{pad}  {{")
            out.append(f"{pad}    OFFSET {_fmt(sk.end_offsets[e] / scale)}")
            out.append(f"{pad}  }}")
        out.append(f"{pad}}}")
    return out, written
