"""Motion data (Lee et al. §3): skeletons, clips, ASF/AMC and BVH, kinematics, contacts.

Quaternions are ``(w, x, y, z)``; Y is up; lengths are metres. See ``_quat`` for the
glossary and ``_types`` for the joint conventions.
"""

from ._amc import read_amc
from ._arrays import read_motion_arrays, write_motion_arrays
from ._asf import AsfSkeleton, read_asf
from ._bvh import UNITS, read_bvh, write_bvh
from ._clean_labels import Boundary, clean_labels, source_label_rows
from ._contacts import FEET, Contacts, contact_events, detect_contacts, foot_points
from ._digest import clips_digest
from ._embedded import (
    EMBEDDED_CLIPS,
    EMBEDDED_LIBRARY,
    EMBEDDED_MAX_BYTES,
    embed_library,
)
from ._errors import MotionFormatError
from ._fk import Pose, forward_kinematics, rest_positions
from ._library import (
    Clip,
    Library,
    LibrarySpec,
    action_keys,
    action_names,
    default_cache_dir,
    default_library_path,
    load_library,
    load_spec,
    read_labels,
)
from ._names import ROLE_ALIASES, find_role, mirror_map, role_point
from ._ops import cut, mirror, mirrored_rotations, resample, resample_positions
from ._quat import (
    FloatArray,
    euler_to_q,
    q_to_euler,
    q_to_R,
    qconj,
    qexp,
    qlog,
    qmul,
    qnormalize,
    qrot,
    slerp,
)
from ._types import Motion, Skeleton

__all__ = [
    "EMBEDDED_CLIPS",
    "EMBEDDED_LIBRARY",
    "EMBEDDED_MAX_BYTES",
    "FEET",
    "ROLE_ALIASES",
    "UNITS",
    "AsfSkeleton",
    "Boundary",
    "Clip",
    "Contacts",
    "FloatArray",
    "Library",
    "LibrarySpec",
    "Motion",
    "MotionFormatError",
    "Pose",
    "Skeleton",
    "action_keys",
    "action_names",
    "clean_labels",
    "clips_digest",
    "contact_events",
    "cut",
    "default_cache_dir",
    "default_library_path",
    "detect_contacts",
    "embed_library",
    "euler_to_q",
    "find_role",
    "foot_points",
    "forward_kinematics",
    "load_library",
    "load_spec",
    "mirror",
    "mirror_map",
    "mirrored_rotations",
    "q_to_R",
    "q_to_euler",
    "qconj",
    "qexp",
    "qlog",
    "qmul",
    "qnormalize",
    "qrot",
    "read_amc",
    "read_asf",
    "read_bvh",
    "read_labels",
    "read_motion_arrays",
    "resample",
    "resample_positions",
    "rest_positions",
    "role_point",
    "slerp",
    "source_label_rows",
    "write_bvh",
    "write_motion_arrays",
]
