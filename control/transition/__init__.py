"""Action-to-action transitions (Peng et al.): two-pass clustering, the cluster transition
graph and its candidate paths. (The run-time phase, clip stitching and the Bezier
fallback are not built yet.)"""

from ._cluster import FrameClusters, two_pass_clusters
from ._tgraph import CandidatePaths, TransitionGraph, build_transition_graph, candidate_paths

__all__ = [
    "CandidatePaths",
    "FrameClusters",
    "TransitionGraph",
    "build_transition_graph",
    "candidate_paths",
    "two_pass_clusters",
]
