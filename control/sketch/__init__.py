"""The sketch interface (Lee et al. §5.2): follow a path drawn on the ground."""

from ._draw import draw_top_down, environment_mesh
from ._files import Environment, SketchFileError, read_environment, read_sketch
from ._ground import SketchSettings, path_deviation
from ._track import SketchTracker

__all__ = [
    "Environment",
    "SketchFileError",
    "SketchSettings",
    "SketchTracker",
    "draw_top_down",
    "environment_mesh",
    "path_deviation",
    "read_environment",
    "read_sketch",
]
