"""Descriptors: what one performer frame (and one bank frame and view) is reduced to.

A descriptor owns its layout, so that the bank, the matcher and DTW never slice feature
vectors themselves. Every descriptor's vector is ``(size,)``: ``n_shape`` shape numbers,
then 2 centre numbers (x right, y up, relative to an origin, in the descriptor's unit of
body size). The kinds:

- ``"hu"``: the 7 log-scaled Hu moments of the mask (Lee et al.'s kind of feature), then
  the silhouette centre in silhouette heights; each Hu number standardised by its own
  spread in the bank.
- ``"grid"``: how much of each cell of an 8x4 grid over the silhouette it fills.
- ``"multigrid"``: grids of 16x8, 8x4 and 4x2 cells over the same box, concatenated: the
  fine grid sees the limbs, the coarse ones still agree when a limb is a cell off
  (another body, another camera). Measured against the others by
  ``benchmarks/bench_recognition.py``. Grid cells, all of one kind, share one scale.
- ``"outline"`` (the default): the multigrid's cells, then how far the silhouette reaches
  left and right of its centroid in each of 16 row bands (``outline_extents``), in
  silhouette heights. The grids' box is half the silhouette's height wide, so arms held
  out to the side reach beyond it; the outline sees them (arm circles against side
  twists, which the cells confuse).
- ``"pose"``: 2D body landmarks (shoulders, elbows, wrists, hips, knees, ankles; left
  before right) relative to the mid-hip, in torso lengths (mid-shoulder to mid-hip, or
  what the legs' bones in the image say it is when the torso leans towards the camera),
  then the mid-hip as the centre. The bank projects the avatar's joints into each view; the
  live side takes MediaPipe Pose's landmarks (``vision``). Needs colour video.

Standardisation (``standardiser``): the matcher divides shape numbers by a scale taken
from the bank, such that the shape numbers together vary as much as 7 standardised
numbers do (for Hu: exactly so, each by its own spread); so ``centre_weight`` means the
same with every descriptor. A multigrid or outline bank also holds a metric learned from
the bank (``_metric``): the matcher then compares the shape numbers along its 24 (48)
directions, scaled the same way.

``mirror`` gives the vector of the mirrored image (a performer using the other side, or a
mirrored camera); ``variants``, the readings of a performer that the matcher tries.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import cv2
import numpy as np
from numpy.typing import NDArray

from ._masks import (
    as_binary,
    binary_outline,
    cells_unclipped,
    crop_rows,
    grid_cells,
    grid_width,
    mask_extents,
    outline_extents,
)

__all__ = [
    "DEFAULT_DESCRIPTOR",
    "DESCRIPTORS",
    "HU_SCALE",
    "POSE_JOINTS",
    "SHIN_RATIO",
    "THIGH_RATIO",
    "Descriptor",
    "GridDescriptor",
    "HuDescriptor",
    "OutlineDescriptor",
    "PoseDescriptor",
    "get_descriptor",
    "grid_cells",
    "hu_log",
    "mask_extents",
    "outline_extents",
]

FloatArray = NDArray[np.float64]

#: s_k of the Hu log scale, per moment (see ``hu_log``)
HU_SCALE = np.array([1e-7, 1e-7, 1e-7, 1e-7, 5e-6, 2e-4, 1.5e-6])

#: the pose descriptor's landmarks, as joint roles (``control.motion.ROLE_ALIASES``), in
#: order: each part left then right
POSE_JOINTS = (
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_wrist",
    "right_wrist",
    "left_hip",
    "right_hip",
    "left_knee",
    "right_knee",
    "left_ankle",
    "right_ankle",
)
#: where a pose vector holds the x of the left and the right shoulder, then hip (``sides``)
_SIDE_X = tuple(
    2 * POSE_JOINTS.index(j) for j in ("left_shoulder", "right_shoulder", "left_hip", "right_hip")
)

#: thigh (hip to knee) and shin (knee to ankle) in torso lengths (mid-hip to mid-shoulder):
#: 0.424, 0.461 and 0.52 m on the CMU exercise subject
THIGH_RATIO = 0.82
SHIN_RATIO = 0.89


def hu_log(hu: FloatArray) -> FloatArray:
    """``sign(h) log10(1 + |h| / s_k)`` of Hu moments ``(..., 7)``: a log scale that is
    continuous through 0.

    For the first four moments (always clearly positive) ``s = 1e-7`` and this is
    ``log10(h) + 7``. The last three change sign on real silhouettes (h7 about half of
    the time), and the usual ``-sign(h) log10|h|`` jumps by twice its size when a tiny
    value changes sign (jumps of 14 were measured between two camera distances); here
    ``s`` is a tenth of the moment's median size on our renders, so values smaller than
    that pass through 0 continuously.
    """
    hu = np.asarray(hu, dtype=np.float64)
    return np.sign(hu) * np.log10(1.0 + np.abs(hu) / HU_SCALE)


@dataclass(frozen=True)
class Descriptor:
    """The layout of one kind of feature vector: ``n_shape`` shape numbers, then the
    centre (2). Subclasses compute it."""

    name: str
    n_shape: int
    #: "silhouette" (computed from a binary mask) or "pose" (from body landmarks)
    kind: str = "silhouette"
    #: a window whose best match costs more than this per frame (the DTW cost over the
    #: square root of its length, on standardised numbers) matches nothing real: the
    #: matcher rejects it (measured by ``benchmarks/bench_recognition.py``)
    reject: float = float("inf")
    #: whether the matcher reads the performer mirrored too by default (``variants``): a
    #: silhouette cannot tell a pose from its mirror image seen from behind, so both
    #: readings are tried; a pose model names each side (``PoseDescriptor``: no)
    reads_mirrored: bool = True

    @property
    def size(self) -> int:
        """Length of a feature vector."""
        return self.n_shape + 2

    def shape(self, x: NDArray[np.floating]) -> NDArray[np.floating]:
        """The shape numbers ``(..., n_shape)`` of vectors ``(..., size)``."""
        return x[..., : self.n_shape]

    def centre(self, x: NDArray[np.floating]) -> NDArray[np.floating]:
        """The centre ``(..., 2)`` of vectors ``(..., size)``."""
        return x[..., self.n_shape :]

    def standardiser(self, rows: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Mean and scale ``(n_shape,)`` of shape numbers ``(N, n_shape)`` (finite rows):
        by default one scale for all, such that together they vary as much as 7
        standardised numbers."""
        x = np.asarray(rows, dtype=np.float64)
        if x.shape[0] == 0:
            return np.zeros(self.n_shape), np.ones(self.n_shape)
        scale = max(float(np.sqrt(x.var(axis=0).sum() / 7.0)), 1e-6)
        return x.mean(axis=0), np.full(self.n_shape, scale)

    def mirror(self, x: NDArray[np.floating]) -> NDArray[np.floating]:
        """Vectors ``(..., size)`` of the left/right mirrored image."""
        out = np.array(x, copy=True)
        out[..., self.n_shape] *= -1.0
        return out

    def variants(
        self, x: NDArray[np.floating], mirror: bool | None = None
    ) -> list[NDArray[np.floating]]:
        """The readings of a performer's vectors ``(..., size)`` to match: as seen, and
        with ``mirror`` (``None``: ``reads_mirrored``) also mirrored."""
        mirror = self.reads_mirrored if mirror is None else mirror
        return [x, self.mirror(x)] if mirror else [x]

    def from_mask(
        self, mask: NDArray[np.generic], origin: tuple[float, float] = (0.0, 0.0)
    ) -> FloatArray:
        """The vector ``(size,)`` of a binary mask ``(H, W)`` (nonzero = silhouette), all
        NaN when it is empty; ``origin`` in pixels (x right, y down). The centre is the
        silhouette's centroid minus ``origin``, over the silhouette's height, y up."""
        return self.from_masks(as_binary(mask)[None], np.asarray([origin], dtype=np.float64))[0]

    def from_masks(
        self,
        masks: NDArray[np.generic],
        origins: NDArray[np.floating] | None = None,
        extents: NDArray[np.int64] | None = None,
    ) -> FloatArray:
        """``from_mask`` of each of ``masks`` ``(N, H, W)``: ``(N, size)``; ``origins``
        ``(N, 2)`` (default 0), ``extents`` the masks' ``mask_extents`` if the caller
        has them."""
        if self.kind != "silhouette":
            raise ValueError(
                f"the {self.name!r} descriptor is computed from body landmarks, not masks"
            )
        m = as_binary(masks, ndim=3)
        n = m.shape[0]
        org = np.zeros((n, 2)) if origins is None else np.asarray(origins, dtype=np.float64)
        ext = mask_extents(m) if extents is None else extents
        out = np.full((n, self.size), np.nan)
        seen = np.flatnonzero(ext[:, 0] > 0)
        if seen.size == 0:
            return out
        m00, m10, m01, top, bottom = ext[seen].T
        height = (bottom - top).astype(np.float64)
        cx, cy = m10 / m00, m01 / m00  # exactly cv2's centroid: the sums are exact
        out[seen, -2] = (cx - org[seen, 0]) / height
        out[seen, -1] = -(cy - org[seen, 1]) / height
        tops, bottoms, cxs = top.tolist(), bottom.tolist(), cx.tolist()
        for i, k in enumerate(seen.tolist()):
            out[k, : self.n_shape] = self._shape_of(m[k], tops[i], bottoms[i], cxs[i])
        if self._fractions:  # once for all, not per mask (NaN rows stay NaN)
            shape = out[:, : self.n_shape]
            np.clip(shape, 0.0, 1.0, out=shape)
        return out

    #: the shape numbers are fractions: ``from_masks`` clips them to [0, 1] (float32's
    #: rounding of an area average), ``_shape_of`` need not
    _fractions: ClassVar[bool] = False

    def _shape_of(self, m: NDArray[np.uint8], top: int, bottom: int, cx: float) -> FloatArray:
        """The shape numbers of one non-empty binary mask spanning rows ``[top, bottom)``
        with its centroid's column ``cx``: each silhouette descriptor defines them."""
        raise TypeError(f"{type(self).__name__} ({self.name!r}) defines no shape numbers of masks")


