"""The choice interface (Lee et al. §5.1): a few well-dispersed actions to pick from.

From the avatar's frame, the actions are the leaves of its cluster tree, optionally only
those reached within a look-ahead window of time and whose motion ends in a region of
the floor (Fig. 6: nodes inside both windows are selected, and the leaves of the selected
subtree are offered). At most one action per cluster (the earliest), then the most
different ones by farthest-point selection over the clusters' mean states. Each action
comes with its most probable motion, its key pose (the frame that enters the chosen
cluster) and the path its root would trace in the avatar's world.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .avatar import Avatar
from .clusters import ClusterTree, HigherLayer
from .graph import FrameData, rotate_y, segment_maps

__all__ = ["Option", "offer"]

IntArray = NDArray[np.int64]


@dataclass(frozen=True, eq=False)
class Option:
    """One action on offer.

    Attributes
    ----------
    cluster : the cluster the action leads to; ``node`` its node in the tree.
    frames, edges : the path from the avatar's frame (``Avatar.take`` accepts them).
    key_frame : the graph frame of the key pose (the first in ``cluster``).
    seconds : how long the action takes.
    root_path : (N, 3) the root's positions along it, in the avatar's world.
    """

    cluster: int
    node: int
    frames: IntArray
    edges: IntArray
    key_frame: int
    seconds: float
    root_path: NDArray[np.float64]


def _root_path(
    avatar: Avatar, data: FrameData, frames: IntArray, edges: IntArray
) -> NDArray[np.float64]:
    jumps = np.flatnonzero(edges >= 0)
    yaws, trans = segment_maps(avatar.graph.align[edges[jumps]], *avatar.root_transform())
    seg = np.searchsorted(jumps + 1, np.arange(frames.size), side="right")
    return rotate_y(data.root[frames], yaws[seg]) + trans[seg]


def _candidates(
    tree: ClusterTree, selected: NDArray[np.bool_], t: NDArray[np.float64]
) -> tuple[list[int], int]:
    """One tree node per cluster, leaves of the selected subtree first (earliest first),
    then, for when there are fewer than wanted, its other selected nodes: reaching an
    intermediate cluster is an action as well. Also the number of the leaves' clusters."""
    # the leaves of the selected subtree; ancestors must be selected for a node to count
    reachable, leaves = tree.subtree(selected)
    if leaves.size > 1:
        leaves = leaves[leaves != 0]
    inner = np.setdiff1d(np.flatnonzero(reachable), leaves)
    inner = inner[inner != 0]
    order = np.concatenate(
        (leaves[np.argsort(t[leaves], kind="stable")], inner[np.argsort(t[inner], kind="stable")])
    )
    # one node per cluster: the first in that order
    first: dict[int, int] = {}
    for node in order:
        first.setdefault(int(tree.cluster[node]), int(node))
    return list(first.values()), len({int(tree.cluster[x]) for x in leaves})


def _most_distinct(
    pool: list[int], picked: list[int], cluster: NDArray[np.int64], means: NDArray[np.float64]
) -> int:
    """The node of ``pool`` whose cluster's mean is farthest from every picked node's
    (the first of ``pool`` before any is picked): offered actions that differ."""
    if not picked:
        return pool[0]
    pm = means[[cluster[p] for p in picked]]
    cm = means[[cluster[c] for c in pool]]
    gap = np.min(((cm[:, None, :] - pm[None]) ** 2).sum(-1), axis=1)
    return pool[int(np.argmax(gap))]


def offer(
    layer: HigherLayer,
    avatar: Avatar,
    data: FrameData,
    n: int = 4,
    lookahead: tuple[float, float] | None = None,
    region: tuple[float, float, float] | None = None,
) -> list[Option]:
    """Up to ``n`` actions from the avatar's current frame.

    Parameters
    ----------
    layer : the higher layer of the avatar's graph. ``data`` : ``FrameData`` of it.
    lookahead : ``(t_min, t_max)`` seconds: only tree nodes first reached in this window.
    region : ``(x, z, radius)`` metres: only actions whose root ends inside this circle.

    Returns an empty list when nothing can be chosen within the look-ahead (the avatar
    must first play on to its next branching frame, further away than ``t_max``) or no
    action ends in the region.
    """
    if n < 1:
        raise ValueError("n must be at least 1")
    frame = avatar.frame
    tree = layer.forest.tree(frame)
    fps = layer.graph.fps
    lead = tree.root_frame - frame  # frames played before the tree's own frame
    t = (tree.arrival + lead) / fps
    selected = np.ones(tree.size, dtype=bool)
    bound = None
    if lookahead is not None:
        t_min, t_max = lookahead
        selected = (t >= t_min) & (t <= t_max)
        bound = int(np.floor(t_max * fps + 1e-9))
    candidates, n_leaf = _candidates(tree, selected, t)
    chosen: list[Option] = []
    picked: list[int] = []
    while candidates and len(chosen) < n:
        pool = candidates[: max(n_leaf - len(picked), 0)] or candidates
        nxt = _most_distinct(pool, picked, tree.cluster, layer.clustering.means)
        candidates.remove(nxt)
        motion = layer.motion_to(frame, nxt, bound)
        if motion is None:
            continue
        root_path = _root_path(avatar, data, motion.frames, motion.edges)
        if region is not None:
            x, z, radius = region
            end = root_path[-1]
            if (end[0] - x) ** 2 + (end[2] - z) ** 2 > radius**2:
                continue
        picked.append(nxt)
        chosen.append(
            Option(
                cluster=int(tree.cluster[nxt]),
                node=nxt,
                frames=motion.frames,
                edges=motion.edges,
                key_frame=int(motion.frames[-1]),
                seconds=(motion.frames.size - 1) / fps,
                root_path=root_path,
            )
        )
    return chosen
