"""Action-to-action transitions (Peng et al.): two-pass clustering, the cluster transition
graph and its candidate paths, the chainer that assembles requested actions into one
motion with root alignment (``Chainer``, behind ``mimic chain``), and parametric actions:
an action's examples found by DTW, registered and blended to hit a target point
(``ParametricAction``, Peng et al. §6). The run-time pieces (node pair, path choice,
greedy stitching at optimal transition points, the Bezier fallback's curve, walk and
duration; ``_runtime``, ``_bezier``) and the examples' search (``_examples``) are the
chainer's own."""

from ._chain import Action, Chainer, ChainPlayer, ChainResult
from ._cluster import FrameClusters, two_pass_clusters
from ._parametric import Blend, ParametricAction
from ._tgraph import CandidatePaths, TransitionGraph, build_transition_graph, candidate_paths

__all__ = [
    "Action",
    "Blend",
    "CandidatePaths",
    "ChainPlayer",
    "ChainResult",
    "Chainer",
    "FrameClusters",
    "ParametricAction",
    "TransitionGraph",
    "build_transition_graph",
    "candidate_paths",
    "two_pass_clusters",
]
