"""The silhouette features, one definition for the bank and for the live camera.

Two descriptors of the silhouette's shape, chosen by ``descriptor``; either is followed by
the silhouette centre (the last two numbers). ``silhouette_features(mask, origin,
"hu") -> (9,)`` (Lee et al.'s kind of feature; this function's default):

- ``[0:7]`` the 7 Hu moments of the binary mask (``cv2.moments(binaryImage=True)``),
  log-scaled so that their magnitudes are comparable: ``sign(h) log10(1 + |h| / s_k)``.
  For the first four (always clearly positive) ``s = 1e-7`` and this is
  ``log10(h) + 7``. The last three change sign on real silhouettes (h7 about half of the
  time), and the usual ``-sign(h) log10|h|`` jumps by twice its size when a tiny value
  changes sign (we measured jumps of 14 between two camera distances); here ``s`` is a
  tenth of the moment's median size on our renders (5e-6, 2e-4, 1.5e-6), so values
  smaller than that pass through 0 continuously. Hu moments do not change when the
  silhouette moves or scales in the image.
- ``[-2:]`` the silhouette centre (centroid) minus ``origin``, divided by the silhouette
  height (rows spanned by the mask), x to the right and y **up**. In units of the body's
  own height, the same motion gives the same numbers whatever the camera distance.

What the centre is relative to: in the bank, ``origin`` is the projection of the avatar's
root (pelvis), so the centre describes the pose (a crouch lowers it, a lean shifts it)
and the root's own image motion is stored beside it (``Bank.root_motion``); on the live
side there is no root, so ``origin`` is the image corner and the matcher compares how the
centre moves within a window. Centre displacement = root displacement + change of the
centre relative to the root, so both sides yield the same trajectory.

``descriptor="grid"`` -> ``(GRID_ROWS * GRID_COLS + 2,)``: instead of the Hu moments, how
much of each cell of a grid the silhouette fills. The grid spans the silhouette's rows
(its height ``h``) and ``h * GRID_COLS / GRID_ROWS`` around the centre's column (square
cells), so it too ignores where the silhouette is and how large; cells beyond the image
count as empty. Unlike Hu moments it keeps *where* limbs are, and a blob at the feet
changes the bottom cells only, not every number. It is the bank's default
(``DEFAULT_DESCRIPTOR``): it matched performers of other builds and viewpoints better
(``benchmarks/bench_accuracy.py --descriptor``; issue 9).
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "DEFAULT_DESCRIPTOR",
    "DESCRIPTORS",
    "GRID_COLS",
    "GRID_ROWS",
    "HU_SCALE",
    "N_FEATURES",
    "feature_size",
    "grid_cells",
    "hu_log",
    "silhouette_features",
]

#: features of the default descriptor ("hu"): 7 Hu moments and the centre
N_FEATURES = 9
DESCRIPTORS = ("hu", "grid")
#: the bank's default: the grid, which the accuracy benchmark found the better of the two
#: (``benchmarks/bench_accuracy.py --descriptor``; README)
DEFAULT_DESCRIPTOR = "grid"
GRID_ROWS = 8
GRID_COLS = 4
FloatArray = NDArray[np.float64]


def feature_size(descriptor: str = "hu") -> int:
    """Length of a feature vector of ``descriptor`` (shape numbers, then the centre)."""
    if descriptor == "hu":
        return N_FEATURES
    if descriptor == "grid":
        return GRID_ROWS * GRID_COLS + 2
    raise ValueError(f"descriptor must be one of {', '.join(DESCRIPTORS)}, not {descriptor!r}")


#: s_k of the log scale, per Hu moment (see the module docstring)
HU_SCALE = np.array([1e-7, 1e-7, 1e-7, 1e-7, 5e-6, 2e-4, 1.5e-6])


def hu_log(hu: FloatArray) -> FloatArray:
    """``sign(h) log10(1 + |h| / s_k)`` of Hu moments ``(..., 7)``: a log scale that is
    continuous through 0."""
    hu = np.asarray(hu, dtype=np.float64)
    return np.sign(hu) * np.log10(1.0 + np.abs(hu) / HU_SCALE)


def grid_cells(
    mask: NDArray[np.uint8], top: int, bottom: int, cx: float, rows: int, cols: int
) -> FloatArray:
    """Fraction filled of each of ``rows x cols`` square cells ``(rows * cols,)``, row by
    row from the top: the grid spans image rows ``[top, bottom)`` and is centred on
    column ``cx``; cells beyond the image are empty."""
    h = bottom - top
    width = h * cols / rows
    x0 = round(cx - width / 2)
    x1 = x0 + max(1, round(width))
    w = mask.shape[1]
    crop = np.zeros((h, x1 - x0), dtype=np.float32)
    a, b = max(x0, 0), min(x1, w)
    if b > a:
        crop[:, a - x0 : b - x0] = mask[top:bottom, a:b]
    cells = cv2.resize(crop, (cols, rows), interpolation=cv2.INTER_AREA)
    # the area average of 0s and 1s, less float32's rounding (1.0000002 seen)
    return np.clip(np.asarray(cells, dtype=np.float64).ravel(), 0.0, 1.0)


def silhouette_features(
    mask: NDArray[np.generic], origin: tuple[float, float] = (0.0, 0.0), descriptor: str = "hu"
) -> FloatArray:
    """Features ``(feature_size(descriptor),)`` of a binary mask ``(H, W)`` (nonzero =
    silhouette); all NaN when the mask is empty. ``origin`` is in pixels (x right, y down,
    as image coordinates)."""
    size = feature_size(descriptor)
    m = np.ascontiguousarray(mask)
    if m.ndim != 2:
        raise ValueError(f"mask must be 2-D, got shape {m.shape}")
    if m.dtype != np.uint8 or m.max(initial=0) > 1:
        m = (m != 0).astype(np.uint8)
    mom = cv2.moments(m, binaryImage=True)
    if mom["m00"] <= 0:
        return np.full(size, np.nan)
    out = np.empty(size)
    rows = np.flatnonzero(m.any(axis=1))
    height = float(rows[-1] - rows[0] + 1)
    cx = mom["m10"] / mom["m00"]
    cy = mom["m01"] / mom["m00"]
    if descriptor == "hu":
        out[:7] = hu_log(np.asarray(cv2.HuMoments(mom), dtype=np.float64).ravel())
    else:
        out[:-2] = grid_cells(m, int(rows[0]), int(rows[-1]) + 1, cx, GRID_ROWS, GRID_COLS)
    out[-2] = (cx - origin[0]) / height
    out[-1] = -(cy - origin[1]) / height
    return out
