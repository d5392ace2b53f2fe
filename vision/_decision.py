"""What the matcher answers: a ``Decision``, with the ``Jump`` it took when it took one."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["Decision", "Jump"]

IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class Jump:
    """A direct blended jump: its ``target`` frame, the avatar's ``own_cost`` it beat,
    the pose distance its ``blend`` starts from, and whether it ``leaves`` the avatar's
    action for the one voted for, whatever it costs."""

    target: int
    own_cost: float
    blend: float
    leaves: bool = False


@dataclass(frozen=True, eq=False)
class Decision:
    """The chosen path (``frames``, ``edges`` from the avatar's frame) and the costs."""

    frames: IntArray
    edges: IntArray
    cluster_path: IntArray
    cost: float
    runner_up: float
    view: int
    candidates: int
    latency_ms: float
    #: the avatar's own frame "plays_on" or is "held" (shown again); "" for the paper's
    #: cluster path or a direct jump (``jump``)
    how: str = ""
    jump: Jump | None = None
