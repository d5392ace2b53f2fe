"""Headless rendering with pyrender, with every known pitfall handled in this one place.

- numpy 2 removed ``np.infty``, which pyrender 0.1.45 still uses: restored before import.
- No display: ``PYOPENGL_PLATFORM=egl`` (Mesa's software rasterizer on a machine without
  a GPU, the GPU's EGL where there is one) unless the caller chose a platform.
- llvmpipe starts a thread pool per context; ``LP_NUM_THREADS=0`` renders on the calling
  thread, which is faster for small images and lets processes share the cores.
- EGL renders into a 4x multisampled buffer: our renderer allocates single-sample
  buffers instead (a silhouette needs no anti-aliasing, and it is cheaper).
- OSMesa misses pyrender's shader cache on every frame (PyOpenGL hands out a new context
  pointer per call), leaking and slowing down: not used; EGL is required.

One renderer is reused; the body is one merged low-poly mesh per frame; only depth is read.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ._camera import CameraRing

__all__ = ["GLRenderer", "capsule_mesh"]

FloatArray = NDArray[np.float64]


def _prepare() -> Any:
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    os.environ.setdefault("LP_NUM_THREADS", "0")
    if not hasattr(np, "infty"):  # numpy 2 removed the alias that pyrender uses
        vars(np)["infty"] = np.inf
    import pyrender

    return pyrender


def _template(count: int = 8) -> tuple[FloatArray, NDArray[np.int64], NDArray[np.bool_]]:
    """A unit capsule along +Z: vertices, faces, and which vertices belong to the top cap."""
    import trimesh

    mesh = trimesh.creation.capsule(height=1.0, radius=1.0, count=[count, count])
    v = np.asarray(mesh.vertices, dtype=np.float64)
    top = v[:, 2] > 0.0
    v = v.copy()
    v[:, 2] = np.where(top, v[:, 2] - 0.5, v[:, 2] + 0.5)  # two unit hemispheres at 0
    return v, np.asarray(mesh.faces, dtype=np.int64), top


_TEMPLATE: tuple[FloatArray, NDArray[np.int64], NDArray[np.bool_]] | None = None


def capsule_mesh(segments: FloatArray, radius: FloatArray) -> tuple[FloatArray, NDArray[np.int64]]:
    """One merged triangle mesh ``(vertices (N, 3), faces (M, 3))`` of capsules ``(B, 2, 3)``."""
    global _TEMPLATE
    if _TEMPLATE is None:
        _TEMPLATE = _template()
    tv, tf, top = _TEMPLATE
    a = segments[:, 0]
    axis = segments[:, 1] - a
    length = np.linalg.norm(axis, axis=1)
    z = axis / np.maximum(length, 1e-12)[:, None]
    z[length < 1e-12] = (0.0, 0.0, 1.0)
    helper = np.where(np.abs(z[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross(z, x)
    local = tv[None] * radius[:, None, None]
    local[:, top, 2] += length[:, None]
    world = (
        a[:, None, :]
        + local[..., :1] * x[:, None, :]
        + local[..., 1:2] * y[:, None, :]
        + local[..., 2:] * z[:, None, :]
    )
    n_v = tv.shape[0]
    faces = (tf[None] + (np.arange(segments.shape[0]) * n_v)[:, None, None]).reshape(-1, 3)
    return world.reshape(-1, 3), faces


def _normals(vertices: FloatArray, faces: NDArray[np.int64]) -> FloatArray:
    """Per-vertex normals (area-weighted face normals)."""
    v = vertices[faces]
    fn = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    out = np.zeros_like(vertices)
    for k in range(3):
        np.add.at(out, faces[:, k], fn)
    return out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-12)


class GLRenderer:
    """Renders silhouettes of capsule bodies with pyrender, offscreen, for a ``CameraRing``."""

    def __init__(self, ring: CameraRing) -> None:
        pyrender = _prepare()
        self._pyrender = pyrender
        self.ring = ring
        self._r = pyrender.OffscreenRenderer(ring.width, ring.height_px)
        self._single_sample(self._r)
        self._scene = pyrender.Scene(bg_color=(0.0, 0.0, 0.0, 0.0))
        cx, cy = ring.centre
        camera = pyrender.IntrinsicsCamera(
            fx=ring.focal, fy=ring.focal, cx=cx, cy=cy, znear=0.05, zfar=100.0
        )
        self._camera = self._scene.add(camera, pose=np.eye(4))
        self._light = self._scene.add(
            pyrender.DirectionalLight(color=np.ones(3), intensity=3.0), pose=np.eye(4)
        )
        self._body: Any = None
        self._scenery: Any = None
        self._face: Any = None
        self._material = pyrender.MetallicRoughnessMaterial(
            baseColorFactor=(0.75, 0.72, 0.68, 1.0), metallicFactor=0.0, roughnessFactor=0.8
        )
        self._face_material = pyrender.MetallicRoughnessMaterial(
            baseColorFactor=(0.12, 0.1, 0.1, 1.0), metallicFactor=0.0, roughnessFactor=0.6
        )
        self.renders = 0

    @staticmethod
    def _single_sample(offscreen: Any) -> None:
        """Swap pyrender's 4x multisampled main framebuffer for a single-sample one."""
        from OpenGL import GL
        from pyrender import renderer as pr

        base = type(offscreen._renderer)

        class _SingleSample(base):  # type: ignore[misc, valid-type]
            def _configure_main_framebuffer(self) -> None:
                storage = pr.glRenderbufferStorageMultisample
                pr.glRenderbufferStorageMultisample = lambda t, _s, f, w, h: (
                    GL.glRenderbufferStorage(t, f, w, h)
                )
                try:
                    super()._configure_main_framebuffer()
                finally:
                    pr.glRenderbufferStorageMultisample = storage

        offscreen._renderer.__class__ = _SingleSample

    def _mesh(
        self,
        node: Any,
        vertices: FloatArray,
        faces: NDArray[np.int64],
        material: Any,
        placed: bool = False,
    ) -> Any:
        """Replace ``node`` (or nothing) by a node of one triangle mesh; returns it. With
        ``placed``, the node sits at the mesh's centre (its vertices relative to it), so
        that pyrender draws it in an order of its own: it draws a scene's meshes sorted by
        their nodes' distance from the camera, ties in the order of a set (of objects
        hashed by address), and where two meshes meet at one depth (the face's spheres
        on the head) the first drawn shows: with every node at the origin a render would
        differ from run to run at a few pixels, and so would the pose model's reading of
        it. (The body stays at the origin: its silhouettes are the rasterizer's.)"""
        pyrender = self._pyrender
        v = np.asarray(vertices, dtype=np.float64)
        f = np.asarray(faces, dtype=np.int64)
        at = v.mean(axis=0) if placed and v.size else np.zeros(3)
        prim = pyrender.Primitive(
            material=material,
            positions=(v - at).astype(np.float32),
            normals=_normals(v, f).astype(np.float32),
            indices=f.astype(np.uint32),
            mode=4,
        )
        if node is not None:
            self._scene.remove_node(node)
        pose = np.eye(4)
        pose[:3, 3] = at
        return self._scene.add(pyrender.Mesh([prim]), pose=pose)

    def set_body(self, segments: FloatArray, radius: FloatArray) -> None:
        """Show the capsules ``(B, 2, 3)`` (world coordinates) as one mesh."""
        vertices, faces = capsule_mesh(np.asarray(segments, dtype=np.float64), np.asarray(radius))
        self._body = self._mesh(self._body, vertices, faces, self._material)

    def set_face(self, centres: FloatArray, radius: FloatArray) -> None:
        """Show small dark spheres ``(K, 3)`` of ``radius`` ``(K,)`` (the face's eyes and
        nose); shaded renders only."""
        c = np.asarray(centres, dtype=np.float64)
        vertices, faces = capsule_mesh(np.stack((c, c), axis=1), np.asarray(radius))
        self._face = self._mesh(self._face, vertices, faces, self._face_material, placed=True)

    def set_scenery(self, vertices: FloatArray, faces: NDArray[np.int64]) -> None:
        """Show a static mesh (world coordinates) beside the body, grey; shaded renders
        only (silhouettes stay the body's alone)."""
        material = self._pyrender.MetallicRoughnessMaterial(
            baseColorFactor=(0.45, 0.47, 0.5, 1.0), metallicFactor=0.0, roughnessFactor=0.9
        )
        self._scenery = self._mesh(self._scenery, vertices, faces, material, placed=True)

    def render(self, camera_pose: FloatArray) -> NDArray[np.uint8]:
        """The silhouette ``(H, W)`` (1 inside) seen from the camera-to-world ``camera_pose``."""
        self._scene.set_pose(self._camera, np.asarray(camera_pose, dtype=np.float64))
        extras = [n for n in (self._scenery, self._face) if n is not None]
        for node in extras:
            node.mesh.is_visible = False
        depth = self._r.render(self._scene, flags=self._pyrender.RenderFlags.DEPTH_ONLY)
        for node in extras:
            node.mesh.is_visible = True
        self.renders += 1
        return (np.asarray(depth) > 0).astype(np.uint8)

    def render_shaded(self, camera_pose: FloatArray) -> NDArray[np.uint8]:
        """A shaded RGB image ``(H, W, 3)`` of the body, lit from the camera."""
        pose = np.asarray(camera_pose, dtype=np.float64)
        self._scene.set_pose(self._camera, pose)
        self._scene.set_pose(self._light, pose)
        color, _ = self._r.render(self._scene)
        self.renders += 1
        return np.asarray(color, dtype=np.uint8)

    def close(self) -> None:
        self._r.delete()

    def __enter__(self) -> GLRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
