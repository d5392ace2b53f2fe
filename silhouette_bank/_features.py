"""The silhouette features, one definition for the bank and for the live camera.

``silhouette_features(mask, origin, descriptor)`` is the vector of a mask under one of
the silhouette descriptors (``_descriptor``: ``"hu"``, ``"grid"``, ``"multigrid"``, ``"outline"``);
the descriptor object owns the layout (shape numbers, then the centre).

What the centre is relative to: in the bank, ``origin`` is the projection of the avatar's
root (pelvis), so the centre describes the pose (a crouch lowers it, a lean shifts it)
and the root's own image motion is stored beside it (``Bank.root_motion``); on the live
side there is no root, so ``origin`` is the image corner and the matcher compares how the
centre moves within a window. Centre displacement = root displacement + change of the
centre relative to the root, so both sides yield the same trajectory.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ._descriptor import DEFAULT_DESCRIPTOR, Descriptor, get_descriptor

__all__ = ["feature_size", "silhouette_features"]

FloatArray = NDArray[np.float64]


def feature_size(descriptor: str | Descriptor = DEFAULT_DESCRIPTOR) -> int:
    """Length of a feature vector of ``descriptor`` (shape numbers, then the centre)."""
    return get_descriptor(descriptor).size


def silhouette_features(
    mask: NDArray[np.generic],
    origin: tuple[float, float] = (0.0, 0.0),
    descriptor: str | Descriptor = DEFAULT_DESCRIPTOR,
) -> FloatArray:
    """Features ``(feature_size(descriptor),)`` of a binary mask ``(H, W)`` (nonzero =
    silhouette); all NaN when the mask is empty. ``origin`` is in pixels (x right, y
    down, as image coordinates)."""
    return get_descriptor(descriptor).from_mask(mask, origin)
