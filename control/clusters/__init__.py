"""Higher layer (Lee et al. §4.2): motion states, spherical Gaussian mixture by BIC, the
cluster forest, cluster paths and their most probable motions."""

from ._cache import LayerFileError, cached_higher_layer, load_layer, save_layer
from ._forest import ClusterForest, ClusterTree
from ._gmm import (
    Clustering,
    decorrelation_frames,
    fit_mixture,
    select_by_bic,
)
from ._layer import DEFAULT_KS, HigherLayer, LayerSettings, build_higher_layer
from ._paths import ProbableMotion, transition_log_probs
from ._state import orientation_distance, state_vectors

__all__ = [
    "DEFAULT_KS",
    "ClusterForest",
    "ClusterTree",
    "Clustering",
    "HigherLayer",
    "LayerFileError",
    "LayerSettings",
    "ProbableMotion",
    "build_higher_layer",
    "cached_higher_layer",
    "decorrelation_frames",
    "fit_mixture",
    "load_layer",
    "orientation_distance",
    "save_layer",
    "select_by_bic",
    "state_vectors",
    "transition_log_probs",
]
