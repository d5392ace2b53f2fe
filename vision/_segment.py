"""Foreground segmentation with OpenCV background subtractors, and mask cleanup.

The subtractor learns the background from the first ``learn_frames`` frames (the
performer should stay out of view meanwhile: the camera flow says so), then keeps it
(``adapt`` = 0): a performer who stays in one place, as in most exercises, would
otherwise fade into the background. Measured on a 640x480 composite (see
``benchmarks/bench_vision.py``): MOG2 with a frozen background reached IoU 0.78;
adapting at a rate of 0.001 dropped it to 0.31; MOG2 is the default.

Cleanup: a small opening (removes speckle), a closing (fills cracks), the largest
connected component, holes filled. Masks smaller than ``min_area`` of the
image count as "no silhouette".
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = ["METHODS", "RIVAL", "Segmenter", "clean_mask", "clean_mask_others"]

METHODS = ("mog2", "knn", "cnt", "gsoc", "lsbp", "gmg", "mog")


#: pixels: the width of the neighbourhood whose vote ``clean_mask`` takes
SMOOTH = 1.0


def clean_mask(mask: NDArray[np.generic], min_area: float = 0.003) -> NDArray[np.bool_] | None:
    """The largest blob of ``mask``, smoothed (``SMOOTH``) and with holes filled, or ``None``
    when it covers less than ``min_area`` of the image. Worked on the box around what is
    set, with a margin of zeros wider than the smoothing reaches (the same result as on
    the whole image, tested; a person fills a fraction of a camera's frame)."""
    return clean_mask_others(mask, min_area)[0]


def clean_mask_others(
    mask: NDArray[np.generic], min_area: float = 0.003
) -> tuple[NDArray[np.bool_] | None, int]:
    """``clean_mask``, and how many other blobs are at least ``RIVAL`` times the kept
    one's area (other people in view: the largest is the one followed)."""
    m: np.ndarray = (np.asarray(mask) > 0).astype(np.uint8)
    if m.ndim != 2:
        raise ValueError(f"mask must be 2-D, got shape {m.shape}")
    x, y, w, h = cv2.boundingRect(m)
    if w == 0:
        return None, 0
    r = _MARGIN
    y0, y1 = max(y - r, 0), min(y + h + r, m.shape[0])
    x0, x1 = max(x - r, 0), min(x + w + r, m.shape[1])
    out = np.zeros(m.shape, dtype=bool)
    blob, others = _largest_blob(m[y0:y1, x0:x1], min_area * m.size)
    if blob is None:
        return None, 0
    out[y0:y1, x0:x1] = blob
    return out, others


#: a blob at least this share of the largest's area counts as another person in view
RIVAL = 0.5


#: zeros around the box that ``clean_mask`` works on: more than the smoothing's kernel
#: reaches (OpenCV's radius for a sigma is 3 or 4 sigmas)
_MARGIN = 4 * math.ceil(SMOOTH) + 2


def _largest_blob(m: NDArray[np.uint8], min_pixels: float) -> tuple[NDArray[np.bool_] | None, int]:
    # a vote of each pixel's neighbourhood (a Gaussian of 1 pixel, kept where more than
    # half): ragged edges smoothed, speckle and pinholes gone, and limbs a few pixels
    # wide kept (a 3x3 opening cuts them where the edge is ragged, and a performer 90
    # pixels tall is then followed far worse)
    # (in 8 bits: as fast as the opening, five times faster than in floats); with the
    # largest blob, how many others are at least RIVAL times its area
    m = (cv2.GaussianBlur(m * 255, (0, 0), SMOOTH) > 127).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(m, connectivity=8)
    if n <= 1:
        return None, 0
    area = stats[1:, cv2.CC_STAT_AREA]
    k = 1 + int(np.argmax(area))
    if stats[k, cv2.CC_STAT_AREA] < min_pixels:
        return None, 0
    others = int(np.count_nonzero(area >= max(RIVAL * area[k - 1], min_pixels))) - 1
    blob = (labels == k).astype(np.uint8)
    # fill holes: flood the background from the border; what it cannot reach is a hole
    pad = np.pad(blob, 1)
    flood = pad.copy()
    cv2.floodFill(flood, None, (0, 0), 1)
    holes = (flood == 0)[1:-1, 1:-1]
    return (blob > 0) | holes, others


class Segmenter:
    """A background subtractor plus cleanup. ``apply`` returns the mask, or ``None`` while
    learning the background and when nothing (big enough) is in view."""

    def __init__(
        self,
        method: str = "mog2",
        learn_frames: int = 30,
        min_area: float = 0.003,
        adapt: float = 0.0,
    ) -> None:
        if method not in METHODS:
            raise ValueError(f"method must be one of {', '.join(METHODS)}, not {method!r}")
        self.method = method
        self.learn_frames = learn_frames
        self.min_area = min_area
        self.adapt = adapt
        self._sub = self._make(method)
        self._n = 0
        #: blobs of the last mask at least ``RIVAL`` times the kept one's area: other
        #: people in view (the largest is followed)
        self.others = 0

    @staticmethod
    def _make(method: str) -> cv2.BackgroundSubtractor:
        if method == "mog2":
            return cv2.createBackgroundSubtractorMOG2(
                history=500, varThreshold=16, detectShadows=True
            )
        if method == "knn":
            return cv2.createBackgroundSubtractorKNN(detectShadows=True)
        bg = cv2.bgsegm
        return {
            "cnt": lambda: bg.createBackgroundSubtractorCNT(),
            "gsoc": lambda: bg.createBackgroundSubtractorGSOC(),
            "lsbp": lambda: bg.createBackgroundSubtractorLSBP(),
            "gmg": lambda: bg.createBackgroundSubtractorGMG(),
            "mog": lambda: bg.createBackgroundSubtractorMOG(),
        }[method]()

    @property
    def learning(self) -> bool:
        return self._n < self.learn_frames

    def apply(self, image: NDArray[np.uint8]) -> NDArray[np.bool_] | None:
        rate = -1.0 if self.learning else self.adapt
        fg = self._sub.apply(image, learningRate=rate)
        self._n += 1
        if self.learning:
            return None
        mask, self.others = clean_mask_others(fg >= 200, self.min_area)  # 127: shadows
        return mask
