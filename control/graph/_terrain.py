"""The rough terrain under captured motion, read off the feet (Lee et al. §4.1.2 and §6).

The terrain clips were captured on blocks laid on a square grid at a few heights. Which
block a planted foot stands on is not in the data, but the contacts show it: planted toes
sit at a few distinct heights (the ground, one block, two blocks) and at a few distinct
places (the block centres, ``block`` metres apart). ``captured_terrain`` estimates the
grid's phase (a block centre, ``origin``) as the circular mean of the planted feet's
positions modulo the block size, and the levels as the k-means of the planted toes'
heights. The terrain coordinate rules then turn motion about block centres by quarter
turns, shift it by whole blocks and lift it by whole levels (``GraphOptions.terrain``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..motion import Clip, foot_points
from ._graph import GraphOptions, select_clips

__all__ = ["CapturedTerrain", "FootTrack", "captured_terrain", "foot_track", "terrain_options"]

FloatArray = NDArray[np.float64]

#: The paper's blocks: 24 by 24 inches on the ground.
BLOCK = 0.6096


@dataclass(frozen=True, eq=False)
class FootTrack:
    """Feet of every frame of some clips end to end: ``toe`` and ``ankle`` ``(n, 2, 3)``
    (left, right) in library coordinates, ``states`` ``(n, 2)`` contacts."""

    toe: FloatArray
    ankle: FloatArray
    states: NDArray[np.bool_]

    @property
    def support(self) -> FloatArray:
        """``(n, 2, 2)`` the ground point ``(x, z)`` under each foot (ankle and toe's
        middle)."""
        return 0.5 * (self.toe[..., [0, 2]] + self.ankle[..., [0, 2]])


def foot_track(clips: Sequence[Clip]) -> FootTrack:
    """The feet of ``clips``, end to end (root translations as captured)."""
    toes, ankles = [], []
    for c in clips:
        ankle, toe = foot_points(c.motion)
        toes.append(toe)
        ankles.append(ankle)
    return FootTrack(
        np.concatenate(toes),
        np.concatenate(ankles),
        np.concatenate([c.contacts.states for c in clips]),
    )


@dataclass(frozen=True)
class CapturedTerrain:
    """The block grid the clips were captured on.

    ``origin``: ``(x, z)`` of a block centre; ``levels``: the planted toe's height on each
    level, lowest (the ground) first; ``toe_floor`` and ``ankle_floor``: the toe's and
    ankle's height when planted on the ground; ``coherence``: per axis, how tightly the
    planted feet gather at block centres (1: all at centres; near 0: no grid, e.g. flat
    ground); ``contacts``: the planted frames used."""

    block: float
    origin: tuple[float, float]
    levels: tuple[float, ...]
    ankle_floor: float
    coherence: tuple[float, float]
    contacts: int

    @property
    def rise(self) -> float:
        """The mean height of one block (metres)."""
        if len(self.levels) < 2:
            return 0.0
        return float((self.levels[-1] - self.levels[0]) / (len(self.levels) - 1))

    @property
    def toe_floor(self) -> float:
        return self.levels[0]

    def level_of(self, toe_height: FloatArray) -> NDArray[np.int64]:
        """The level (0 = ground) a planted toe at ``toe_height`` stands on."""
        lv = np.asarray(self.levels)
        h = np.asarray(toe_height, dtype=np.float64)
        return np.abs(h[..., None] - lv).argmin(axis=-1).astype(np.int64)

    def to_dict(self) -> dict[str, object]:
        return {
            "block_m": self.block,
            "origin_m": [round(v, 4) for v in self.origin],
            "rise_m": round(self.rise, 4),
            "levels_toe_m": [round(v, 4) for v in self.levels],
            "coherence": [round(v, 3) for v in self.coherence],
            "contacts": self.contacts,
        }


def captured_terrain(
    clips: Sequence[Clip], block: float = BLOCK, n_levels: int = 3, feet: FootTrack | None = None
) -> CapturedTerrain:
    """Estimate the block grid under ``clips`` from their planted feet.

    Raises ``ValueError`` when the clips have fewer planted frames than the estimate
    needs (ten per level)."""
    if not block > 0 or n_levels < 1:
        raise ValueError("block must be positive and n_levels at least 1")
    feet = feet or foot_track(clips)
    s = feet.states
    if int(s.sum()) < 10 * n_levels:
        names = ", ".join(c.name for c in clips)
        raise ValueError(f"too few planted feet in {names} to find the terrain under them")
    xz = feet.support[s]
    # the grid's phase per axis: a circular mean of positions modulo the block
    z = np.exp(2j * math.pi * xz / block).mean(axis=0)
    origin = np.angle(z) * block / (2.0 * math.pi)
    h = feet.toe[..., 1][s]
    levels = _kmeans_1d(h, n_levels)
    nearest = np.abs(h[:, None] - levels).argmin(axis=1)
    ground = nearest == 0
    ankle_h = feet.ankle[..., 1][s]
    return CapturedTerrain(
        block=float(block),
        origin=(float(origin[0]), float(origin[1])),
        levels=tuple(float(v) for v in levels),
        ankle_floor=float(np.median(ankle_h[ground])),
        coherence=(float(abs(z[0])), float(abs(z[1]))),
        contacts=int(s.sum()),
    )


def _kmeans_1d(x: FloatArray, k: int) -> FloatArray:
    """Cluster centres of heights on a line, lowest first (scikit-learn's k-means)."""
    from sklearn.cluster import KMeans

    km = KMeans(n_clusters=k, n_init=10, random_state=0).fit(x.reshape(-1, 1))
    return np.sort(km.cluster_centers_.ravel())


def terrain_options(
    clips: Sequence[Clip], block: float = BLOCK, options: GraphOptions | None = None
) -> tuple[GraphOptions, CapturedTerrain]:
    """``options`` (default ``GraphOptions()``) made a terrain graph's: ``coords``
    ``"terrain"`` with ``block`` and the grid origin and block height found under the
    clips the graph would use; and that captured terrain."""
    chosen, _ = select_clips(list(clips))
    if any(c.mirrored for c in chosen):
        raise ValueError("mirrored clips do not stand on the captured blocks' grid")
    cap = captured_terrain(chosen, block)
    base = options or GraphOptions()
    opts = dataclasses.replace(
        base,
        coords="terrain",
        block=float(block),
        origin_x=cap.origin[0],
        origin_z=cap.origin[1],
        rise=cap.rise,
    )
    return opts, cap