@dataclass(frozen=True)
class HuDescriptor(Descriptor):
    """7 log-scaled Hu moments (``hu_log``) and the centre."""

    name: str = "hu"
    n_shape: int = 7

    def standardiser(self, rows: FloatArray) -> tuple[FloatArray, FloatArray]:
        x = np.asarray(rows, dtype=np.float64)
        if x.shape[0] == 0:
            return np.zeros(7), np.ones(7)
        return x.mean(axis=0), np.maximum(x.std(axis=0), 1e-6)

    def mirror(self, x: NDArray[np.floating]) -> NDArray[np.floating]:
        out = super().mirror(x)
        out[..., 6] *= -1.0  # h7 is the skew invariant: it changes sign under reflection
        return out

    def _shape_of(self, m: NDArray[np.uint8], top: int, bottom: int, cx: float) -> FloatArray:
        mom = cv2.moments(m, binaryImage=True)
        return hu_log(np.asarray(cv2.HuMoments(mom), dtype=np.float64).ravel())


@dataclass(frozen=True)
class GridDescriptor(Descriptor):
    """Cell fill fractions of grids ``levels`` (``(rows, cols)`` each, concatenated) over
    the silhouette: rows span its height, ``h * cols / rows`` columns its centroid's
    column; position and scale drop out."""

    name: str = "grid"
    n_shape: int = 32
    levels: tuple[tuple[int, int], ...] = ((8, 4),)
    _fractions: ClassVar[bool] = True

    def __post_init__(self) -> None:
        if sum(r * c for r, c in self.levels) != self.n_shape:
            raise ValueError(f"{self.name}: n_shape must be the number of cells of {self.levels}")

    def _shape_of(self, m: NDArray[np.uint8], top: int, bottom: int, cx: float) -> FloatArray:
        rows = m[top:bottom]  # (the crop's rows: no other row is sampled)
        crops: dict[int, NDArray[np.float32]] = {}  # levels of one aspect share a crop
        cells = []
        for r, c in self.levels:
            width = grid_width(bottom - top, r, c)
            crop = crops.get(width)
            if crop is None:
                crop = crops[width] = crop_rows(rows, 0, bottom - top, cx, width)
            cells.append(cells_unclipped(crop, r, c))
        return np.concatenate(cells)

    def mirror(self, x: NDArray[np.floating]) -> NDArray[np.floating]:
        out = super().mirror(x)
        at = 0
        for r, c in self.levels:
            cells = out[..., at : at + r * c].reshape(*out.shape[:-1], r, c)
            out[..., at : at + r * c] = cells[..., ::-1].reshape(*out.shape[:-1], r * c)
            at += r * c
        return out


