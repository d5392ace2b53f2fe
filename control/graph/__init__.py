"""Lower layer (Lee et al. §4.1): frame distance, transition likelihoods, pruning, SCC,
blended transitions and the random walk."""

from ._artifact import GraphFileError, cached_graph, graph_cache_dir, load_graph, save_graph
from ._blending import BlendSettings
from ._distance import (
    pair_distances,
)
from ._features import (
    COORDS,
    FrameFeatures,
    frame_features,
    root_scales,
    rotate_y,
    weighted_joints,
    yaw_of,
    yaw_q,
)
from ._graph import (
    GraphOptions,
    MotionGraph,
    build_graph,
    graph_sigma,
    select_clips,
)
from ._ik import (
    TURN_RATE,
    knee_hinge,
    leg_chain,
    solve_leg,
)
from ._prune import (
    CONTACT_RULES,
    case4,
    largest_scc,
)
from ._quality import (
    foot_slide,
    jerk,
    joint_jumps,
    longest_off_floor,
    lowest_foot,
    off_floor_seconds,
    quality_summary,
    sole_speed,
)
from ._synth import FrameData, Synthesis, compose, hermite, segment_maps, synthesize
from ._terrain import CapturedTerrain, FootTrack, captured_terrain, foot_track, terrain_options
from ._turns import (
    follow_turns,
)
from ._walk import random_step, random_walk

__all__ = [
    "CONTACT_RULES",
    "COORDS",
    "TURN_RATE",
    "BlendSettings",
    "CapturedTerrain",
    "FootTrack",
    "FrameData",
    "FrameFeatures",
    "GraphFileError",
    "GraphOptions",
    "MotionGraph",
    "Synthesis",
    "build_graph",
    "cached_graph",
    "captured_terrain",
    "case4",
    "compose",
    "follow_turns",
    "foot_slide",
    "foot_track",
    "frame_features",
    "graph_cache_dir",
    "graph_sigma",
    "hermite",
    "jerk",
    "joint_jumps",
    "knee_hinge",
    "largest_scc",
    "leg_chain",
    "load_graph",
    "longest_off_floor",
    "lowest_foot",
    "off_floor_seconds",
    "pair_distances",
    "quality_summary",
    "random_step",
    "random_walk",
    "root_scales",
    "rotate_y",
    "save_graph",
    "segment_maps",
    "select_clips",
    "sole_speed",
    "solve_leg",
    "synthesize",
    "terrain_options",
    "weighted_joints",
    "yaw_of",
    "yaw_q",
]
