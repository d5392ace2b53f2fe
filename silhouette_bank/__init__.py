"""Offline half of the vision interface (Lee et al. §5.3): the silhouette bank."""

from ._arrays import (
    RACY_NS,
    block_hashes,
    npy_file,
    open_mapped,
)
from ._bank import (
    Bank,
    BankFileError,
    StaleBankError,
    bank_cache_dir,
    build_bank,
    load_bank,
)
from ._body import (
    BodyShape,
    CapsuleBody,
    capsule_body,
    capsule_segments,
    with_proportions,
)
from ._cache import cached_bank, ensure_bank
from ._camera import CameraRing
from ._descriptor import (
    DEFAULT_DESCRIPTOR,
    DESCRIPTORS,
    POSE_JOINTS,
    Descriptor,
    GridDescriptor,
    HuDescriptor,
    OutlineDescriptor,
    PoseDescriptor,
    get_descriptor,
    outline_extents,
)
from ._features import (
    silhouette_features,
)
from ._gl import GLRenderer
from ._metric import (
    lda_directions,
    learn_metric,
)
from ._occlusion import joint_visibility
from ._pose import joint_points, pose_visibility
from ._raster import rasterize
from ._rate import render_rate
from ._render import (
    MP4_FOURCC,
    draw_ground_shadow,
    gl_features,
    gl_silhouettes,
    motion_features,
    motion_silhouettes,
    render_motion_video,
    shaded_frames,
    write_mp4,
)
from ._settings import (
    BankSettings,
    robust_settings,
)

__all__ = [
    "DEFAULT_DESCRIPTOR",
    "DESCRIPTORS",
    "MP4_FOURCC",
    "POSE_JOINTS",
    "RACY_NS",
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
    "OutlineDescriptor",
    "PoseDescriptor",
    "StaleBankError",
    "bank_cache_dir",
    "block_hashes",
    "build_bank",
    "cached_bank",
    "capsule_body",
    "capsule_segments",
    "draw_ground_shadow",
    "ensure_bank",
    "get_descriptor",
    "gl_features",
    "gl_silhouettes",
    "joint_points",
    "joint_visibility",
    "lda_directions",
    "learn_metric",
    "load_bank",
    "motion_features",
    "motion_silhouettes",
    "npy_file",
    "open_mapped",
    "outline_extents",
    "pose_visibility",
    "rasterize",
    "render_motion_video",
    "render_rate",
    "robust_settings",
    "shaded_frames",
    "silhouette_features",
    "with_proportions",
    "write_mp4",
]
