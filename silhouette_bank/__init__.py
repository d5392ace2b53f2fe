"""Offline half of the vision interface (Lee et al. §5.3): the silhouette bank."""

from ._bank import (
    BANK_VERSION,
    Bank,
    BankFileError,
    BankSettings,
    StaleBankError,
    bank_cache_dir,
    build_bank,
    ensure_bank,
    load_bank,
    robust_settings,
)
from ._body import BodyShape, CapsuleBody, capsule_body, capsule_segments
from ._camera import CameraRing
from ._features import (
    DEFAULT_DESCRIPTOR,
    DESCRIPTORS,
    HU_SCALE,
    N_FEATURES,
    feature_size,
    hu_log,
    silhouette_features,
)
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

__all__ = [
    "BANK_VERSION",
    "DEFAULT_DESCRIPTOR",
    "DESCRIPTORS",
    "HU_SCALE",
    "N_FEATURES",
    "Bank",
    "BankFileError",
    "BankSettings",
    "BodyShape",
    "CameraRing",
    "CapsuleBody",
    "StaleBankError",
    "bank_cache_dir",
    "build_bank",
    "capsule_body",
    "capsule_segments",
    "draw_ground_shadow",
    "ensure_bank",
    "feature_size",
    "gl_features",
    "gl_silhouettes",
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
