"""Acclaim ASF (skeleton) and AMC (motion) readers.

The Acclaim conventions, as used by the CMU database:

- Lengths are in ``1 / :units length`` inches (CMU: ``length 0.45``, so metres =
  value / 0.45 * 0.0254). Angles are degrees unless ``:units angle rad``.
- A bone's ``axis ax ay az XYZ`` gives its local frame ``C``; the letters say the order in
  which the rotations are applied (``XYZ``: first about X, so ``C = Rz Ry Rx``).
- An AMC line gives a bone's dof values in its ``dof`` order; the bone's motion matrix
  ``M`` applies them in that order too, and the bone's rotation relative to its parent is
  ``L = C M C^-1``. Bone directions are world directions at rest, where every ``L`` is I.

We turn bones into joints the way ASF-to-BVH converters do: each bone becomes a joint at
the bone's start (its parent's end) with the bone's rotation; a leaf bone's end is an end
site. The root joint carries the root's translation and rotation.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ._errors import MotionFormatError
from ._quat import FloatArray, euler_to_q, qconj, qmul
from ._text import decode, is_int, parse_floats, parse_floats_fast, read_bytes
from ._types import Motion, Skeleton

__all__ = ["AsfSkeleton", "read_amc", "read_asf"]

INCH = 0.0254
_ROT_DOFS = ("rx", "ry", "rz")
_TRANS_DOFS = ("tx", "ty", "tz")
_BVH_NAME = {
    "rx": "Xrotation",
    "ry": "Yrotation",
    "rz": "Zrotation",
    "tx": "Xposition",
    "ty": "Yposition",
    "tz": "Zposition",
}


@dataclass(frozen=True, eq=False)
class AsfSkeleton:
    """What an AMC file needs from its ASF: the skeleton plus the Acclaim specifics.

    Attributes
    ----------
    skeleton : joints in metres, joint ``j`` is the bone ``skeleton.names[j]``.
    dofs : per joint, the AMC dof names in file order (``("rx", "rz")``); the root's
        come from ``:root order``.
    axis_q : (J, 4) the ``C`` rotation of every joint.
    degrees : True when AMC angles are in degrees.
    metres_per_unit : length scale of ASF lengths and AMC root translations.
    path : the ASF file.
    """

    skeleton: Skeleton
    dofs: tuple[tuple[str, ...], ...]
    axis_q: FloatArray
    degrees: bool
    metres_per_unit: float
    path: str


@dataclass
class _Bone:
    name: str
    line: int
    direction: FloatArray | None = None
    length: float | None = None
    axis: tuple[FloatArray, str] | None = None
    dofs: tuple[str, ...] = ()


def _axis_q(
    path: str | Path, angles: FloatArray, order: str, degrees: bool, line: int
) -> FloatArray:
    if sorted(order.upper()) != ["X", "Y", "Z"]:
        raise MotionFormatError(path, f"axis order {order!r} is not a permutation of XYZ", line)
    rad = np.deg2rad(angles) if degrees else angles
    # Extrinsic sequence in the listed order: the first letter is applied first.
    seq = order.lower()
    idx = ["xyz".index(c) for c in seq]
    return euler_to_q(rad[idx], seq)


def read_asf(path: str | Path, metres_per_unit: float | None = None) -> AsfSkeleton:
    """Read an Acclaim ASF skeleton.

    Parameters
    ----------
    path : the ``.asf`` file (any line endings).
    metres_per_unit : override the length scale; by default ``0.0254 / :units length``.

    Raises
    ------
    MotionFormatError
        naming the file and line for anything malformed or inconsistent.
    """
    text = decode(path, read_bytes(path))
    lines = text.splitlines()
    section = ""
    length_unit = 1.0
    degrees = True
    root_order: tuple[str, ...] = ("tx", "ty", "tz", "rx", "ry", "rz")
    root_axis = "XYZ"
    bones: dict[str, _Bone] = {}
    current: _Bone | None = None
    hierarchy: list[tuple[int, list[str]]] = []
    in_hierarchy_block = False
    seen_sections: set[str] = set()

    for n, raw in enumerate(lines, start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        tokens = line.split()
        key = tokens[0].lower()
        if key.startswith(":"):
            section = key
            seen_sections.add(section)
            if section == ":version" or section == ":name":
                continue
            if len(tokens) > 1 and section not in (":documentation",):
                raise MotionFormatError(path, f"unexpected text after {tokens[0]}", n)
            continue
        if section == ":units":
            if len(tokens) != 2:
                raise MotionFormatError(path, f"units line needs a name and a value: {line!r}", n)
            if key == "length":
                (length_unit,) = parse_floats(path, tokens[1:], n, "units length")
                if length_unit <= 0:
                    raise MotionFormatError(path, "units length must be positive", n)
            elif key == "angle":
                if tokens[1].lower() not in ("deg", "rad"):
                    raise MotionFormatError(path, f"angle unit {tokens[1]!r} is not deg or rad", n)
                degrees = tokens[1].lower() == "deg"
        elif section == ":root":
            if key == "order":
                order = tuple(t.lower() for t in tokens[1:])
                bad = [t for t in order if t not in _ROT_DOFS + _TRANS_DOFS]
                if bad or len(set(order)) != len(order):
                    raise MotionFormatError(path, f"bad root order {' '.join(tokens[1:])!r}", n)
                root_order = order
            elif key == "axis":
                if len(tokens) != 2:
                    raise MotionFormatError(path, "root axis needs one order like XYZ", n)
                root_axis = tokens[1]
                _axis_q(path, np.zeros(3), root_axis, degrees, n)
            elif key in ("position", "orientation"):
                parse_floats(path, tokens[1:], n, f"root {key}")
            else:
                raise MotionFormatError(path, f"unknown root field {tokens[0]!r}", n)
        elif section == ":bonedata":
            if key == "begin":
                if current is not None:
                    raise MotionFormatError(path, "'begin' inside a bone that has no 'end'", n)
                current = _Bone(name="", line=n)
            elif key == "end":
                if current is None:
                    raise MotionFormatError(path, "'end' without 'begin'", n)
                _finish_bone(path, current, bones)
                current = None
            elif current is None:
                raise MotionFormatError(path, f"{tokens[0]!r} outside a bone's begin/end", n)
            else:
                _bone_field(path, current, tokens, n, degrees)
        elif section == ":hierarchy":
            if key == "begin":
                in_hierarchy_block = True
            elif key == "end":
                in_hierarchy_block = False
            elif not in_hierarchy_block:
                raise MotionFormatError(path, "hierarchy line outside begin/end", n)
            else:
                hierarchy.append((n, tokens))
        elif section in (":documentation", ":version", ":name"):
            continue
        elif section == "":
            raise MotionFormatError(path, f"text before the first section: {line!r}", n)
        # Unknown sections (vendor extensions) are skipped.

    if current is not None:
        raise MotionFormatError(path, f"bone begun on line {current.line} has no 'end'", len(lines))
    for required in (":bonedata", ":hierarchy"):
        if required not in seen_sections:
            raise MotionFormatError(path, f"no {required} section")
    if not hierarchy:
        raise MotionFormatError(path, "the hierarchy is empty")
    metres = INCH / length_unit if metres_per_unit is None else float(metres_per_unit)
    return _assemble(path, bones, hierarchy, root_order, root_axis, degrees, metres)


def _bone_field(path: str | Path, bone: _Bone, tokens: list[str], n: int, degrees: bool) -> None:
    key = tokens[0].lower()
    if key == "id" or key in ("bodymass", "cofmass"):
        return
    if key == "name":
        if len(tokens) != 2:
            raise MotionFormatError(path, "bone name must be one word", n)
        bone.name = tokens[1]
    elif key == "direction":
        if len(tokens) != 4:
            raise MotionFormatError(path, "direction needs 3 numbers", n)
        bone.direction = np.array(parse_floats(path, tokens[1:], n, "direction"))
    elif key == "length":
        if len(tokens) != 2:
            raise MotionFormatError(path, "length needs 1 number", n)
        (length,) = parse_floats(path, tokens[1:], n, "length")
        if length < 0:
            raise MotionFormatError(path, "length must not be negative", n)
        bone.length = length
    elif key == "axis":
        if len(tokens) != 5:
            raise MotionFormatError(path, "axis needs 3 angles and an order like XYZ", n)
        angles = np.array(parse_floats(path, tokens[1:4], n, "axis"))
        bone.axis = (_axis_q(path, angles, tokens[4], degrees, n), tokens[4])
    elif key == "dof":
        dofs = tuple(t.lower() for t in tokens[1:])
        for d in dofs:
            if d == "l":
                raise MotionFormatError(path, "the bone-length dof 'l' is not supported", n)
            if d not in _ROT_DOFS:
                raise MotionFormatError(path, f"bone dof {d!r} is not rx, ry or rz", n)
        if len(set(dofs)) != len(dofs) or not dofs:
            raise MotionFormatError(path, f"bad dof list {' '.join(tokens[1:])!r}", n)
        bone.dofs = dofs
    elif key == "limits" or key.startswith("("):
        return
    else:
        raise MotionFormatError(path, f"unknown bone field {tokens[0]!r}", n)


def _finish_bone(path: str | Path, bone: _Bone, bones: dict[str, _Bone]) -> None:
    where = f"bone begun on line {bone.line}"
    if not bone.name:
        raise MotionFormatError(path, f"{where} has no name", bone.line)
    if bone.name in bones or bone.name.lower() == "root":
        raise MotionFormatError(path, f"bone {bone.name!r} is defined twice", bone.line)
    if bone.direction is None or bone.length is None or bone.axis is None:
        missing = [k for k in ("direction", "length", "axis") if getattr(bone, k) is None]
        raise MotionFormatError(path, f"bone {bone.name!r} lacks {', '.join(missing)}", bone.line)
    norm = float(np.linalg.norm(bone.direction))
    if bone.length > 0 and norm < 1e-9:
        raise MotionFormatError(path, f"bone {bone.name!r} has a zero direction", bone.line)
    if norm > 0:
        bone.direction = bone.direction / norm
    bones[bone.name] = bone


def _assemble(
    path: str | Path,
    bones: dict[str, _Bone],
    hierarchy: list[tuple[int, list[str]]],
    root_order: tuple[str, ...],
    root_axis: str,
    degrees: bool,
    metres: float,
) -> AsfSkeleton:
    children: dict[str, list[str]] = {}
    parent_of: dict[str, str] = {}
    for n, tokens in hierarchy:
        parent = tokens[0]
        if parent != "root" and parent not in bones:
            raise MotionFormatError(path, f"hierarchy names unknown bone {parent!r}", n)
        for child in tokens[1:]:
            if child not in bones:
                raise MotionFormatError(path, f"hierarchy names unknown bone {child!r}", n)
            if child in parent_of:
                raise MotionFormatError(path, f"bone {child!r} has two parents", n)
            parent_of[child] = parent
            children.setdefault(parent, []).append(child)
    # Depth-first pre-order (as BVH lists joints) is parents-first.
    order: list[str] = []
    stack = ["root"]
    while stack:
        top = stack.pop()
        order.append(top)
        stack.extend(reversed(children.get(top, [])))
    unreached = [b for b in bones if b not in order]
    if unreached:
        raise MotionFormatError(path, f"bones not connected to the root: {', '.join(unreached)}")
    index = {name: j for j, name in enumerate(order)}
    n_joints = len(order)
    parents = np.full(n_joints, -1, dtype=np.int64)
    offsets = np.zeros((n_joints, 3))
    axis_q = np.zeros((n_joints, 4))
    axis_q[0] = _axis_q(path, np.zeros(3), root_axis, degrees, 0)
    dofs: list[tuple[str, ...]] = [root_order]
    end_parents: list[int] = []
    end_offsets: list[FloatArray] = []
    for j, name in enumerate(order[1:], start=1):
        bone = bones[name]
        parent = parent_of[name]
        parents[j] = index[parent]
        if parent != "root":
            pb = bones[parent]
            assert pb.direction is not None and pb.length is not None
            offsets[j] = pb.direction * pb.length * metres
        assert bone.axis is not None
        axis_q[j] = bone.axis[0]
        dofs.append(bone.dofs)
        if not children.get(name):
            assert bone.direction is not None and bone.length is not None
            end_parents.append(j)
            end_offsets.append(bone.direction * bone.length * metres)
    skeleton = Skeleton(
        names=tuple(order),
        parents=parents,
        offsets=offsets,
        channels=tuple(tuple(_BVH_NAME[d] for d in ds) for ds in dofs),
        end_parents=np.array(end_parents, dtype=np.int64),
        end_offsets=np.array(end_offsets).reshape(-1, 3),
    )
    return AsfSkeleton(skeleton, tuple(dofs), axis_q, degrees, metres, str(path))


# --- AMC ---------------------------------------------------------------------------------

_NAME_RE = re.compile(r"(?m)^[ \t]*([A-Za-z_][^ \t\r\n]*)")


def read_amc(path: str | Path, asf: AsfSkeleton, name: str | None = None) -> Motion:
    """Read an AMC motion for the skeleton ``asf`` at 120 frames/s (the CMU rate).

    Frames must be numbered consecutively and give every bone that has dofs, with one
    value per dof. A fast vectorised parse handles regular files; anything irregular is
    re-read line by line, which either accepts it or says exactly where it is wrong.
    """
    return read_amc_at(path, asf, fps=120.0, name=name)


def read_amc_at(path: str | Path, asf: AsfSkeleton, fps: float, name: str | None = None) -> Motion:
    """:func:`read_amc` with an explicit frame rate (AMC files do not store one)."""
    text = decode(path, read_bytes(path))
    header_lines, body_start = _amc_header(text)
    body = text[body_start:]
    moving = [j for j, d in enumerate(asf.dofs) if d]
    values = _amc_fast(body, asf, moving)
    if values is None:
        values = _amc_slow(path, body, header_lines, asf, moving)
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
    path: str | Path, body: str, header_lines: int, asf: AsfSkeleton, moving: list[int]
) -> FloatArray:
    names = asf.skeleton.names
    expected = {names[j]: len(asf.dofs[j]) for j in moving}
    all_bones = set(names)
    col_start: dict[str, int] = {}
    c = 0
    for j in moving:
        col_start[names[j]] = c
        c += len(asf.dofs[j])
    width = c
    frames: list[list[float]] = []
    seen: set[str] = set()
    frame_no: int | None = None
    frame_line = 0

    def close_frame(at_line: int) -> None:
        missing = [b for b in expected if b not in seen]
        if missing:
            raise MotionFormatError(
                path,
                f"frame {frame_no} (line {frame_line}) lacks bone(s) {', '.join(missing)}",
                at_line,
            )

    for n, raw in enumerate(body.splitlines(), start=header_lines + 1):
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
        if bone not in all_bones:
            raise MotionFormatError(path, f"bone {bone!r} is not in the skeleton {asf.path}", n)
        if bone not in expected:
            if len(tokens) > 1:
                raise MotionFormatError(path, f"bone {bone!r} has no dofs in {asf.path}", n)
            continue
        if bone in seen:
            raise MotionFormatError(path, f"bone {bone!r} appears twice in frame {frame_no}", n)
        want = expected[bone]
        if len(tokens) - 1 != want:
            dofs = " ".join(asf.dofs[asf.skeleton.index(bone)])
            raise MotionFormatError(
                path, f"bone {bone!r} expects {want} values ({dofs}), got {len(tokens) - 1}", n
            )
        vals = parse_floats(path, tokens[1:], n, f"bone {bone!r}")
        s = col_start[bone]
        frames[-1][s : s + want] = vals
        seen.add(bone)
    if frame_no is not None:
        close_frame(header_lines + len(body.splitlines()))
    return np.array(frames, dtype=np.float64).reshape(-1, width)


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
        rot_idx = [k for k, d in enumerate(dofs) if d in _ROT_DOFS]
        for k, d in enumerate(dofs):
            if d in _TRANS_DOFS:
                root_pos[:, _TRANS_DOFS.index(d)] = block[:, k] * asf.metres_per_unit
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
    norms = np.linalg.norm(quats, axis=-1, keepdims=True)
    return Motion(sk, root_pos, quats / norms, fps, name=name, source=str(path))
