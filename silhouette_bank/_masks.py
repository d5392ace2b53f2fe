"""What the silhouette descriptors (``_descriptor``) measure of binary masks: numba kernels
for the raw moments and rows a silhouette spans (``mask_extents``) and how far it reaches
left and right in row bands (``outline_extents``), and the grid cells it fills
(``grid_cells``, by OpenCV's area resampling)."""

from __future__ import annotations

import cv2
import numba
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "as_binary",
    "binary_outline",
    "cells_unclipped",
    "crop_rows",
    "grid_cells",
    "grid_width",
    "mask_extents",
    "outline_extents",
]

FloatArray = NDArray[np.float64]


@numba.njit(cache=True, parallel=True)
def _extents_kernel(masks: NDArray[np.uint8], out: NDArray[np.int64]) -> None:
    n, h, w = masks.shape
    for k in numba.prange(n):
        m00 = 0
        m10 = 0
        m01 = 0
        top = -1
        bottom = -1
        for y in range(h):
            row = 0
            xs = 0
            for x in range(w):
                v = int(masks[k, y, x] != 0)
                row += v
                xs += v * x
            if row > 0:
                if top < 0:
                    top = y
                bottom = y + 1
                m00 += row
                m10 += xs
                m01 += row * y
        out[k, 0] = m00
        out[k, 1] = m10
        out[k, 2] = m01
        out[k, 3] = top
        out[k, 4] = bottom


def mask_extents(masks: NDArray[np.generic]) -> NDArray[np.int64]:
    """Per mask of ``masks`` ``(N, H, W)`` (nonzero = silhouette): ``(N, 5)`` integers
    ``m00, m10, m01, top, bottom``, the raw image moments of order 0 and 1 (as
    ``cv2.moments(mask, binaryImage=True)`` has them, exactly: they are sums of pixel
    indices) and the rows ``[top, bottom)`` the silhouette spans (-1, -1 when empty)."""
    m = np.asarray(masks)
    if m.ndim != 3:
        raise ValueError(f"masks must be (N, H, W), got shape {m.shape}")
    if m.dtype != np.uint8:
        m = (m != 0).view(np.uint8)
    out = np.empty((m.shape[0], 5), dtype=np.int64)
    _extents_kernel(np.ascontiguousarray(m), out)
    return out


def as_binary(mask: NDArray[np.generic], ndim: int = 2) -> NDArray[np.uint8]:
    m = np.ascontiguousarray(mask)
    if m.ndim != ndim:
        what = "2-D" if ndim == 2 else "(N, H, W)"
        raise ValueError(f"mask must be {what}, got shape {m.shape}")
    if m.dtype != np.uint8 or m.max(initial=0) > 1:
        m = (m != 0).astype(np.uint8)
    return m


@numba.njit(cache=True, parallel=True)
def _outline_kernel(
    masks: NDArray[np.uint8],
    which: NDArray[np.int64],
    tops: NDArray[np.int64],
    bottoms: NDArray[np.int64],
    cxs: NDArray[np.float64],
    bands: int,
    out: NDArray[np.float64],
) -> None:
    for k in numba.prange(which.size):
        i = which[k]
        top, h, cx = tops[k], bottoms[k] - tops[k], cxs[k]
        w = masks.shape[2]
        for b in range(bands):
            a = (b * h) // bands
            e = max(((b + 1) * h) // bands, a + 1)
            lo, hi = w, -1
            for y in range(top + a, top + e):
                for x in range(lo):  # the leftmost pixel further left than seen so far
                    if masks[i, y, x]:
                        lo = x
                        break
                for x in range(w - 1, hi, -1):
                    if masks[i, y, x]:
                        hi = x
                        break
            if hi >= 0:
                out[k, 2 * b] = (lo - 0.5 - cx) / h
                out[k, 2 * b + 1] = (hi + 0.5 - cx) / h
            else:
                out[k, 2 * b] = 0.0
                out[k, 2 * b + 1] = 0.0


def outline_extents(
    masks: NDArray[np.generic], bands: int, extents: NDArray[np.int64] | None = None
) -> FloatArray:
    """The outline of each of ``masks`` ``(N, H, W)``: ``(N, 2 * bands)``, for each of
    ``bands`` row bands over the silhouette's height (band ``b`` spans rows ``b h // bands``
    to ``(b + 1) h // bands``, at least one) the left edge of its leftmost pixel and the
    right edge of its rightmost, relative to the centroid's column, in silhouette heights
    (0 and 0 for an empty band); NaN for an empty mask. ``extents``: the masks'
    ``mask_extents`` if the caller has them."""
    m = as_binary(masks, ndim=3)
    return binary_outline(m, mask_extents(m) if extents is None else extents, bands)


def binary_outline(m: NDArray[np.uint8], ext: NDArray[np.int64], bands: int) -> FloatArray:
    """``outline_extents`` of binary masks ``m`` (``as_binary``'s, C-ordered) whose
    ``mask_extents`` are ``ext``: for a caller that has both, so that the masks are not
    scanned again."""
    out = np.full((m.shape[0], 2 * bands), np.nan)
    seen = np.flatnonzero(ext[:, 0] > 0)
    if seen.size:
        got = np.empty((seen.size, 2 * bands))
        cx = ext[seen, 1] / ext[seen, 0]
        _outline_kernel(m, seen.astype(np.int64), ext[seen, 3], ext[seen, 4], cx, bands, got)
        out[seen] = got
    return out


def grid_cells(
    mask: NDArray[np.uint8], top: int, bottom: int, cx: float, rows: int, cols: int
) -> FloatArray:
    """Fraction filled of each of ``rows x cols`` cells ``(rows * cols,)``, row by row
    from the top: the grid spans image rows ``[top, bottom)`` and ``h * cols / rows``
    columns (rounded) centred on ``cx`` (pixel-index coordinates, as the centroid of
    ``cv2.moments``; sampled to a fraction of a pixel, so the mirrored image gives the
    mirrored cells); cells beyond the image are empty."""
    return _cells(
        crop_rows(mask, top, bottom, cx, grid_width(bottom - top, rows, cols)), rows, cols
    )


def grid_width(h: int, rows: int, cols: int) -> int:
    """The width in pixels of a grid of ``rows x cols`` square cells ``h`` pixels high."""
    return max(1, round(h * cols / rows))


def crop_rows(
    mask: NDArray[np.uint8], top: int, bottom: int, cx: float, width: int
) -> NDArray[np.float32]:
    """Image rows ``[top, bottom)`` and ``width`` columns centred on ``cx``, as float32."""
    shift = np.array([[1.0, 0.0, cx - (width - 1) / 2.0], [0.0, 1.0, float(top)]])
    crop = cv2.warpAffine(
        np.asarray(mask, dtype=np.float32),
        shift,
        (width, bottom - top),
        flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=0.0,
    )
    return np.asarray(crop, dtype=np.float32)


def _cells(crop: NDArray[np.float32], rows: int, cols: int) -> FloatArray:
    # the area average of values in [0, 1], less float32's rounding (1.0000002 seen)
    return np.clip(cells_unclipped(crop, rows, cols).astype(np.float64), 0.0, 1.0)


def cells_unclipped(crop: NDArray[np.float32], rows: int, cols: int) -> NDArray[np.float32]:
    """The mean of ``crop`` over each of ``rows x cols`` cells, row by row (float32)."""
    cells = cv2.resize(crop, (cols, rows), interpolation=cv2.INTER_AREA)
    return np.asarray(cells, dtype=np.float32).ravel()
