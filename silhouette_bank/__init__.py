"""Offline half of the vision interface (Lee et al. §5.3): the silhouette bank."""

from ._body import BodyShape, CapsuleBody, capsule_body, capsule_segments
from ._camera import CameraRing
from ._features import HU_SCALE, N_FEATURES, hu_log, silhouette_features
from ._raster import rasterize
from ._render import motion_features, motion_silhouettes

__all__ = [
    "HU_SCALE",
    "N_FEATURES",
    "BodyShape",
    "CameraRing",
    "CapsuleBody",
    "capsule_body",
    "capsule_segments",
    "hu_log",
    "motion_features",
    "motion_silhouettes",
    "rasterize",
    "silhouette_features",
]
