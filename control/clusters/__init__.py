"""Higher layer (Lee et al. §4.2): motion states, spherical Gaussian mixture by BIC, the
cluster forest, cluster paths and their most probable motions."""

from ._cache import LAYER_VERSION, LayerFileError, cached_higher_layer, load_layer, save_layer
from ._forest import ClusterForest, ClusterTree, build_forest
from ._gmm import (
    SEEDINGS,
    Clustering,
    decorrelation_frames,
    effective_bic,
    fit_mixture,
    keyframe_seeds,
    select_by_bic,
)
from ._layer import DEFAULT_KS, HigherLayer, LayerSettings, build_higher_layer
from ._paths import ProbableMotion, most_probable_motion, transition_log_probs
from ._state import orientation_distance, reference_orientation, state_vectors

__all__ = [
    "DEFAULT_KS",
    "LAYER_VERSION",
    "SEEDINGS",
    "ClusterForest",
    "ClusterTree",
    "Clustering",
    "HigherLayer",
    "LayerFileError",
    "LayerSettings",
    "ProbableMotion",
    "build_forest",
    "build_higher_layer",
    "cached_higher_layer",
    "decorrelation_frames",
    "effective_bic",
    "fit_mixture",
    "keyframe_seeds",
    "load_layer",
    "most_probable_motion",
    "orientation_distance",
    "reference_orientation",
    "save_layer",
    "select_by_bic",
    "state_vectors",
    "transition_log_probs",
]