@dataclass(frozen=True)
class PoseDescriptor(Descriptor):
    """12 landmarks (``POSE_JOINTS``) relative to the mid-hip in torso lengths, x right,
    y up, then the mid-hip relative to the origin in torso lengths. The image's torso
    length is the largest of the torso, each thigh over ``THIGH_RATIO`` and each shin
    over ``SHIN_RATIO`` (all foreshortened; the largest is the nearest the truth)."""

    name: str = "pose"
    n_shape: int = 2 * len(POSE_JOINTS)
    kind: str = "pose"
    #: read as seen only: the landmarks name the performer's left and right, so the
    #: avatar does the side the performer does (``bench_accuracy --descriptor pose``
    #: against the four readings: the same label agreement, a better pose score on the
    #: performer's own side)
    reads_mirrored: bool = False
    #: a frame shows the performer's front or back (``sides``) where its shoulders and
    #: hips lie in the same left-right order, each pair this far apart (torso lengths)
    side_margin: float = 0.1

    def scale(self, points: FloatArray) -> FloatArray:
        """The torso length ``(...)`` in pixels of image points ``(..., 12, 2)``: the
        largest of the torso (mid-hip to mid-shoulder) and the legs' bones in torso
        lengths. A torso bent towards the camera is short in the image, and each bone is
        foreshortened by its own angle, so the largest is the nearest the truth."""
        p = np.asarray(points, dtype=np.float64)
        hip = 0.5 * (p[..., 6, :] + p[..., 7, :])
        shoulder = 0.5 * (p[..., 0, :] + p[..., 1, :])
        torso = np.linalg.norm(shoulder - hip, axis=-1)
        for a, b, ratio in ((6, 8, THIGH_RATIO), (8, 10, SHIN_RATIO)):  # left; +1: right
            for k in (0, 1):
                bone = np.linalg.norm(p[..., a + k, :] - p[..., b + k, :], axis=-1) / ratio
                torso = np.fmax(torso, bone)
        return torso

    def from_points(
        self, points: FloatArray, origin: FloatArray | tuple[float, float] = (0.0, 0.0)
    ) -> FloatArray:
        """Vectors ``(..., size)`` of image points ``(..., 12, 2)`` (pixels, x right, y
        down, in ``POSE_JOINTS`` order) with the centre relative to ``origin`` (``(2,)``
        or ``(..., 2)`` pixels), in units of ``scale``; NaN where the torso is
        degenerate."""
        p = np.asarray(points, dtype=np.float64)
        if p.shape[-2:] != (len(POSE_JOINTS), 2):
            raise ValueError(f"points must be (..., {len(POSE_JOINTS)}, 2), got {p.shape}")
        hip = 0.5 * (p[..., 6, :] + p[..., 7, :])
        torso = self.scale(p)
        with np.errstate(invalid="ignore", divide="ignore"):
            torso = np.where(torso > 1e-6, torso, np.nan)
            rel = (p - hip[..., None, :]) / torso[..., None, None]
            centre = (hip - np.asarray(origin, dtype=np.float64)) / torso[..., None]
        rel[..., 1] *= -1.0
        centre[..., 1] *= -1.0
        out = np.empty((*p.shape[:-2], self.size))
        out[..., : self.n_shape] = rel.reshape(*p.shape[:-2], self.n_shape)
        out[..., self.n_shape :] = centre
        return out

    def swap(self, x: NDArray[np.floating]) -> NDArray[np.floating]:
        """Vectors ``(..., size)`` with left and right landmarks exchanged (a detector
        that took the performer's left for the right)."""
        out = np.array(x, copy=True)
        pts = out[..., : self.n_shape].reshape(*out.shape[:-1], len(POSE_JOINTS) // 2, 2, 2)
        out[..., : self.n_shape] = pts[..., ::-1, :].reshape(*out.shape[:-1], self.n_shape)
        return out

    def mirror(self, x: NDArray[np.floating]) -> NDArray[np.floating]:
        out = self.swap(super().mirror(x))
        out[..., 0 : self.n_shape : 2] *= -1.0
        return out

    def variants(
        self, x: NDArray[np.floating], mirror: bool | None = None
    ) -> list[NDArray[np.floating]]:
        """As seen; with ``mirror`` (``None``: ``reads_mirrored``, no) also with left and
        right swapped (what a detector gives of a performer seen from behind, were it to
        confuse the two) and both mirrored (the other arm and leg). A window ``(n, size)``
        whose frames show both sides is also read with every frame showing one side, then
        the other (``sides``)."""
        mirror = self.reads_mirrored if mirror is None else mirror
        seen = [x, self.swap(x), self.mirror(x), self.mirror(self.swap(x))] if mirror else [x]
        return seen + self.sides(x)

    def sides(self, x: NDArray[np.floating]) -> list[NDArray[np.floating]]:
        """A window ``(n, size)`` whose frames show both sides of the body (some the
        shoulders and hips in one left-right order, some in the other: ``side_margin``)
        read twice more: those of the one side swapped, then those of the other (``[]``
        where every frame shows one side or none). A pose model reading a performer from
        behind takes their left for their right in about two frames of three and not the
        rest: such a window mixes two readings, and each of these is one of them throughout
        (``benchmarks/HISTORY.md``, "Views and people")."""
        if x.ndim != 2:
            return []
        m, (ls, rs, lh, rh) = self.side_margin, _SIDE_X
        shoulders, hips = x[:, ls] - x[:, rs], x[:, lh] - x[:, rh]
        ones = ((shoulders > m) & (hips > m), (shoulders < -m) & (hips < -m))
        if not (ones[0].any() and ones[1].any()):
            return []
        out = []
        for flip in ones:
            read = np.array(x, copy=True)
            read[flip] = self.swap(x[flip])
            out.append(read)
        return out


@dataclass(frozen=True)
class OutlineDescriptor(Descriptor):
    """The multigrid's cells, then the silhouette's outline (``outline_extents``): for
    each of ``bands`` row bands, how far the silhouette reaches left and right of its
    centroid, in silhouette heights. The grids span half the silhouette's height around
    the centroid, so outstretched arms reach beyond them: the outline tells arms held out
    to the side (arm circles) from arms swung round with the torso (side twists), and how
    far each reaches."""

    name: str = "outline"
    n_shape: int = 168 + 2 * 16
    grid: GridDescriptor = GridDescriptor("multigrid", 168, levels=((16, 8), (8, 4), (4, 2)))
    bands: int = 16

    def __post_init__(self) -> None:
        if self.grid.n_shape + 2 * self.bands != self.n_shape:
            raise ValueError(f"{self.name}: n_shape must be the grid's cells plus 2 x bands")

    def from_masks(
        self,
        masks: NDArray[np.generic],
        origins: NDArray[np.floating] | None = None,
        extents: NDArray[np.int64] | None = None,
    ) -> FloatArray:
        m = as_binary(masks, ndim=3)
        ext = mask_extents(m) if extents is None else extents
        cells = self.grid.from_masks(m, origins, ext)
        k = self.grid.n_shape
        out = np.empty((m.shape[0], self.size))
        out[:, :k] = cells[:, :k]
        out[:, k : self.n_shape] = binary_outline(m, ext, self.bands)
        out[:, self.n_shape :] = cells[:, k:]
        return out

    def mirror(self, x: NDArray[np.floating]) -> NDArray[np.floating]:
        x = np.asarray(x)
        k = self.grid.n_shape
        out = np.array(x, copy=True)
        grid = np.concatenate([x[..., :k], x[..., self.n_shape :]], axis=-1)
        g = self.grid.mirror(grid)
        out[..., :k] = g[..., :k]
        out[..., self.n_shape :] = g[..., k:]
        ext = x[..., k : self.n_shape].reshape(*x.shape[:-1], self.bands, 2)
        out[..., k : self.n_shape] = (-ext[..., ::-1]).reshape(*x.shape[:-1], 2 * self.bands)
        return out


_DESCRIPTORS: dict[str, Descriptor] = {
    "hu": HuDescriptor(),
    # reject: above the 99th percentile of true matches' costs on the leave-one-take-out
    # folds, below most garbage (bench_recognition.py; Hu moments cannot tell a person
    # upside down, being invariant to rotation: no threshold)
    "grid": GridDescriptor(reject=5.0),
    "multigrid": GridDescriptor(
        "multigrid", 128 + 32 + 8, reject=4.0, levels=((16, 8), (8, 4), (4, 2))
    ),
    "outline": OutlineDescriptor(reject=4.5),
    # the pose descriptor's from a pose model's own landmarks of performers the library
    # has not seen, from every side (``bench_views``' recordings): above their 98th
    # percentile, below the same performers upside down
    "pose": PoseDescriptor(reject=5.5),
}
DESCRIPTORS = tuple(_DESCRIPTORS)
#: the silhouette bank's default (``benchmarks/bench_recognition.py``; README)
DEFAULT_DESCRIPTOR = "outline"


def get_descriptor(name: str | Descriptor) -> Descriptor:
    """The descriptor called ``name`` (one of ``DESCRIPTORS``)."""
    if isinstance(name, Descriptor):
        return name
    try:
        return _DESCRIPTORS[name]
    except KeyError:
        raise ValueError(
            f"descriptor must be one of {', '.join(DESCRIPTORS)}, not {name!r}"
        ) from None
