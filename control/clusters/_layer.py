"""The whole higher layer for one graph: states, mixture, forest, and motions for paths."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..artifacts import array_digest
from ..graph import MotionGraph, frame_features
from ..jobs import JobStore
from ..motion import Clip
from ._forest import ClusterForest, build_forest
from ._gmm import (
    FIT_KEYS,
    SEEDINGS,
    Clustering,
    decorrelation_frames,
    fit_arrays,
    fit_mixture,
    fit_of,
    select_by_bic,
)
from ._paths import ProbableMotion, most_probable_motion, transition_log_probs
from ._state import state_vectors

__all__ = ["DEFAULT_KS", "HigherLayer", "LayerSettings", "build_higher_layer"]

DEFAULT_KS = tuple(range(5, 61, 5))
#: the states the costly choices are made on by default (``LayerSettings.sample``)
SAMPLE = 40_000


@dataclass(frozen=True)
class LayerSettings:
    """How the higher layer is built (Lee et al. §4), as ``GraphOptions`` says how the
    graph is.

    Attributes
    ----------
    k : the number of clusters; ``None``: chosen by effective BIC among ``ks``.
    ks : the candidate numbers of clusters of the BIC search.
    seeding : how the mixture's means start: ``"keyframes"`` (frames far apart in pose)
        or ``"random"``.
    seed : the random seed of the mixture's fits.
    bound_seconds : how far ahead a cluster tree reaches (its time bound).
    max_nodes : the most nodes a cluster tree may have.
    max_states : the most search states a tree's build may visit.
    sample : the most states the costly choices are made on, spread evenly over the
        library (0: every state): the BIC search fits each candidate number of clusters
        on them (the chosen one is then fitted on every state, EM starting from the
        sample's means), and the reference orientation is chosen among them (measured
        against every state). A library of that many frames or fewer is clustered exactly
        as without it; a larger one in a time that grows with one full fit rather than
        one per candidate.
    """

    k: int | None = None
    ks: tuple[int, ...] = DEFAULT_KS
    seeding: str = "keyframes"
    seed: int = 0
    bound_seconds: float = 15.0
    max_nodes: int = 4096
    max_states: int = 200_000
    sample: int = SAMPLE

    def __post_init__(self) -> None:
        object.__setattr__(self, "ks", tuple(int(k) for k in self.ks))
        object.__setattr__(self, "bound_seconds", float(self.bound_seconds))
        if self.k is not None and self.k < 1:
            raise ValueError(f"k must be at least 1, not {self.k}")
        if self.k is None and (not self.ks or min(self.ks) < 1):
            raise ValueError(f"ks must be numbers of clusters of at least 1, not {self.ks}")
        if self.seeding not in SEEDINGS:
            raise ValueError(f"seeding must be one of {', '.join(SEEDINGS)}, not {self.seeding!r}")
        if not self.bound_seconds > 0 or self.max_nodes < 1 or self.max_states < 1:
            raise ValueError("bound_seconds, max_nodes and max_states must be positive")
        if self.sample < 0:
            raise ValueError(f"sample must be a number of states >= 0, not {self.sample}")

    def key(self) -> dict[str, Any]:
        """The settings as the layer cache's key names them (``sample`` only where it is
        not the default: a library under it is clustered the same either way, and a
        layer cached before it existed, from every state, serves as well)."""
        out = {
            "k": self.k,
            "ks": list(self.ks),
            "seeding": self.seeding,
            "seed": self.seed,
            "bound_seconds": self.bound_seconds,
            "max_nodes": self.max_nodes,
            "max_states": self.max_states,
        }
        if self.sample != SAMPLE:
            out["sample"] = self.sample
        return out


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
    settings: LayerSettings | None = None,
    cluster: str | None = None,
    progress: Callable[[int, int], None] | None = None,
    work: str | Path | None = None,
    trees: Callable[[int, int], None] | None = None,
) -> HigherLayer:
    """Cluster the graph's frames (``settings.k`` clusters, or chosen by effective BIC
    over ``settings.ks``) and build the cluster forest with its time bound (the BIC
    search's fits and the trees as jobs on ``cluster``, or ``$MIMIC_CLUSTER``, where one
    is named: ``select_by_bic``, ``build_forest``). ``progress(done, total)`` counts the
    mixture fits as they come in (the search's, and the full fit after a sample's). With
    ``work`` (a folder) the fits and the trees are kept there as they finish, so that a
    build stopped midway resumes with them (``_Kept``); ``trees(done, total)`` counts an
    eager forest's trees."""
    st = settings or LayerSettings()
    k, seeding, seed = st.k, st.seeding, st.seed
    chosen = graph.clips_of(clips)
    feat = frame_features(chosen, graph.options.coords)
    x, q_hat = state_vectors(feat, candidates=st.sample or None)
    kept = _Kept(Path(work), x, st) if work is not None else None
    if k is not None:
        best = _full_fit(x, k, st, None, kept)
        fits: list[Clustering] = [best]
        curve: dict[str, Any] = {"k": [k], "bic": [best.bic], "chosen_k": k}
        if progress is not None:
            progress(1, 1)
    elif not 0 < st.sample < x.shape[0]:
        fit_store = kept.fits if kept is not None else None
        best, fits, curve = select_by_bic(
            x, st.ks, seeding, seed, feat.clip_start, cluster, progress=progress, store=fit_store
        )
    else:
        best, fits, curve = _sampled_bic(x, feat.clip_start, st, cluster, progress, kept)
    forest = build_forest(
        graph,
        best.labels,
        st.bound_seconds,
        st.max_nodes,
        st.max_states,
        cluster,
        store=kept.trees(best.labels) if kept is not None else None,
        progress=trees,
    )
    return HigherLayer(
        graph, x, q_hat, best, tuple(fits), curve, forest, transition_log_probs(graph)
    )


