"""Action-to-action transitions (Peng et al.): two-pass clustering, the cluster transition
graph, its candidate paths, and the run-time pieces (node pair, path choice, greedy
stitching at optimal transition points, the Bezier fallback's curve, walk and duration),
and the chainer that assembles requested actions into one motion with root alignment
(``Chainer``, behind ``mimic chain``), and parametric actions: an action's examples found
by DTW, registered and blended to hit a target point (``ParametricAction``, Peng et al.
§6)."""

from ._bezier import average_quats, bezier_quats, greedy_walk, interpolation_frames
from ._chain import Action, Chainer, ChainPlayer, ChainResult
from ._cluster import FrameClusters, two_pass_clusters
from ._examples import Example, find_examples, register
from ._parametric import Blend, ParametricAction
from ._runtime import choose_path, clip_frames, nearest_cluster, stitch_path, transition_point
from ._tgraph import CandidatePaths, TransitionGraph, build_transition_graph, candidate_paths

__all__ = [
    "Action",
    "Blend",
    "CandidatePaths",
    "ChainPlayer",
    "ChainResult",
    "Chainer",
    "Example",
    "FrameClusters",
    "ParametricAction",
    "TransitionGraph",
    "average_quats",
    "bezier_quats",
    "build_transition_graph",
    "candidate_paths",
    "choose_path",
    "clip_frames",
    "find_examples",
    "greedy_walk",
    "interpolation_frames",
    "nearest_cluster",
    "register",
    "stitch_path",
    "transition_point",
    "two_pass_clusters",
]
