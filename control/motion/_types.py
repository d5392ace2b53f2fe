"""``Skeleton`` and ``Motion``: frozen dataclasses of read-only arrays.

Conventions (see ``_quat`` for the quaternion glossary):

- Y is up, lengths are metres, time is ``frame / fps`` seconds.
- Joints are stored parents-first: ``parents[j] < j`` and ``parents[0] == -1``.
- A joint's local rotation ``quats[f, j]`` rotates its own frame relative to its
  parent's; its position is ``pos[parent] + R_parent_global @ offsets[j]``. The rest pose is
  every local rotation equal to the identity.
- End sites are points fixed in a joint's frame (toe tips, the top of the head): they
  have a position but no rotation channel.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["Motion", "Skeleton"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


def _frozen(a: NDArray[Any], dtype: type) -> NDArray[Any]:
    out: NDArray[Any] = np.array(a, dtype=dtype, copy=True)
    out.setflags(write=False)
    return out


@dataclass(frozen=True, eq=False)
class Skeleton:
    """Joint hierarchy with rest offsets.

    Attributes
    ----------
    names : (J,) joint names, unique.
    parents : (J,) int, parent index, -1 for the root; parents come first.
    offsets : (J, 3) metres, each joint's position in its parent's frame at rest.
    channels : per joint, the channel layout of the source file, in file order, as BVH
        channel names (``"Xposition"``, ``"Zrotation"``...). Informative: the motion itself
        is stored as quaternions.
    end_parents : (E,) int, the joint each end site hangs from.
    end_offsets : (E, 3) metres, the end site in that joint's frame.
    """

    names: tuple[str, ...]
    parents: IntArray
    offsets: FloatArray
    channels: tuple[tuple[str, ...], ...]
    end_parents: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    end_offsets: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))

    def __post_init__(self) -> None:
        names = tuple(str(n) for n in self.names)
        parents = _frozen(self.parents, np.int64).reshape(-1)
        offsets = _frozen(self.offsets, np.float64).reshape(-1, 3)
        end_parents = _frozen(self.end_parents, np.int64).reshape(-1)
        end_offsets = _frozen(self.end_offsets, np.float64).reshape(-1, 3)
        n = len(names)
        if n == 0:
            raise ValueError("a skeleton needs at least one joint")
        if len(set(names)) != n:
            raise ValueError("joint names must be unique")
        if parents.shape != (n,) or offsets.shape != (n, 3) or len(self.channels) != n:
            raise ValueError("names, parents, offsets and channels must have one entry a joint")
        if parents[0] != -1 or np.any(parents[1:] < 0) or np.any(parents[1:] >= np.arange(1, n)):
            raise ValueError("joints must be ordered parents-first with a single root at 0")
        if end_parents.shape[0] != end_offsets.shape[0]:
            raise ValueError("end_parents and end_offsets differ in length")
        if end_parents.size and (end_parents.min() < 0 or end_parents.max() >= n):
            raise ValueError("an end site hangs from a joint that does not exist")
        if not (np.all(np.isfinite(offsets)) and np.all(np.isfinite(end_offsets))):
            raise ValueError("offsets must be finite")
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "parents", parents)
        object.__setattr__(self, "offsets", offsets)
        object.__setattr__(self, "channels", tuple(tuple(c) for c in self.channels))
        object.__setattr__(self, "end_parents", end_parents)
        object.__setattr__(self, "end_offsets", end_offsets)

    @property
    def n_joints(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        """Index of the joint called ``name`` (exact match); ``KeyError`` if absent."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"no joint named {name!r}") from None

    def children(self, j: int) -> list[int]:
        """Indices of the joints whose parent is ``j``."""
        return [int(c) for c in np.flatnonzero(self.parents == j)]

    def same_as(self, other: Skeleton, atol: float = 1e-9) -> bool:
        """True when both skeletons have the same joints, hierarchy and offsets."""
        return (
            self.names == other.names
            and np.array_equal(self.parents, other.parents)
            and np.array_equal(self.end_parents, other.end_parents)
            and np.allclose(self.offsets, other.offsets, atol=atol, rtol=0)
            and np.allclose(self.end_offsets, other.end_offsets, atol=atol, rtol=0)
        )

    def scaled(self, factor: float) -> Skeleton:
        """The same skeleton with every length multiplied by ``factor``."""
        return replace(self, offsets=self.offsets * factor, end_offsets=self.end_offsets * factor)


@dataclass(frozen=True, eq=False)
class Motion:
    """A clip: root trajectory and local joint rotations over frames.

    Attributes
    ----------
    skeleton : the joint hierarchy.
    root_pos : (F, 3) metres, the root joint's world position.
    quats : (F, J, 4) unit quaternions (w, x, y, z), local rotation of every joint
        (``quats[:, 0]`` is the root's world orientation).
    fps : frames per second.
    name : the clip's name (``"02_01"``).
    source : where it came from (a file path, or a description of the operation).
    """

    skeleton: Skeleton
    root_pos: FloatArray
    quats: FloatArray
    fps: float
    name: str = ""
    source: str = ""

    def __post_init__(self) -> None:
        root_pos = _frozen(self.root_pos, np.float64)
        quats = _frozen(self.quats, np.float64)
        j = self.skeleton.n_joints
        if root_pos.ndim != 2 or root_pos.shape[1] != 3:
            raise ValueError(f"root_pos must be (F, 3), got {root_pos.shape}")
        if quats.shape != (root_pos.shape[0], j, 4):
            raise ValueError(f"quats must be ({root_pos.shape[0]}, {j}, 4), got {quats.shape}")
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise ValueError(f"fps must be positive, got {self.fps}")
        if not (np.all(np.isfinite(root_pos)) and np.all(np.isfinite(quats))):
            raise ValueError("motion values must be finite")
        if quats.size and np.max(np.abs(np.einsum("fjk,fjk->fj", quats, quats) - 1.0)) > 1e-6:
            raise ValueError("quats must be unit quaternions")
        object.__setattr__(self, "root_pos", root_pos)
        object.__setattr__(self, "quats", quats)
        object.__setattr__(self, "fps", float(self.fps))

    @property
    def n_frames(self) -> int:
        return int(self.root_pos.shape[0])

    @property
    def duration(self) -> float:
        """Seconds from the first to the last frame."""
        return max(self.n_frames - 1, 0) / self.fps

    def __len__(self) -> int:
        return self.n_frames
