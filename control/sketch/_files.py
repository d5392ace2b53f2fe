"""Sketched paths and environments, read from files (Lee et al. §5.2 and §6).

A sketch is a polyline on the ground: the centre of mass projected on the ground, in
metres, ``x`` to the right and ``z`` forward (the library's ground plane; ``y`` is up).

- JSON: ``{"points": [[x, z], ...]}`` (or a bare list of pairs);
- CSV: one ``x,z`` pair per line; a first line ``x,z`` and ``#`` comments are allowed.

An environment is JSON::

    {"kind": "maze",
     "bounds": [xmin, zmin, xmax, zmax],             # optional: walls around the maze
     "obstacles": [[[x, z], [x, z], [x, z], ...], ...]}  # polygons, 3+ corners each

or a block terrain (Lee et al. §6: blocks at a few heights on a square grid)::

    {"kind": "terrain",
     "block": 0.6096,                 # the side of a block (metres; the captured blocks')
     "corner": [x, z],                # the low corner of the first block of the first row
     "levels": [[0, 1, 2, ...], ...], # block heights in levels, one row per block along z
     "obstacles": [...], "bounds": [...]}  # optional, as in a maze

Outside the grid is the ground (level 0). A level is one captured block height, which
the library tells (``captured_terrain``).

Every reader error names the file (and the line or the item) and what is wrong.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numba
import numpy as np
from numpy.typing import NDArray

from ..kernels import kernel_input

__all__ = ["Environment", "SketchFileError", "TerrainMap", "read_environment", "read_sketch"]

FloatArray = NDArray[np.float64]

ENV_KINDS = ("maze", "terrain")


class SketchFileError(ValueError):
    """A sketch or environment file that cannot be used; the message says where and why."""


def _pair(path: Path, where: str, item: Any) -> tuple[float, float]:
    if not isinstance(item, list | tuple) or len(item) != 2:
        raise SketchFileError(f"{path}: {where}: expected a pair [x, z], got {item!r}")
    try:
        x, z = float(item[0]), float(item[1])
    except (TypeError, ValueError, OverflowError):
        raise SketchFileError(
            f"{path}: {where}: coordinates must be numbers, got {item!r}"
        ) from None
    if not (math.isfinite(x) and math.isfinite(z)):
        raise SketchFileError(f"{path}: {where}: coordinates must be finite, got {item!r}")
    return x, z


class _HugeNumber(ValueError):
    pass


def _small_int(text: str) -> int:
    if len(text.lstrip("-")) > 15:  # no plausible coordinate, level or count
        raise _HugeNumber(text)
    return int(text)


def _load_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text(encoding="utf-8-sig"), parse_int=_small_int)
    except FileNotFoundError:
        raise SketchFileError(f"{path}: no such file") from None
    except UnicodeDecodeError:
        raise SketchFileError(f"{path}: not a text file") from None
    except json.JSONDecodeError as exc:
        raise SketchFileError(f"{path}:{exc.lineno}: not valid JSON ({exc.msg})") from None
    except _HugeNumber as exc:
        raise SketchFileError(f"{path}: a number of {len(str(exc))} digits") from None
    except RecursionError:
        raise SketchFileError(f"{path}: nested too deeply to be a sketch") from None


def read_sketch(path: str | Path) -> FloatArray:
    """The sketched polyline ``(n, 2)`` (x, z) of a JSON or CSV file; at least 2 points,
    consecutive duplicates dropped."""
    path = Path(path)
    pts: list[tuple[float, float]] = []
    if path.suffix.lower() == ".json":
        data = _load_json(path)
        items = data.get("points") if isinstance(data, dict) else data
        if not isinstance(items, list):
            raise SketchFileError(f"{path}: expected {{'points': [[x, z], ...]}}")
        pts = [_pair(path, f"point {i}", p) for i, p in enumerate(items)]
    else:
        try:
            text = path.read_text()
        except FileNotFoundError:
            raise SketchFileError(f"{path}: no such file") from None
        except UnicodeDecodeError:
            raise SketchFileError(f"{path}: not a text file") from None
        for no, raw in enumerate(text.splitlines(), 1):
            line = raw.split("#", 1)[0].strip()
            if not line or (not pts and line.replace(" ", "").lower() == "x,z"):
                continue
            parts = [p.strip() for p in line.split(",")]
            if len(parts) != 2:
                raise SketchFileError(f"{path}:{no}: expected 'x,z', got {raw!r}")
            pts.append(_pair(path, f"line {no}", parts))
    arr = np.array(pts, dtype=np.float64).reshape(-1, 2)
    if arr.shape[0]:
        keep = np.concatenate(([True], np.any(np.diff(arr, axis=0) != 0, axis=1)))
        arr = arr[keep]
    if arr.shape[0] < 2:
        raise SketchFileError(f"{path}: a sketch needs at least 2 distinct points")
    return arr


@dataclass(frozen=True, eq=False)
class TerrainMap:
    """Blocks on a square grid: ``levels[r, c]`` (whole block heights) covers
    ``x`` in ``corner_x + [c, c + 1) * block`` and ``z`` in ``corner_z + [r, r + 1) * block``;
    outside the grid is level 0."""

    block: float
    corner: tuple[float, float]
    levels: NDArray[np.int64]

    def level_at(self, xz: FloatArray) -> NDArray[np.int64]:
        """The level ``(n,)`` under ground points ``(n, 2)``."""
        xz = np.asarray(xz, dtype=np.float64).reshape(-1, 2)
        c = np.floor((xz[:, 0] - self.corner[0]) / self.block).astype(np.int64)
        r = np.floor((xz[:, 1] - self.corner[1]) / self.block).astype(np.int64)
        rows, cols = self.levels.shape
        inside = (r >= 0) & (r < rows) & (c >= 0) & (c < cols)
        out = np.zeros(xz.shape[0], dtype=np.int64)
        out[inside] = self.levels[r[inside], c[inside]]
        return out

    def level_at_point(self, x: float, z: float) -> int:
        """``level_at`` for one point, without arrays (the search's inner loop)."""
        c = math.floor((x - self.corner[0]) / self.block)
        r = math.floor((z - self.corner[1]) / self.block)
        rows, cols = self.levels.shape
        if 0 <= r < rows and 0 <= c < cols:
            return int(self.levels[r, c])
        return 0

    @property
    def first_centre(self) -> tuple[float, float]:
        """``(x, z)`` of the first block's centre."""
        return self.corner[0] + 0.5 * self.block, self.corner[1] + 0.5 * self.block


@dataclass(frozen=True, eq=False)
class Environment:
    """Obstacles (polygons ``(k, 2)`` in x, z), optional ``bounds`` walls and, for
    ``kind == "terrain"``, the blocks."""

    kind: str = "maze"
    obstacles: tuple[FloatArray, ...] = ()
    bounds: tuple[float, float, float, float] | None = None
    name: str = ""
    terrain: TerrainMap | None = None

    def __post_init__(self) -> None:
        # every obstacle edge at once, for vectorised distance and inside tests
        if self.obstacles:
            a = np.concatenate(self.obstacles)
            b = np.concatenate([np.roll(p, -1, axis=0) for p in self.obstacles])
            ids = np.concatenate([np.full(len(p), i) for i, p in enumerate(self.obstacles)])
        else:
            a = b = np.zeros((0, 2))
            ids = np.zeros(0, dtype=np.int64)
        edges = (kernel_input(a, np.float64), kernel_input(b - a, np.float64))
        object.__setattr__(self, "_edges", (*edges, kernel_input(ids, np.int64)))
        bounds = self.bounds if self.bounds is not None else ()
        object.__setattr__(self, "_bounds", kernel_input(bounds, np.float64))

    def clearance(self, xz: FloatArray) -> FloatArray:
        """Signed distance ``(n,)`` of ground points ``(n, 2)`` to the nearest obstacle
        edge or wall: negative inside an obstacle or outside the bounds (even-odd rule:
        a ray to +x crosses a polygon's edges an odd number of times from inside it).
        The search asks this of every node it opens, one point at a time: a numba
        kernel (``_clearance_kernel``)."""
        xz = kernel_input(np.reshape(xz, (-1, 2)), np.float64)
        a, ab, ids = self._edges  # type: ignore[attr-defined]
        out = np.empty(xz.shape[0])
        bounds = self._bounds  # type: ignore[attr-defined]
        _clearance_kernel(xz, a, ab, ids, len(self.obstacles), bounds, out)
        return out


@numba.njit(cache=True)
def _clearance_kernel(
    xz: FloatArray,
    a: FloatArray,
    ab: FloatArray,
    ids: NDArray[np.int64],
    n_polys: int,
    bounds: FloatArray,
    out: FloatArray,
) -> None:
    crossings = np.zeros(max(n_polys, 1), dtype=np.int64)
    for i in range(xz.shape[0]):
        px, py = xz[i, 0], xz[i, 1]
        best = np.inf
        if ids.size:
            crossings[:] = 0
            d = np.inf
            for e in range(ids.size):
                apx, apy = px - a[e, 0], py - a[e, 1]
                t = (apx * ab[e, 0] + apy * ab[e, 1]) / max(
                    ab[e, 0] * ab[e, 0] + ab[e, 1] * ab[e, 1], 1e-12
                )
                t = min(max(t, 0.0), 1.0)
                dx, dy = apx - t * ab[e, 0], apy - t * ab[e, 1]
                d = min(d, np.sqrt(dx * dx + dy * dy))
                y0, y1 = a[e, 1], a[e, 1] + ab[e, 1]
                if (y0 > py) != (y1 > py):
                    x = a[e, 0] + (py - y0) / (y1 - y0) * ab[e, 0]
                    if px < x:
                        crossings[ids[e]] += 1
            inside = False
            for k in range(n_polys):
                inside = inside or crossings[k] % 2 == 1
            best = -d if inside else d
        if bounds.size:
            wall = min(px - bounds[0], bounds[2] - px, py - bounds[1], bounds[3] - py)
            best = min(best, wall)
        out[i] = best


def read_environment(path: str | Path) -> Environment:
    """An environment JSON file (see the module docs)."""
    path = Path(path)
    data = _load_json(path)
    if not isinstance(data, dict):
        raise SketchFileError(f"{path}: expected a JSON object with 'kind'")
    kind = data.get("kind")
    if kind not in ENV_KINDS:
        raise SketchFileError(
            f"{path}: unknown environment kind {kind!r} (supported: {', '.join(ENV_KINDS)})"
        )
    allowed = {"kind", "obstacles", "bounds", "name"}
    if kind == "terrain":
        allowed |= {"block", "corner", "levels"}
    unknown = set(data) - allowed
    if unknown:
        raise SketchFileError(f"{path}: unknown keys {', '.join(sorted(unknown))}")
    polys = []
    raw = data.get("obstacles", [])
    if not isinstance(raw, list):
        raise SketchFileError(f"{path}: 'obstacles' must be a list of polygons")
    for i, poly in enumerate(raw):
        if not isinstance(poly, list) or len(poly) < 3:
            raise SketchFileError(f"{path}: obstacle {i}: a polygon needs 3 or more corners")
        arr = np.array([_pair(path, f"obstacle {i} corner {j}", p) for j, p in enumerate(poly)])
        x, z = arr[:, 0], arr[:, 1]
        if abs(np.dot(x, np.roll(z, -1)) - np.dot(z, np.roll(x, -1))) < 1e-9:
            raise SketchFileError(f"{path}: obstacle {i}: the polygon has no area")
        polys.append(arr)
    bounds = data.get("bounds")
    if bounds is not None:
        if not isinstance(bounds, list) or len(bounds) != 4:
            raise SketchFileError(f"{path}: 'bounds' must be [xmin, zmin, xmax, zmax]")
        x0, z0 = _pair(path, "bounds", bounds[:2])
        x1, z1 = _pair(path, "bounds", bounds[2:])
        if not (x1 > x0 and z1 > z0):
            raise SketchFileError(f"{path}: 'bounds' must have xmax > xmin and zmax > zmin")
        bounds = (x0, z0, x1, z1)
    terrain = _read_terrain(path, data) if kind == "terrain" else None
    return Environment(kind, tuple(polys), bounds, str(data.get("name", path.stem)), terrain)


def _read_terrain(path: Path, data: dict[str, Any]) -> TerrainMap:
    for key in ("block", "corner", "levels"):
        if key not in data:
            raise SketchFileError(f"{path}: a terrain needs '{key}'")
    block = data["block"]
    if isinstance(block, bool) or not isinstance(block, int | float) or not block > 0:
        raise SketchFileError(f"{path}: 'block' must be a positive number, got {block!r}")
    if not math.isfinite(block):
        raise SketchFileError(f"{path}: 'block' must be finite, got {block!r}")
    corner = _pair(path, "corner", data["corner"])
    rows = data["levels"]
    if not isinstance(rows, list) or not rows:
        raise SketchFileError(f"{path}: 'levels' must be a non-empty list of rows")
    width = None
    for r, row in enumerate(rows):
        if not isinstance(row, list) or not row:
            raise SketchFileError(f"{path}: levels row {r}: expected a non-empty list")
        if width is None:
            width = len(row)
        elif len(row) != width:
            raise SketchFileError(
                f"{path}: levels row {r}: {len(row)} blocks, but row 0 has {width}"
            )
        for c, v in enumerate(row):
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                raise SketchFileError(
                    f"{path}: levels row {r} block {c}: expected a whole number >= 0, got {v!r}"
                )
    return TerrainMap(float(block), corner, np.array(rows, dtype=np.int64))
