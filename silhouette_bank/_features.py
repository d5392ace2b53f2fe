"""The silhouette features, one definition for the bank and for the live camera.

``silhouette_features(mask, origin) -> (9,)``:

- ``[0:7]`` the 7 Hu moments of the binary mask (``cv2.moments(binaryImage=True)``),
  log-scaled so that their magnitudes are comparable: ``sign(h) log10(1 + |h| / s_k)``.
  For the first four (always clearly positive) ``s = 1e-7`` and this is
  ``log10(h) + 7``. The last three change sign on real silhouettes (h7 about half of the
  time), and the usual ``-sign(h) log10|h|`` jumps by twice its size when a tiny value
  changes sign (we measured jumps of 14 between two camera distances); here ``s`` is a
  tenth of the moment's median size on our renders (5e-6, 2e-4, 1.5e-6), so values
  smaller than that pass through 0 continuously. Hu moments do not change when the
  silhouette moves or scales in the image.
- ``[7:9]`` the silhouette centre (centroid) minus ``origin``, divided by the silhouette
  height (rows spanned by the mask), x to the right and y **up**. In units of the body's
  own height, the same motion gives the same numbers whatever the camera distance.

What the centre is relative to: in the bank, ``origin`` is the projection of the avatar's
root (pelvis), so the centre describes the pose (a crouch lowers it, a lean shifts it)
and the root's own image motion is stored beside it (``Bank.root_motion``); on the live
side there is no root, so ``origin`` is the image corner and the matcher compares how the
centre moves within a window. Centre displacement = root displacement + change of the
centre relative to the root, so both sides yield the same trajectory.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = ["HU_SCALE", "N_FEATURES", "hu_log", "silhouette_features"]

N_FEATURES = 9
FloatArray = NDArray[np.float64]


#: s_k of the log scale, per Hu moment (see the module docstring)
HU_SCALE = np.array([1e-7, 1e-7, 1e-7, 1e-7, 5e-6, 2e-4, 1.5e-6])


def hu_log(hu: FloatArray) -> FloatArray:
    """``sign(h) log10(1 + |h| / s_k)`` of Hu moments ``(..., 7)``: a log scale that is
    continuous through 0."""
    hu = np.asarray(hu, dtype=np.float64)
    return np.sign(hu) * np.log10(1.0 + np.abs(hu) / HU_SCALE)


def silhouette_features(
    mask: NDArray[np.generic], origin: tuple[float, float] = (0.0, 0.0)
) -> FloatArray:
    """Features ``(9,)`` of a binary mask ``(H, W)`` (nonzero = silhouette); all NaN when
    the mask is empty. ``origin`` is in pixels (x right, y down, as image coordinates)."""
    m = np.ascontiguousarray(mask)
    if m.ndim != 2:
        raise ValueError(f"mask must be 2-D, got shape {m.shape}")
    if m.dtype != np.uint8:
        m = (m != 0).astype(np.uint8)
    mom = cv2.moments(m, binaryImage=True)
    if mom["m00"] <= 0:
        return np.full(N_FEATURES, np.nan)
    out = np.empty(N_FEATURES)
    out[:7] = hu_log(np.asarray(cv2.HuMoments(mom), dtype=np.float64).ravel())
    rows = np.flatnonzero(m.any(axis=1))
    height = float(rows[-1] - rows[0] + 1)
    cx = mom["m10"] / mom["m00"]
    cy = mom["m01"] / mom["m00"]
    out[7] = (cx - origin[0]) / height
    out[8] = -(cy - origin[1]) / height
    return out
