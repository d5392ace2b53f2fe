"""A top-down picture of a sketch, its environment and the avatar's root paths; the
environment as a mesh for rendered videos."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..artifacts import atomic_write
from ._files import Environment, TerrainMap

__all__ = ["draw_top_down", "environment_mesh"]

FloatArray = NDArray[np.float64]

# BGR colours of the root paths, in order
_COLOURS = ((40, 40, 220), (200, 120, 0), (0, 150, 0), (160, 0, 160))


def draw_top_down(
    path: str | Path,
    sketch: FloatArray,
    env: Environment | None,
    roots: Mapping[str, FloatArray],
    size: int = 800,
) -> None:
    """A PNG seen from above (x right, z up): obstacles grey, terrain blocks shaded by
    level (darker is higher, with the level written on each), the sketch black with
    its start marked, each root path in its own colour with a legend, a 1 m scale bar."""
    import cv2

    pts = [sketch, *roots.values()]
    if env is not None:
        pts += list(env.obstacles)
        if env.bounds is not None:
            x0, z0, x1, z1 = env.bounds
            pts.append(np.array([[x0, z0], [x1, z1]]))
        if env.terrain is not None:
            t = env.terrain
            rows, cols = t.levels.shape
            x0, z0 = t.corner
            pts.append(np.array([[x0, z0], [x0 + cols * t.block, z0 + rows * t.block]]))
    allp = np.concatenate([p.reshape(-1, 2) for p in pts])
    lo, hi = allp.min(axis=0) - 0.5, allp.max(axis=0) + 0.5
    scale = (size - 40) / float(max(hi - lo))
    h = int((hi[1] - lo[1]) * scale) + 40
    w = int((hi[0] - lo[0]) * scale) + 40

    def px(p: FloatArray) -> NDArray[np.int32]:
        q = np.asarray(p, dtype=np.float64).reshape(-1, 2)
        x = 20 + (q[:, 0] - lo[0]) * scale
        y = h - 20 - (q[:, 1] - lo[1]) * scale
        return np.round(np.stack((x, y), axis=1)).astype(np.int32)

    img = np.full((h, w, 3), 255, dtype=np.uint8)
    if env is not None and env.terrain is not None:
        _draw_terrain(img, env.terrain, px)
    if env is not None:
        for poly in env.obstacles:
            cv2.fillPoly(img, [px(poly)], (170, 170, 170))
        if env.bounds is not None:
            x0, z0, x1, z1 = env.bounds
            corners = np.array([[x0, z0], [x1, z0], [x1, z1], [x0, z1]])
            cv2.polylines(img, [px(corners)], True, (90, 90, 90), 2)
    cv2.polylines(img, [px(sketch)], False, (0, 0, 0), 2, cv2.LINE_AA)
    cv2.circle(img, tuple(int(v) for v in px(sketch[0])[0]), 6, (0, 0, 0), -1)
    for i, (name, root) in enumerate(roots.items()):
        colour = _COLOURS[i % len(_COLOURS)]
        cv2.polylines(img, [px(root)], False, colour, 2, cv2.LINE_AA)
        cv2.putText(img, name, (10, 22 + 20 * i), cv2.FONT_HERSHEY_SIMPLEX, 0.55, colour, 1)
    bar = round(scale)
    cv2.line(img, (w - 20 - bar, h - 12), (w - 20, h - 12), (0, 0, 0), 2)
    cv2.putText(img, "1 m", (w - 20 - bar, h - 18), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1)
    ok, buf = cv2.imencode(".png", img)
    if not ok:
        raise OSError(f"{path}: could not encode the picture")
    with atomic_write(path, "wb") as fh:
        fh.write(buf.tobytes())


def _draw_terrain(
    img: NDArray[np.uint8], t: TerrainMap, px: Callable[[FloatArray], NDArray[np.int32]]
) -> None:
    """Terrain blocks on ``img``, shaded by level (darker is higher), each raised block's
    level written on it; ``px`` maps metres (x, z) to pixels."""
    import cv2

    top = max(1, int(t.levels.max()))
    for (r, c), level in np.ndenumerate(t.levels):
        x0, z0 = t.corner[0] + c * t.block, t.corner[1] + r * t.block
        cell = np.array(
            [[x0, z0], [x0 + t.block, z0], [x0 + t.block, z0 + t.block], [x0, z0 + t.block]]
        )
        shade = int(245 - 130 * level / top)
        cv2.fillPoly(img, [px(cell)], (shade, shade, shade))
        cv2.polylines(img, [px(cell)], True, (200, 200, 200), 1)
        if level:
            at = px(np.array([x0 + 0.4 * t.block, z0 + 0.35 * t.block]))[0]
            cv2.putText(
                img,
                str(level),
                (int(at[0]), int(at[1])),
                cv2.FONT_HERSHEY_SIMPLEX,
                0.4,
                (60, 60, 60),
                1,
            )


def _prism(poly: FloatArray, y0: float, y1: float) -> tuple[FloatArray, NDArray[np.int64]]:
    """A polygon ``(k, 2)`` (x, z) extruded from height ``y0`` to ``y1``: side walls and a
    top (the Delaunay triangles of its corners that lie inside it)."""
    from scipy.spatial import Delaunay

    k = len(poly)
    bottom = np.column_stack((poly[:, 0], np.full(k, y0), poly[:, 1]))
    top = np.column_stack((poly[:, 0], np.full(k, y1), poly[:, 1]))
    verts = np.vstack((bottom, top))
    faces = []
    for i in range(k):
        j = (i + 1) % k
        faces += [(i, j, k + j), (i, k + j, k + i)]
    cap = Delaunay(poly).simplices
    inside = Environment(obstacles=(poly,)).clearance(poly[cap].mean(axis=1)) < 0
    faces += [tuple(k + t) for t in cap[inside]]
    return verts, np.array(faces, dtype=np.int64)


def environment_mesh(
    env: Environment, rise: float = 0.0, height: float = 0.6
) -> tuple[FloatArray, NDArray[np.int64]] | None:
    """The environment as one mesh ``(vertices, faces)`` in metres (y up) for a rendered
    video: obstacles as walls ``height`` high, terrain blocks ``level * rise`` high.
    ``None`` when there is nothing to show."""
    parts = [_prism(p, 0.0, height) for p in env.obstacles]
    if env.terrain is not None and rise > 0:
        t = env.terrain
        for (r, c), level in np.ndenumerate(t.levels):
            if level > 0:
                x0, z0 = t.corner[0] + c * t.block, t.corner[1] + r * t.block
                sq = np.array(
                    [[x0, z0], [x0 + t.block, z0], [x0 + t.block, z0 + t.block], [x0, z0 + t.block]]
                )
                parts.append(_prism(sq, 0.0, level * rise))
    if not parts:
        return None
    verts, faces, base = [], [], 0
    for v, f in parts:
        verts.append(v)
        faces.append(f + base)
        base += len(v)
    return np.vstack(verts), np.vstack(faces)
