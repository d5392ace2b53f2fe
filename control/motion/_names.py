"""Joint roles (which joint is the left knee?) and left/right partners, by name.

Skeletons from different sources name joints differently (CMU ASF ``ltibia``, CMU BVH
``lShin``, Mixamo-style ``LeftLeg``). Roles give the rest of the system one vocabulary.
Matching is case-insensitive and takes the first alias that the skeleton has.
"""

from __future__ import annotations

import numpy as np

from ._types import Skeleton

__all__ = ["ROLE_ALIASES", "find_role", "mirror_map", "role_point"]

_SIDE_ALIASES = {
    "hip": ["{s}femur", "{s}thigh", "{S}upleg", "{s}_hip", "{S}hip", "{S}thigh"],
    "knee": ["{s}tibia", "{s}shin", "{S}leg", "{s}_knee", "{S}knee", "{S}shin"],
    "ankle": ["{s}foot", "{S}foot", "{s}_ankle", "{S}ankle"],
    "toe": ["{s}toes", "{S}toebase", "{S}toe", "{s}_toe", "{s}toe"],
    "shoulder": ["{s}humerus", "{s}shldr", "{S}arm", "{s}_shoulder", "{S}shoulder"],
    "elbow": ["{s}radius", "{s}forearm", "{S}forearm", "{s}_elbow", "{S}elbow"],
    "wrist": ["{s}wrist", "{s}hand", "{S}hand", "{s}_wrist", "{S}wrist"],
    "collar": ["{s}clavicle", "{s}collar", "{S}shoulder", "{s}_collar", "{S}collar"],
}

#: role -> candidate joint names, lower case, most specific first.
ROLE_ALIASES: dict[str, list[str]] = {
    "root": ["root", "hip", "hips", "pelvis"],
    "spine": ["lowerback", "abdomen", "spine", "spine1"],
    "chest": ["thorax", "chest", "spine2", "spine1", "upperback"],
    "neck": ["lowerneck", "neck", "neck1"],
    "head": ["head"],
}
for _part, _forms in _SIDE_ALIASES.items():
    for _side, _s, _S in (("left", "l", "left"), ("right", "r", "right")):
        ROLE_ALIASES[f"{_side}_{_part}"] = [f.format(s=_s, S=_S) for f in _forms]


def find_role(skeleton: Skeleton, role: str) -> int | None:
    """Index of the joint that plays ``role`` (a key of ``ROLE_ALIASES``), or ``None``."""
    if role not in ROLE_ALIASES:
        raise KeyError(f"unknown role {role!r}; known: {', '.join(sorted(ROLE_ALIASES))}")
    lower = {n.lower(): j for j, n in enumerate(skeleton.names)}
    for alias in ROLE_ALIASES[role]:
        if alias in lower:
            return lower[alias]
    return None


def role_point(skeleton: Skeleton, role: str) -> tuple[str, int]:
    """Where to read a role's position: ``("joint", j)`` or ``("end", e)``.

    A toe with no joint of its own (CMU BVH feet end in an end site) is the farthest end
    site under the ankle. Raises ``KeyError`` when the skeleton has no such point.
    """
    j = find_role(skeleton, role)
    if j is not None:
        return ("joint", j)
    if role.endswith("_toe"):
        ankle = find_role(skeleton, role.replace("_toe", "_ankle"))
        if ankle is not None:
            ends = np.flatnonzero(skeleton.end_parents == ankle)
            if ends.size:
                far = ends[np.argmax(np.linalg.norm(skeleton.end_offsets[ends], axis=1))]
                return ("end", int(far))
    raise KeyError(f"skeleton has no joint for role {role!r} (joints: {', '.join(skeleton.names)})")


def _partner_candidates(name: str) -> list[str]:
    out = []
    for a, b in (("l", "r"), ("r", "l")):
        if name.startswith(a) and len(name) > 1:
            out.append(b + name[1:])
        if name.startswith(a.upper()) and len(name) > 1:
            out.append(b.upper() + name[1:])
        if name.lower().endswith(("_" + a, "." + a)):
            out.append(name[:-1] + (b if name[-1].islower() else b.upper()))
    for a, b in (("left", "right"), ("right", "left")):
        for src, dst in ((a, b), (a.capitalize(), b.capitalize()), (a.upper(), b.upper())):
            if src in name:
                out.append(name.replace(src, dst))
    return out


def mirror_map(skeleton: Skeleton) -> np.ndarray:
    """(J,) int: the left/right partner of every joint (itself on the midline).

    Raises ``ValueError`` when the partners found by name do not form a consistent
    symmetry of the hierarchy.
    """
    index = {n: j for j, n in enumerate(skeleton.names)}
    partner = np.arange(skeleton.n_joints)
    for j, name in enumerate(skeleton.names):
        for cand in _partner_candidates(name):
            if cand in index and cand != name:
                partner[j] = index[cand]
                break
    if not np.array_equal(partner[partner], np.arange(skeleton.n_joints)):
        raise ValueError("left/right joint names do not pair up one to one")
    par = skeleton.parents
    for j in range(1, skeleton.n_joints):
        if par[partner[j]] != partner[par[j]]:
            raise ValueError(
                f"joints {skeleton.names[j]!r} and {skeleton.names[partner[j]]!r} pair by name "
                "but their parents do not"
            )
    return partner
