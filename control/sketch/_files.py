"""Sketched paths and environments, read from files (Lee et al. §5.2 and §6).

A sketch is a polyline on the ground: the centre of mass projected on the ground, in
metres, ``x`` to the right and ``z`` forward (the library's ground plane; ``y`` is up).

- JSON: ``{"points": [[x, z], ...]}`` (or a bare list of pairs);
- CSV: one ``x,z`` pair per line; a first line ``x,z`` and ``#`` comments are allowed.

An environment is JSON::

    {"kind": "maze",
     "bounds": [xmin, zmin, xmax, zmax],             # optional: walls around the maze
     "obstacles": [[[x, z], [x, z], [x, z], ...], ...]}  # polygons, 3+ corners each

Every reader error names the file (and the line or the item) and what is wrong.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["Environment", "SketchFileError", "read_environment", "read_sketch"]

FloatArray = NDArray[np.float64]

ENV_KINDS = ("maze",)


class SketchFileError(ValueError):
    """A sketch or environment file that cannot be used; the message says where and why."""


def _pair(path: Path, where: str, item: Any) -> tuple[float, float]:
    if not isinstance(item, list | tuple) or len(item) != 2:
        raise SketchFileError(f"{path}: {where}: expected a pair [x, z], got {item!r}")
    try:
        x, z = float(item[0]), float(item[1])
    except (TypeError, ValueError):
        raise SketchFileError(
            f"{path}: {where}: coordinates must be numbers, got {item!r}"
        ) from None
    if not (math.isfinite(x) and math.isfinite(z)):
        raise SketchFileError(f"{path}: {where}: coordinates must be finite, got {item!r}")
    return x, z


def _load_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise SketchFileError(f"{path}: no such file") from None
    except UnicodeDecodeError:
        raise SketchFileError(f"{path}: not a text file") from None
    except json.JSONDecodeError as exc:
        raise SketchFileError(f"{path}:{exc.lineno}: not valid JSON ({exc.msg})") from None


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
class Environment:
    """Obstacles (polygons ``(k, 2)`` in x, z) and optional ``bounds`` walls."""

    kind: str = "maze"
    obstacles: tuple[FloatArray, ...] = ()
    bounds: tuple[float, float, float, float] | None = None
    name: str = ""

    def __post_init__(self) -> None:
        # every obstacle edge at once, for vectorised distance and inside tests
        if self.obstacles:
            a = np.concatenate(self.obstacles)
            b = np.concatenate([np.roll(p, -1, axis=0) for p in self.obstacles])
            ids = np.concatenate([np.full(len(p), i) for i, p in enumerate(self.obstacles)])
        else:
            a = b = np.zeros((0, 2))
            ids = np.zeros(0, dtype=np.int64)
        object.__setattr__(self, "_edges", (a, b - a, ids.astype(np.int64)))

    def clearance(self, xz: FloatArray) -> FloatArray:
        """Signed distance ``(n,)`` of ground points ``(n, 2)`` to the nearest obstacle
        edge or wall: negative inside an obstacle or outside the bounds."""
        xz = np.asarray(xz, dtype=np.float64).reshape(-1, 2)
        best = np.full(xz.shape[0], np.inf)
        a, ab, ids = self._edges  # type: ignore[attr-defined]
        if ids.size:
            ap = xz[:, None, :] - a[None]  # (n, E, 2)
            t = np.clip((ap * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-12), 0.0, 1.0)
            d = np.linalg.norm(ap - t[..., None] * ab, axis=-1).min(axis=1)
            # even-odd rule: a ray to +x crosses a polygon's edges an odd number of times
            # from inside it
            y0, y1 = a[None, :, 1], a[None, :, 1] + ab[None, :, 1]
            py = xz[:, None, 1]
            crosses = (y0 > py) != (y1 > py)
            xs = a[None, :, 0] + (py - y0) / np.where(y1 != y0, y1 - y0, 1.0) * ab[None, :, 0]
            hit = (crosses & (xz[:, None, 0] < xs)).astype(np.int64)  # (n, E)
            per_poly = np.zeros((xz.shape[0], len(self.obstacles)), dtype=np.int64)
            np.add.at(per_poly.T, ids, hit.T)
            inside = (per_poly % 2 == 1).any(axis=1)
            best = np.where(inside, -d, d)
        if self.bounds is not None:
            x0, z0, x1, z1 = self.bounds
            wall = np.minimum.reduce([xz[:, 0] - x0, x1 - xz[:, 0], xz[:, 1] - z0, z1 - xz[:, 1]])
            best = np.minimum(best, wall)
        return best


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
    unknown = set(data) - {"kind", "obstacles", "bounds", "name"}
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
    return Environment("maze", tuple(polys), bounds, str(data.get("name", path.stem)))
