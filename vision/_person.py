"""Person segmentation for footage without a background plate (issue 9).

A background subtractor needs a few frames of the empty scene; prerecorded footage
rarely has them (the person is in view from the first frame and gets absorbed into the
background). MediaPipe's legacy person segmenters ship their models inside the wheel,
so nothing is downloaded at run time:

- ``selfie``: the selfie segmentation model (general variant), a few milliseconds per
  640x480 frame on one core;
- ``pose``: the pose landmarker with segmentation, slower, sometimes tighter on limbs.

MediaPipe is optional (``pip install --no-deps mediapipe==0.10.14`` and its small
dependencies: see the README): its own wheel asks for the non-headless OpenCV and an
older protobuf, so it is installed without its dependency list, and the headless OpenCV
the project needs stays the one installed.

The probability map is thresholded and cleaned like a subtractor's mask
(``clean_mask``: the largest blob, holes filled).

A frame larger than ``MAX_SIDE`` pixels on its longest side is scaled down first
(``cv2.INTER_AREA``): the models look at 256x256 crops whatever the frame, but converting,
segmenting at and cleaning the frame's own size cost a 720x1280 frame about 6 ms of the
loop's 36. The landmarks are image fractions, so they mean the same; the mask is cleaned at the
model's size and scaled back to the frame's (nearest pixel): on ``bench_real_video``
every decision is the same as at the frame's own size, and the loop faster.

The pose model smooths its mask from frame to frame and, given a frame of another size
than the last (a camera reconfigured, files played one after another), fails on that
frame and every later one. A change of size starts the model again, with a warning:
its tracking begins afresh, nothing else is lost.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
import warnings
from collections.abc import Iterator
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from ._segment import Segmenter, clean_mask_others

__all__ = [
    "INSTALL",
    "PERSON_METHODS",
    "PersonSegmenter",
    "make_segmenter",
    "person_segmentation_available",
    "resolve_segmentation",
]

log = logging.getLogger(__name__)

PERSON_METHODS = ("selfie", "pose")

#: the least share of the frame a person the pose model cannot read must fill
#: (``PersonSegmenter.unposed``)
UNPOSED_AREA = 0.01

INSTALL = (
    "pip install --no-deps mediapipe==0.10.14 && "
    "pip install absl-py attrs flatbuffers 'protobuf>=4.25.3,<5' matplotlib"
)


@contextlib.contextmanager
def quiet_native_stderr() -> Iterator[None]:
    """Send what native code writes to the process's stderr (file descriptor 2) to
    /dev/null meanwhile: MediaPipe's TFLite and glog lines ("Created TensorFlow Lite
    XNNPACK delegate", "Feedback manager requires ...") that no Python setting
    silences. Python's own errors still reach the user: they are raised, and printed
    after this returns."""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):  # no descriptor 2 (an embedding host): nothing to do
        yield
        return
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
            try:
                yield
            finally:
                os.dup2(saved, 2)
    finally:
        os.close(saved)


def _mediapipe() -> Any:
    # glog: warnings and worse only (MediaPipe logs every graph start at INFO)
    os.environ.setdefault("GLOG_minloglevel", "2")
    try:
        import mediapipe as mp
    except ImportError as exc:
        raise ImportError(
            f"person segmentation needs MediaPipe 0.10.14 ({exc}); install it with: {INSTALL}"
        ) from None
    return mp


def person_segmentation_available() -> bool:
    """Whether MediaPipe can be imported here."""
    try:
        _mediapipe()
    except ImportError:
        return False
    return True


#: the longest side (pixels) of the frame the person models are given
MAX_SIDE = 640


class PersonSegmenter:
    """A learned person segmenter with the ``Segmenter`` interface: ``apply(image)``
    gives the cleaned mask, or ``None`` when nobody (big enough) is in view. Nothing is
    learned first (``learning`` is always False)."""

    learning = False

    def __init__(
        self,
        method: str = "selfie",
        threshold: float = 0.5,
        min_area: float = 0.003,
        max_side: int | None = MAX_SIDE,
        masks: bool = True,
    ):
        if method not in PERSON_METHODS:
            raise ValueError(f"method must be one of {', '.join(PERSON_METHODS)}, not {method!r}")
        if not 0.0 < threshold < 1.0:
            raise ValueError("threshold must lie in (0, 1)")
        if not masks and method != "pose":
            raise ValueError(f"only the pose model can go without masks, not {method!r}")
        if max_side is not None and max_side < 64:
            raise ValueError(
                f"max_side must be at least 64 pixels (None: never scaled), not {max_side}"
            )
        #: frames longer than this (pixels) are scaled down before the model (``None``:
        #: never)
        self.max_side = max_side
        mp = _mediapipe()
        #: whether the model makes person masks (``apply``); without them the pose model
        #: gives the same landmarks (``landmarks_of``) in about a tenth less time
        self.masks = masks
        self.method = method
        self.threshold = threshold
        self.min_area = min_area
        #: the pose model's 33 landmarks ``(33, 3)`` (x, y as image fractions,
        #: visibility) of the last frame, ``None`` when nobody was found (pose only)
        self.landmarks: NDArray[np.float64] | None = None
        #: the size ``(w, h)`` the model was last given: the pose model's tracking (its
        #: segmentation smoothing) fails for good on a frame of another size, so a
        #: change of size starts it afresh (``restarts`` counts them)
        self._size: tuple[int, int] | None = None
        self.restarts = 0
        #: blobs of the last mask at least ``RIVAL`` times the kept one's area (the
        #: selfie model's other people; the pose model follows one person)
        self.others = 0
        #: the last mask is of a person in whom the pose model found no body (pose
        #: only): the pose model's detector looks for a face and shoulders, so a
        #: performer cut at the waist by the frame's top is nobody to it; the selfie
        #: model, asked on those frames only, still finds them, and the loop then says
        #: that a person it cannot read is there rather than that nobody is (and matches
        #: the mask, where it can). Legs alone neither model finds
        self.unposed = False
        self._finder: PersonSegmenter | None = None
        self._model = self._open(mp)

    def _open(self, mp: Any) -> Any:
        """A new model (its graph started quietly on the first frames)."""
        self._quiet_calls = 2  # the first frames start the graph and the TFLite delegate
        with quiet_native_stderr():
            if self.method == "selfie":
                return mp.solutions.selfie_segmentation.SelfieSegmentation(model_selection=0)
            return mp.solutions.pose.Pose(
                static_image_mode=False, model_complexity=1, enable_segmentation=self.masks
            )

    def probability(self, image: NDArray[np.uint8]) -> NDArray[np.float32] | None:
        """The model's person probability per pixel ``(H, W)``, or ``None`` (the pose
        model finds no person)."""
        self._need_masks()
        prob = self._model_probability(image)
        if prob is None or prob.shape == image.shape[:2]:
            return prob
        size = (image.shape[1], image.shape[0])
        return np.asarray(cv2.resize(prob, size, interpolation=cv2.INTER_LINEAR), np.float32)

    def _model_probability(self, image: NDArray[np.uint8]) -> NDArray[np.float32] | None:
        """The model's probability at the size it was given (the frame scaled down to
        ``max_side``), or ``None``; ``landmarks`` set."""
        if image.ndim != 3 or image.shape[2] != 3:
            raise ValueError(f"expected a BGR image (H, W, 3), got shape {image.shape}")
        h, w = image.shape[:2]
        if self.max_side is not None and max(h, w) > self.max_side:
            f = self.max_side / max(h, w)
            size = (max(1, round(w * f)), max(1, round(h * f)))
            image = np.asarray(cv2.resize(image, size, interpolation=cv2.INTER_AREA), np.uint8)
        size = (image.shape[1], image.shape[0])
        if self.method == "pose" and self._size is not None and size != self._size:
            log.warning(
                "the frames changed size (%dx%d to %dx%d): the pose model starts again",
                *self._size,
                *size,
            )
            self._model.close()
            self._model = self._open(_mediapipe())
            self.restarts += 1
        self._size = size
        quiet = quiet_native_stderr() if self._quiet_calls > 0 else contextlib.nullcontext()
        self._quiet_calls -= 1
        with warnings.catch_warnings(), quiet:  # MediaPipe 0.10.14 on a newer protobuf
            warnings.filterwarnings("ignore", "SymbolDatabase.GetPrototype", UserWarning)
            result = self._model.process(cv2.cvtColor(image, cv2.COLOR_BGR2RGB))
        if self.method == "pose":
            got = result.pose_landmarks
            self.landmarks = (
                None
                if got is None
                else np.array([(p.x, p.y, p.visibility) for p in got.landmark], dtype=np.float64)
            )
        prob = result.segmentation_mask
        return None if prob is None else np.asarray(prob, dtype=np.float32)

    def _need_masks(self) -> None:
        """Refuse to make a mask with a model made without them (its ``None`` would read
        as nobody found)."""
        if not self.masks:
            raise ValueError("this person model was made without masks (masks=False)")

    def apply(self, image: NDArray[np.uint8]) -> NDArray[np.bool_] | None:
        self._need_masks()
        prob = self._model_probability(image)
        self.unposed = False
        if prob is None and self.method == "pose":
            return self._find_unposed(image)
        if prob is None:
            self.others = 0
            return None
        mask, self.others = clean_mask_others(prob > self.threshold, self.min_area)
        if mask is None or mask.shape == image.shape[:2]:
            return mask
        size = (image.shape[1], image.shape[0])
        return cv2.resize(mask.astype(np.uint8), size, interpolation=cv2.INTER_NEAREST) > 0

    def landmarks_of(self, image: NDArray[np.uint8]) -> NDArray[np.float64] | None:
        """The pose model's 33 landmarks ``(33, 3)`` of ``image`` (``landmarks``), or
        ``None``: the pose model alone, no mask made and no other model asked."""
        if self.method != "pose":
            raise ValueError(f"landmarks come from the pose model, not {self.method!r}")
        self._model_probability(image)
        return self.landmarks

    def _find_unposed(self, image: NDArray[np.uint8]) -> NDArray[np.bool_] | None:
        """The selfie model's mask of a frame the pose model found nobody in (``None``
        when it finds nobody either); a person must fill ``UNPOSED_AREA`` of the frame,
        so that a scrap the selfie model takes for one in an empty room is not."""
        if self._finder is None:
            self._finder = PersonSegmenter("selfie", self.threshold, UNPOSED_AREA, self.max_side)
        mask = self._finder.apply(image)
        self.others = self._finder.others if mask is not None else 0
        self.unposed = mask is not None
        return mask

    def close(self) -> None:
        self._model.close()
        if self._finder is not None:
            self._finder.close()


def resolve_segmentation(method: str, live: bool, landmarks: bool = False) -> str:
    """``"auto"`` made concrete. With ``landmarks`` (the pose descriptor) the pose
    model, which gives them. Otherwise a camera learns a plate (``mog2``: the performer
    steps out of view first); footage has no plate, so a person segmenter (``pose``,
    which gave far better masks than ``selfie`` on the shared real clips) when MediaPipe
    is installed, else ``mog2`` with a warning on stderr."""
    if method != "auto":
        if landmarks and method != "pose":
            raise ValueError(
                f"the pose descriptor needs the pose model's landmarks, not {method!r} "
                "segmentation (use --segmentation pose or auto)"
            )
        return method
    if landmarks:
        _mediapipe()  # a clear error naming the install line
        return "pose"
    if live:
        return "mog2"
    if person_segmentation_available():
        return "pose"
    print(
        "warning: no person segmentation here (MediaPipe is not installed), so a "
        "background subtractor learns from the first frames; a person already in view "
        f"fades into the background. Install it with: {INSTALL}",
        file=sys.stderr,
    )
    return "mog2"


def make_segmenter(method: str, learn_frames: int = 30) -> Any:
    """A segmenter by name: a person segmenter (``PERSON_METHODS``) or a background
    subtractor (``METHODS``)."""
    if method in PERSON_METHODS:
        return PersonSegmenter(method)
    return Segmenter(method, learn_frames)