class _Kept:
    """Where a layer build keeps its jobs (``control.jobs.JobStore``): ``fits/`` (the
    BIC search's, a job a candidate), ``full/`` (the chosen number of clusters fitted
    on every state) and ``trees/`` (the forest's, a job of trees at a time), each keyed
    by what it was made from (the states, the settings, the labels), so that nothing of
    another build is read back."""

    def __init__(self, folder: Path, x: FloatArray, st: LayerSettings) -> None:
        self.folder = folder
        self.key = array_digest(repr(st.key()), [x])[:24]
        self.fits = JobStore(folder / "fits", self.key)

    def full(self, means_init: FloatArray | None) -> JobStore:
        arrays = [] if means_init is None else [means_init]
        return JobStore(self.folder / "full", array_digest(self.key, arrays)[:24])

    def trees(self, labels: NDArray[np.int64]) -> JobStore:
        return JobStore(self.folder / "trees", array_digest(self.key, [labels])[:24])


def _full_fit(
    x: FloatArray,
    k: int,
    st: LayerSettings,
    means_init: FloatArray | None,
    kept: _Kept | None,
) -> Clustering:
    """``fit_mixture`` of every state, read back where a stopped build kept it."""
    store = kept.full(means_init) if kept is not None else None
    if store is not None and (done := store.done(1, FIT_KEYS)):
        return fit_of(done[0])
    fit = fit_mixture(x, k, st.seeding, st.seed, means_init=means_init)
    if store is not None:
        store.save(0, fit_arrays(fit))
    return fit


def _sampled_bic(
    x: FloatArray,
    clip_start: NDArray[np.int64],
    st: LayerSettings,
    cluster: str | None,
    progress: Callable[[int, int], None] | None,
    kept: _Kept | None = None,
) -> tuple[Clustering, list[Clustering], dict[str, Any]]:
    """``select_by_bic`` on ``st.sample`` states spread evenly over ``x``, with the
    effective size of all of them; then the chosen ``k`` fitted on every state from the
    sample fit's means. ``fits`` are the sample's; the curve says the sample's size."""
    n = x.shape[0]
    sample = np.unique(np.linspace(0, n - 1, st.sample).round().astype(np.int64))
    n_eff = n / decorrelation_frames(x, clip_start)
    total = len(st.ks) + 1
    each = None if progress is None else lambda done, _: progress(done, total)
    chosen, fits, curve = select_by_bic(
        x[sample],
        st.ks,
        st.seeding,
        st.seed,
        cluster=cluster,
        n_eff=n_eff,
        progress=each,
        store=kept.fits if kept is not None else None,
    )
    best = _full_fit(x, chosen.k, st, chosen.means, kept)
    if progress is not None:
        progress(total, total)
    curve["sample"] = int(sample.size)
    return best, fits, curve
