"""What each frame says of the performer, one of ``Performance``'s collaborators: the
performer's features from a source's landmarks, its masks, or its pictures through a
person segmenter (made at the first picture, as ``PerformSettings.segmentation`` asks),
and why a frame has none."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from silhouette_bank import Descriptor, silhouette_features

from ._fallback import SilhouetteFallback
from ._landmarks import PoseReader
from ._person import make_segmenter, resolve_segmentation
from ._segment import clean_mask_others
from ._settings import PerformSettings
from ._sources import Frame, Source
from ._voice import PoseVoice

__all__ = ["HOLD_S", "MAX_COVER", "NO_PICTURE", "UNPOSED", "FrameReader"]

#: a silhouette mask covering more of the frame than this is no performer (a white
#: frame, the lights going on under a background subtractor): treated as no silhouette
MAX_COVER = 0.6
#: why a frame has no pose when the pose model found nobody and a person is there all
#: the same (``PersonSegmenter.unposed``: only part of a body in view, as a rule)
UNPOSED = "a person in view, no body found in them"
#: a source with no new picture for a moment (a camera page whose frames come later than
#: the loop waits for them, on a loaded machine; a camera reconnecting) leaves the
#: performer as last seen for up to this many seconds of media time: the picture is
#: late, the performer has not gone. Longer, and the frame has no features
HOLD_S = 1.0
#: why a frame has no features when its source has given no picture for over ``HOLD_S``
NO_PICTURE = "no picture"


class FrameReader:
    """The performer's features of each frame of ``source`` (``read``) as the matcher's
    descriptor ``desc`` has them: ``latest`` the last frame's (NaN where it has none,
    ``why_blank`` says why), ``mask`` its cleaned mask, ``picture`` the colour frame and
    the pose model's landmarks, ``others`` the other people in view beside the one
    followed. With the pose descriptor ``pose`` reads the landmarks (which limbs are
    hidden, whether the body is upright), and the silhouette ``fallback``, if any, is
    shown each frame's mask; with a silhouette descriptor the landmarks' ``voice``, if
    any, is."""

    def __init__(
        self,
        source: Source,
        settings: PerformSettings,
        desc: Descriptor,
        fallback: SilhouetteFallback | None = None,
        voice: PoseVoice | None = None,
    ) -> None:
        self.source, self.settings, self.desc, self.fallback = source, settings, desc, fallback
        self.voice = voice
        self.landmarks = desc.kind == "pose"
        self.pose = PoseReader() if self.landmarks else None
        self.segmenter: Any = None
        self.why_blank = ""  # why the latest frame has no features
        #: other people in view in the latest frame's mask, beside the one followed (the
        #: largest blob: ``clean_mask_others``); the decisions' log says so
        self.others = 0
        self.blank = np.full(desc.size, np.nan)  # a frame without a silhouette
        self.latest = self.blank
        self.mask: NDArray[np.bool_] | None = None
        self.picture: tuple[Any, Any] = (None, None)  # the latest colour frame, landmarks
        self._pictured: float | None = None  # media time of the last frame with a picture

    def read(self, frame: Frame) -> NDArray[np.bool_] | None:
        """The performer's features of ``frame`` into ``latest`` (NaN, and ``why_blank``
        says why, when there are none); returns its cleaned mask. A frame without a
        picture (nor a problem said) keeps the last one's for up to ``HOLD_S``."""
        if frame.image is None and frame.mask is None and frame.landmarks is None:
            return self._without_picture(frame)
        self._pictured = frame.t
        if frame.landmarks is not None:  # a source that gives landmarks, not pictures
            self._read_landmarks(frame)
            return None
        mask, others, problem = self._mask_of(frame)
        self.others = others if mask is not None else 0
        if self.pose is not None:
            lm = getattr(self.segmenter, "landmarks", None) if frame.image is not None else None
            h_px, w_px = frame.image.shape[:2] if frame.image is not None else (1, 1)
            self.latest = self.pose.read(lm, (w_px, h_px))
            self.why_blank = self.pose.why
            if lm is None and getattr(self.segmenter, "unposed", False):
                self.why_blank = UNPOSED
            if self.fallback is not None:
                self.fallback.see(mask, self.pose.limbs_hidden)
        elif mask is not None:
            self.latest = silhouette_features(mask, descriptor=self.desc)
        else:
            self.latest, self.why_blank = self.blank, problem or "no silhouette"
        if self.voice is not None:
            self.voice.see(mask)
        self.mask = mask
        self.picture = (frame.image, getattr(self.segmenter, "landmarks", None))
        return mask

    def _without_picture(self, frame: Frame) -> NDArray[np.bool_] | None:
        """A frame with no picture: the performer as last seen, while the last picture
        is at most ``HOLD_S`` old and no problem is said; else no features, said why."""
        late = None if self._pictured is None else frame.t - self._pictured
        if not frame.problem and late is not None and late <= HOLD_S:
            return self.mask
        self.latest, self.mask, self.picture, self.others = self.blank, None, (None, None), 0
        if self.pose is not None:  # (no hidden limbs or upright body left from before)
            self.pose.read(None, (1, 1))
        self.why_blank = frame.problem or (
            NO_PICTURE if late is None else f"{NO_PICTURE} (none for {late:.1f} s)"
        )
        if self.fallback is not None:
            self.fallback.see(None, 1.0)
        if self.voice is not None:
            self.voice.see(None)
        return None

    def _read_landmarks(self, frame: Frame) -> None:
        """The features of a source that gives landmarks (and perhaps a mask beside)."""
        if self.pose is None:
            raise ValueError(
                f"{self.source.name}: this source gives body landmarks, and only the "
                "pose descriptor reads them (use --descriptor pose)"
            )
        self.latest = self.pose.read(frame.landmarks, (1, 1))
        self.why_blank, self.mask = self.pose.why, None
        if self.fallback is not None:  # the person's mask, where the source gives one
            # too, cleaned as a silhouette source's is
            m = None if frame.mask is None else clean_mask_others(frame.mask)[0]
            self.fallback.see(m, self.pose.limbs_hidden)

    def _mask_of(self, frame: Frame) -> tuple[NDArray[np.bool_] | None, int, str]:
        """The performer's cleaned mask in ``frame`` (a source's mask, or its picture
        through the segmenter, made at the first), the other people beside them, and
        the problem that left it without one."""
        mask: NDArray[np.bool_] | None
        if frame.mask is not None:
            if self.landmarks:
                raise ValueError(
                    f"{self.source.name}: the pose descriptor needs "
                    "colour frames, and this source gives silhouettes (use a silhouette "
                    "descriptor: --descriptor outline)"
                )
            mask, others = clean_mask_others(frame.mask)
        else:
            if self.segmenter is None:
                method = resolve_segmentation(
                    self.settings.segmentation,
                    bool(getattr(self.source, "live", False)),  # a camera
                    self.landmarks,
                )
                self.segmenter = make_segmenter(method, self.settings.learn_frames)
            mask = self.segmenter.apply(frame.image)
            others = int(getattr(self.segmenter, "others", 0))
        problem = frame.problem  # e.g. an unreadable mask file: no silhouette, said why
        cover = float(mask.mean()) if mask is not None and mask.size else 0.0
        if not self.landmarks and cover > MAX_COVER:
            # a lighting change, a white frame, a bad mask: no performer looks so
            mask, problem = None, f"the mask covers {cover:.0%} of the frame"
        return mask, others, problem
