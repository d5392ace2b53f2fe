"""Offline half of the vision interface (Lee et al. §5.3): the silhouette bank."""

from ._bank import (
    Bank,
    BankFileError,
    StaleBankError,
    bank_cache_dir,
    build_bank,
    ensure_bank,
    load_bank,
)
from ._body import BodyShape, CapsuleBody, capsule_body, capsule_segments
from ._camera import CameraRing
from ._descriptor import (
    DEFAULT_DESCRIPTOR,
    DESCRIPTORS,
    HU_SCALE,
    POSE_JOINTS,
    SHIN_RATIO,
    THIGH_RATIO,
    Descriptor,
    GridDescriptor,
    HuDescriptor,
    PoseDescriptor,
    get_descriptor,
    grid_cells,
    hu_log,
)
from ._features import feature_size, silhouette_features
from ._gl import GLRenderer
from ._raster import rasterize
from ._render import (
    draw_ground_shadow,
    gl_features,
    gl_silhouettes,
    motion_features,
    motion_silhouettes,
    render_motion_video,
    shaded_frames,
    write_mp4,
)
from ._settings import BANK_VERSION, METRIC_DIMS, BankSettings, robust_settings

__all__ = [
    "BANK_VERSION",
    "DEFAULT_DESCRIPTOR",
    "DESCRIPTORS",
    "HU_SCALE",
    "METRIC_DIMS",
    "POSE_JOINTS",
    "SHIN_RATIO",
    "THIGH_RATIO",
    "Bank",
    "BankFileError",
    "BankSettings",
    "BodyShape",
    "CameraRing",
    "CapsuleBody",
    "Descriptor",
    "GLRenderer",
    "GridDescriptor",
    "HuDescriptor",
    "PoseDescriptor",
    "StaleBankError",
    "bank_cache_dir",
    "build_bank",
    "capsule_body",
    "capsule_segments",
    "draw_ground_shadow",
    "ensure_bank",
    "feature_size",
    "get_descriptor",
    "gl_features",
    "gl_silhouettes",
    "grid_cells",
    "hu_log",
    "load_bank",
    "motion_features",
    "motion_silhouettes",
    "rasterize",
    "render_motion_video",
    "robust_settings",
    "shaded_frames",
    "silhouette_features",
    "write_mp4",
]
