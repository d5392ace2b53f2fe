"""The whole higher layer for one graph: states, mixture, forest, and motions for paths."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..graph import MotionGraph, frame_features
from ..motion import Clip
from ._forest import ClusterForest, build_forest
from ._gmm import Clustering, fit_mixture, select_by_bic
from ._paths import ProbableMotion, most_probable_motion, transition_log_probs
from ._state import state_vectors

__all__ = ["DEFAULT_KS", "HigherLayer", "build_higher_layer"]

DEFAULT_KS = tuple(range(5, 61, 5))
FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class HigherLayer:
    """Clusters of the graph's frames and the cluster forest.

    Attributes
    ----------
    graph : the lower layer.
    states : (n, d) motion state vectors (eq. 4); ``q_hat`` the reference orientation.
    clustering : the chosen mixture; ``fits`` every mixture tried; ``curve`` the BIC curve.
    forest : the cluster trees.
    """

    graph: MotionGraph
    states: FloatArray
    q_hat: FloatArray
    clustering: Clustering
    fits: tuple[Clustering, ...]
    curve: dict[str, Any]
    forest: ClusterForest
    tables: tuple[FloatArray, FloatArray] = field(repr=False)

    @property
    def labels(self) -> NDArray[np.int64]:
        return self.clustering.labels

    def motion_to(self, frame: int, node: int, bound: int | None = None) -> ProbableMotion | None:
        """The most probable motion from ``frame`` to the cluster of ``node`` of its tree,
        at most ``bound`` frames long (default: the forest's time bound).

        A frame without a tree of its own plays on to the frame whose tree it shares;
        those frames come first.
        """
        tree = self.forest.tree(frame)
        r = tree.root_frame
        if r < frame:
            raise ValueError(f"frame {frame} does not lead to its tree's frame {r}")
        limit = self.forest.bound if bound is None else min(bound - (r - frame), self.forest.bound)
        if limit < 0:
            return None
        best = most_probable_motion(
            self.graph,
            self.labels,
            self.clustering.posterior,
            r,
            tree.clusters_to(node),
            limit,
            self.tables,
        )
        if best is None or r == frame:
            return best
        prefix = np.arange(frame, r, dtype=np.int64)
        return ProbableMotion(
            np.concatenate((prefix, best.frames)),
            np.concatenate((np.full(prefix.size, -1, dtype=np.int64), best.edges)),
            best.clusters,
            best.log_prob,
        )


def build_higher_layer(
    graph: MotionGraph,
    clips: Sequence[Clip],
    k: int | None = None,
    ks: Sequence[int] = DEFAULT_KS,
    seeding: str = "keyframes",
    seed: int = 0,
    bound_seconds: float = 15.0,
    max_nodes: int = 4096,
    max_states: int = 200_000,
    cluster: str | None = None,
) -> HigherLayer:
    """Cluster the graph's frames (``k`` clusters, or chosen by effective BIC over ``ks``)
    and build the cluster forest with a ``bound_seconds`` time bound (the BIC search's
    fits and the trees as jobs on ``cluster``, or ``$MIMIC_CLUSTER``, where one is named:
    ``select_by_bic``, ``build_forest``)."""
    chosen = graph.clips_of(clips)
    feat = frame_features(chosen, graph.options.coords)
    x, q_hat = state_vectors(feat)
    if k is not None:
        best = fit_mixture(x, k, seeding=seeding, seed=seed)
        fits: list[Clustering] = [best]
        curve: dict[str, Any] = {"k": [k], "bic": [best.bic], "chosen_k": k}
    else:
        best, fits, curve = select_by_bic(
            x, ks, seeding=seeding, seed=seed, clip_start=feat.clip_start, cluster=cluster
        )
    forest = build_forest(graph, best.labels, bound_seconds, max_nodes, max_states, cluster)
    return HigherLayer(
        graph, x, q_hat, best, tuple(fits), curve, forest, transition_log_probs(graph)
    )
