"""The sketch interface (Lee et al. §5.2): follow a path drawn on the ground."""

from ._actions import ActionPlanner
from ._blocks import BlockFit
from ._draw import draw_top_down, environment_mesh
from ._files import Environment, SketchFileError, read_environment, read_sketch
from ._ground import SketchSettings, ground_path, path_deviation, resample_polyline, start_map
from ._search import search_step
from ._track import SketchTracker

__all__ = [
    "ActionPlanner",
    "BlockFit",
    "Environment",
    "SketchFileError",
    "SketchSettings",
    "SketchTracker",
    "draw_top_down",
    "environment_mesh",
    "ground_path",
    "path_deviation",
    "read_environment",
    "read_sketch",
    "resample_polyline",
    "search_step",
    "start_map",
]
