"""The online half of the vision interface (Lee et al. §5.3): sources (camera, video,
mask folders), segmentation, silhouette and pose features against the bank, the matcher
and its global window index, the performance loop, the live view, the side-by-side video,
ground truth and evaluation, and synthetic recordings."""

from __future__ import annotations

from ._browser import BrowserCamera
from ._classify import (
    ActionClassifier,
    choose_action,
)
from ._decision import (
    Decision,
    Jump,
)
from ._evaluate import (
    brief_actions_per_minute,
    decision_points,
    evaluation,
    plot_evaluation,
    plot_timeline,
    switch_delays,
)
from ._index import (
    WindowIndex,
)
from ._index_store import (
    IndexFileError,
    cached_window_index,
)
from ._landmarks import (
    MEDIAPIPE_INDEX,
    PoseReader,
)
from ._library import (
    FLOOR_ABOVE,
    FLOOR_SECONDS,
    VISION_COORDS,
    floor_level,
    on_the_floor,
)
from ._live import StagePainter
from ._matcher import (
    Matcher,
)
from ._perform import (
    PerformResult,
    perform,
)
from ._person import (
    INSTALL,
    PERSON_METHODS,
    PersonSegmenter,
    person_segmentation_available,
)
from ._play import PlaySession
from ._record import (
    RECORDING_FOURCC,
    RecordSettings,
    camera_poses,
    performer_masks,
    record_clip,
)
from ._segment import (
    METHODS,
    Segmenter,
    clean_mask,
)
from ._settings import (
    FILTER_SWITCH,
    ActionSettings,
    LandingSettings,
    MatchSettings,
    PathSettings,
    PerformSettings,
)
from ._sources import (
    CameraSource,
    Frame,
    MaskFolderSource,
    Source,
    SourceError,
    VideoSource,
    looks_like_silhouettes,
    open_source,
)
from ._stage import Stage
from ._tables import (
    WindowTablesError,
    cached_shape_stats,
    cached_window_tables,
)
from ._truth import (
    LAGS,
    LabelFileError,
    Truth,
    action_runs,
    agreement,
    avatar_labels,
    library_actions,
    motion_truth,
    read_span_labels,
    truth_for,
)
from ._vendor import THREE_VERSION, vendor_three
from ._video import (
    MaskTape,
    write_video,
)
from ._vote import ActionVote
from ._windows import (
    best_window,
    per_frame_cost,
    performer_queries,
    performer_sequence,
    shape_stats,
    window_tables,
)

__all__ = [
    "FILTER_SWITCH",
    "FLOOR_ABOVE",
    "FLOOR_SECONDS",
    "INSTALL",
    "LAGS",
    "MEDIAPIPE_INDEX",
    "METHODS",
    "PERSON_METHODS",
    "RECORDING_FOURCC",
    "THREE_VERSION",
    "VISION_COORDS",
    "ActionClassifier",
    "ActionSettings",
    "ActionVote",
    "BrowserCamera",
    "CameraSource",
    "Decision",
    "Frame",
    "IndexFileError",
    "Jump",
    "LabelFileError",
    "LandingSettings",
    "MaskFolderSource",
    "MaskTape",
    "MatchSettings",
    "Matcher",
    "PathSettings",
    "PerformResult",
    "PerformSettings",
    "PersonSegmenter",
    "PlaySession",
    "PoseReader",
    "RecordSettings",
    "Segmenter",
    "Source",
    "SourceError",
    "Stage",
    "StagePainter",
    "Truth",
    "VideoSource",
    "WindowIndex",
    "WindowTablesError",
    "action_runs",
    "agreement",
    "avatar_labels",
    "best_window",
    "brief_actions_per_minute",
    "cached_shape_stats",
    "cached_window_index",
    "cached_window_tables",
    "camera_poses",
    "choose_action",
    "clean_mask",
    "decision_points",
    "evaluation",
    "floor_level",
    "library_actions",
    "looks_like_silhouettes",
    "motion_truth",
    "on_the_floor",
    "open_source",
    "per_frame_cost",
    "perform",
    "performer_masks",
    "performer_queries",
    "performer_sequence",
    "person_segmentation_available",
    "plot_evaluation",
    "plot_timeline",
    "read_span_labels",
    "record_clip",
    "shape_stats",
    "switch_delays",
    "truth_for",
    "vendor_three",
    "window_tables",
    "write_video",
]
