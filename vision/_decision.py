"""What the matcher answers: a ``Decision``, with the ``Jump`` it took when it took one."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

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

    def logged(self, view: int) -> dict[str, Any]:
        """The decision's part of its log entry (``view``: the one the avatar is shown
        from, the last decision's where this one has none); costs ``None`` where infinite."""

        def num(x: float, digits: int) -> float | None:
            return round(x, digits) if math.isfinite(x) else None

        out: dict[str, Any] = {self.how: True} if self.how in ("plays_on", "held") else {}
        if self.jump is not None:
            if self.jump.leaves:  # (for the action voted for, whatever it costs)
                out["leaves"] = True
            out.update(
                jump=self.jump.target,
                own_cost=num(self.jump.own_cost, 4),
                blend=round(self.jump.blend, 4),
            )
        out.update(
            decision=[int(c) for c in self.cluster_path],
            cost=num(self.cost, 4),
            runner_up=num(self.runner_up, 4),
            view=view,
            candidates=self.candidates,
            latency_ms=round(self.latency_ms, 3),
        )
        return out
