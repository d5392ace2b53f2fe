"""Acclaim ASF skeleton reader (the AMC motion reader is ``_amc``).

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

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ._errors import MotionFormatError
from ._quat import FloatArray, euler_to_q
from ._text import decode, parse_floats, read_bytes
from ._types import Skeleton

__all__ = ["AsfSkeleton", "read_asf"]

INCH = 0.0254
ROT_DOFS = ("rx", "ry", "rz")
TRANS_DOFS = ("tx", "ty", "tz")
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


#: the longest bone a skeleton may have, metres (after the units are applied)
MAX_BONE_M = 10.0


def _bonedata_line(
    path: str | Path,
    tokens: list[str],
    n: int,
    current: _Bone | None,
    bones: dict[str, _Bone],
    degrees: bool,
) -> _Bone | None:
    """One line ``n`` of the ``:bonedata`` section: a bone begun, ended (into ``bones``)
    or given a field; the bone open after it."""
    key = tokens[0].lower()
    if key == "begin":
        if current is not None:
            raise MotionFormatError(path, "'begin' inside a bone that has no 'end'", n)
        return _Bone(name="", line=n)
    if key == "end":
        if current is None:
            raise MotionFormatError(path, "'end' without 'begin'", n)
        _finish_bone(path, current, bones)
        return None
    if current is None:
        raise MotionFormatError(path, f"{tokens[0]!r} outside a bone's begin/end", n)
    _bone_field(path, current, tokens, n, degrees)
    return current


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
    head = _Header()
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
            _units_field(path, head, tokens, n, line)
        elif section == ":root":
            _root_field(path, head, tokens, n)
        elif section == ":bonedata":
            current = _bonedata_line(path, tokens, n, current, bones, head.degrees)
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

    _check_ended(path, current, seen_sections, hierarchy, len(lines))
    metres = INCH / head.length_unit if metres_per_unit is None else float(metres_per_unit)
    return _assemble(path, bones, hierarchy, head.root_order, head.root_axis, head.degrees, metres)


def _check_ended(
    path: str | Path,
    current: _Bone | None,
    sections: set[str],
    hierarchy: list[tuple[int, list[str]]],
    n_lines: int,
) -> None:
    """At the file's end: no bone left open, and a bone section and a hierarchy read."""
    if current is not None:
        raise MotionFormatError(path, f"bone begun on line {current.line} has no 'end'", n_lines)
    for required in (":bonedata", ":hierarchy"):
        if required not in sections:
            raise MotionFormatError(path, f"no {required} section")
    if not hierarchy:
        raise MotionFormatError(path, "the hierarchy is empty")


@dataclass
class _Header:
    """What the ``:units`` and ``:root`` sections say."""

    length_unit: float = 1.0
    degrees: bool = True
    root_order: tuple[str, ...] = ("tx", "ty", "tz", "rx", "ry", "rz")
    root_axis: str = "XYZ"


def _units_field(path: str | Path, head: _Header, tokens: list[str], n: int, line: str) -> None:
    key = tokens[0].lower()
    if len(tokens) != 2:
        raise MotionFormatError(path, f"units line needs a name and a value: {line!r}", n)
    if key == "length":
        (head.length_unit,) = parse_floats(path, tokens[1:], n, "units length")
        if head.length_unit <= 0:
            raise MotionFormatError(path, "units length must be positive", n)
    elif key == "angle":
        if tokens[1].lower() not in ("deg", "rad"):
            raise MotionFormatError(path, f"angle unit {tokens[1]!r} is not deg or rad", n)
        head.degrees = tokens[1].lower() == "deg"


def _root_field(path: str | Path, head: _Header, tokens: list[str], n: int) -> None:
    key = tokens[0].lower()
    if key == "order":
        order = tuple(t.lower() for t in tokens[1:])
        bad = [t for t in order if t not in ROT_DOFS + TRANS_DOFS]
        if bad or len(set(order)) != len(order):
            raise MotionFormatError(path, f"bad root order {' '.join(tokens[1:])!r}", n)
        head.root_order = order
    elif key == "axis":
        if len(tokens) != 2:
            raise MotionFormatError(path, "root axis needs one order like XYZ", n)
        head.root_axis = tokens[1]
        _axis_q(path, np.zeros(3), head.root_axis, head.degrees, n)
    elif key in ("position", "orientation"):
        parse_floats(path, tokens[1:], n, f"root {key}")
    else:
        raise MotionFormatError(path, f"unknown root field {tokens[0]!r}", n)


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
            if d not in ROT_DOFS:
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


def _tree(
    path: str | Path, bones: dict[str, _Bone], hierarchy: list[tuple[int, list[str]]]
) -> tuple[list[str], dict[str, list[str]], dict[str, str]]:
    """The ``:hierarchy`` lines (line number, tokens) checked against ``bones``: the
    joints parents first (depth-first pre-order, as BVH lists them, from ``root``),
    each bone's children, and each bone's parent."""
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
    order: list[str] = []
    stack = ["root"]
    while stack:
        top = stack.pop()
        order.append(top)
        stack.extend(reversed(children.get(top, [])))
    unreached = [b for b in bones if b not in order]
    if unreached:
        raise MotionFormatError(path, f"bones not connected to the root: {', '.join(unreached)}")
    return order, children, parent_of


def _assemble(
    path: str | Path,
    bones: dict[str, _Bone],
    hierarchy: list[tuple[int, list[str]]],
    root_order: tuple[str, ...],
    root_axis: str,
    degrees: bool,
    metres: float,
) -> AsfSkeleton:
    order, children, parent_of = _tree(path, bones, hierarchy)
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
    for name in order[1:]:  # after the units are applied: a person's bones, not 1e8 m
        b = bones[name]
        assert b.length is not None
        if b.length * metres > MAX_BONE_M:
            raise MotionFormatError(
                path,
                f"bone {name!r} is {b.length * metres:.3g} m long after the units "
                f"(over {MAX_BONE_M:g} m): wrong units or a broken file",
            )
    skeleton = Skeleton(
        names=tuple(order),
        parents=parents,
        offsets=offsets,
        channels=tuple(tuple(_BVH_NAME[d] for d in ds) for ds in dofs),
        end_parents=np.array(end_parents, dtype=np.int64),
        end_offsets=np.array(end_offsets).reshape(-1, 3),
    )
    return AsfSkeleton(skeleton, tuple(dofs), axis_q, degrees, metres, str(path))
