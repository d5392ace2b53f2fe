"""Parametric actions (Peng et al. §6, Fig. 10): examples of one action blended so that the
avatar reaches a point the game names.

``ParametricAction`` takes a reference example (library frames), finds the action's other
instances (``find_examples``), time-aligns each to the reference (``register``) with its
root aligned (heading 0 and floor position 0 at its first aligned frame: the *action
frame*, x left, y up, z forward), and gives each its parameter: where the ``effector``
(a joint role, e.g. ``right_wrist``; ``root`` for where a jump lands, on the floor;
``turn`` for the angle turned, as ``(degrees, 0, 0)``) is at the key frame in the action
frame. The key frame is the reference frame where the effector is farthest
from where it started (a strike's apex), or the last frame (``key="end"``).

Blending: the weights of a target are convex (non-negative, summing to one), so every
blended frame is an average of real poses, and local: non-negative least squares of the
examples' parameters against the target, with a penalty on far examples' weights
(``locality``). Neither inverse-distance weights nor radial basis functions (the issue's
suggestions) are used: inverse distance falls short of targets between examples (its
weights flatten out towards each example: 6.1 cm off on average at random targets inside
the hull of the strikes of 02_05, against 2.8 cm here and 10.5 cm for the nearest single
example, ``benchmarks/bench_parametric.py``) and an RBF's negative weights extrapolate
rotations. A blend's effector is not the weights' average of the examples'
(averaging an arm's angles shortens its reach: 4-7 cm on the strikes), so the fit is
repeated twice with each example's parameter replaced by where moving the weights
towards it takes the blend (Gauss-Newton on the key frame; ``solve``). The paper's voxels
are here too: a grid over the examples' box whose centres inside their hull hold solved
weights, read trilinearly with ``request(voxels=True)``, faster and less exact
(``benchmarks/bench_parametric.py``). The blend averages, per aligned frame, the
examples' joint rotations (weighted quaternion sums, signs aligned) and root positions;
a foot is held still (leg IK) at the mean place of each contact the blended motion's own
contacts show, the correction fading in and out. Outside the hull a target is clamped
to its nearest point in the hull, and the answer says so.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import nnls

from ..graph import FrameFeatures, knee_hinge, leg_chain, rotate_y, solve_leg, yaw_of, yaw_q
from ..motion import Motion, Skeleton, detect_contacts, forward_kinematics, qmul, role_point
from ._examples import Example, find_examples, register

__all__ = ["Blend", "ParametricAction"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True, eq=False)
class Blend:
    """One answered request: the blended ``motion`` (action frame), the ``weights`` per
    example, the ``target`` asked for (after clamping), what the effector ``reached``
    at the key frame, and whether the target was ``clamped`` into the hull."""

    motion: Motion
    weights: FloatArray
    target: FloatArray
    reached: FloatArray
    clamped: bool


class ParametricAction:
    """The examples of one action, registered, with their parameters and the voxel grid.

    ``root`` (N, 3) and ``quats`` (N, J, 4) are the library's frames end to end (as
    ``feat``'s); ``reference`` the example ``(start, stop)``; ``max_cost`` as
    ``find_examples``'s.
    """

    def __init__(
        self,
        feat: FrameFeatures,
        root: FloatArray,
        quats: FloatArray,
        skeleton: Skeleton,
        fps: float,
        reference: tuple[int, int],
        effector: str = "right_wrist",
        key: str = "apex",
        nu: float = 0.01,
        max_cost: float = 0.5,
        grid: int = 6,
        locality: float = 0.1,
    ) -> None:
        if key not in ("apex", "end"):
            raise ValueError(f"key must be 'apex' or 'end', got {key!r}")
        self.skeleton, self.fps = skeleton, fps
        self.effector = effector
        plain = effector in ("root", "turn")
        self._point = None if plain else role_point(skeleton, effector)
        self.examples: list[Example] = find_examples(feat, reference[0], reference[1], nu, max_cost)
        ref = np.arange(reference[0], reference[1], dtype=np.int64)
        roots, rots, aligned = [], [], []
        for ex in self.examples:
            frames = np.arange(ex.start, ex.stop, dtype=np.int64)
            where = register(feat, ref, frames, nu) if ex.start != reference[0] else None
            r, q = _resampled(root[frames], quats[frames], where)
            roots.append(r)
            rots.append(q)
            aligned.append(frames[np.round(where).astype(np.int64)] if where is not None else ref)
        #: (E, m) the library frame of each example nearest each reference frame
        self.aligned = np.stack(aligned)
        self.roots = np.stack(roots)  # (E, m, 3), action frame
        self.quats = np.stack(rots)  # (E, m, J, 4)
        tracks = np.stack([self._track(r, q) for r, q in zip(self.roots, self.quats, strict=True)])
        ref_track = tracks[0]
        self.key = (
            ref.size - 1
            if key == "end"
            else int(np.argmax(np.linalg.norm(ref_track - ref_track[0], axis=1)))
        )
        self.params = tracks[:, self.key]  # (E, 3)
        gaps = np.linalg.norm(self.params[:, None] - self.params[None], axis=-1)
        self.spread = float(np.median(gaps[gaps > 0])) if (gaps > 0).any() else 1.0
        self.locality = locality
        self._grid(grid)

    # --- the parameter -------------------------------------------------------------

    def _track(self, root: FloatArray, quats: FloatArray) -> FloatArray:
        """The effector's path ``(m, 3)`` in the action frame (the root's on the floor:
        its height is not a target; for ``turn``, ``(degrees turned, 0, 0)``)."""
        if self.effector == "turn":  # (the action frame's heading is 0 where it begins)
            turned = np.degrees(np.unwrap(np.concatenate(([0.0], yaw_of(quats[:, 0]))))[1:])
            return np.stack((turned, np.zeros_like(turned), np.zeros_like(turned)), axis=1)
        if self._point is None:
            return root * np.array([1.0, 0.0, 1.0])
        pose = forward_kinematics(Motion(self.skeleton, root, quats, self.fps))
        kind, j = self._point
        return (pose.positions if kind == "joint" else pose.end_positions)[:, j]

    def weights(self, target: FloatArray, params: FloatArray | None = None) -> FloatArray:
        """Convex weights ``(E,)`` whose average parameter is ``target``, preferring near
        examples: non-negative least squares of ``params.T @ w = target`` with ``sum(w) =
        1`` and a penalty ``locality * (d_i / spread) * w_i`` (``d_i`` the example's
        distance from ``target``); one-hot at an example's own parameter."""
        t = np.asarray(target, dtype=np.float64)
        d = np.linalg.norm(self.params - t, axis=1)
        if d.min() < 1e-9:
            w = np.zeros(d.size)
            w[int(np.argmin(d))] = 1.0
            return w
        big = 1e3
        p = self.params if params is None else params
        a = np.vstack((p.T, np.diag(self.locality * d / self.spread), np.full(d.size, big)))
        b = np.concatenate((t, np.zeros(d.size), [big]))
        w, _ = nnls(a, b)
        return w / max(w.sum(), 1e-12)

    def reached(self, weights: FloatArray) -> FloatArray:
        """Where the blends of ``weights`` ``(E,)`` or ``(K, E)`` put the effector at the
        key frame: ``(3,)`` or ``(K, 3)``."""
        w = np.atleast_2d(np.asarray(weights, dtype=np.float64))
        k = self.key
        parts = [_blend_frames(self.roots[:, k : k + 1], self.quats[:, k : k + 1], x) for x in w]
        root = np.concatenate([r for r, _ in parts])
        quats = np.concatenate([q for _, q in parts])
        out = self._track(root, quats)
        return out if np.ndim(weights) == 2 else out[0]

    def solve(self, target: FloatArray, steps: int = 2) -> FloatArray:
        """The weights whose blend puts the effector at ``target``: the linear fit
        (``weights``), then ``steps`` Gauss-Newton steps on the blend itself, each fitting
        again with every example's parameter replaced by where moving the weights
        towards it takes the blend (a finite difference: the blend's effector is not
        linear in the weights, as an arm's reach is not in its angles)."""
        t = np.asarray(target, dtype=np.float64)
        w = self.weights(t)
        h = 0.05
        for _ in range(steps):
            if w.max() >= 1.0:  # an example's own parameter: that example
                break
            n = w.size
            trial = np.vstack((w, w + h * (np.eye(n) - w)))
            r = self.reached(trial)
            seen = r[0] + (r[1:] - r[0]) / h  # each example's parameter as seen from w
            w = self.weights(t, seen)
        return w

    # --- the voxels ----------------------------------------------------------------

    def _grid(self, n: int) -> None:
        lo, hi = self.params.min(axis=0), self.params.max(axis=0)
        self.lo, self.step = lo, np.maximum((hi - lo) / max(n - 1, 1), 1e-9)
        axes = [lo[i] + self.step[i] * np.arange(n) for i in range(3)]
        centres = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        table = np.full((centres.shape[0], len(self.params)), np.nan)
        for i, c in enumerate(centres):
            if self.inside(c):
                table[i] = self.solve(c, 3)
        self.table = table.reshape(n, n, n, -1)

    def inside(self, target: FloatArray) -> bool:
        """Whether ``target`` lies in the convex hull of the examples' parameters."""
        return _same_point(self.clamp(target), target)

    def clamp(self, target: FloatArray) -> FloatArray:
        """The point of the examples' hull nearest ``target`` (non-negative least squares
        with the weights' sum held at one)."""
        big = 1e3
        a = np.vstack((self.params.T, np.full(len(self.params), big)))
        b = np.concatenate((np.asarray(target, dtype=np.float64), [big]))
        w, _ = nnls(a, b)
        return np.asarray(self.params.T @ (w / max(w.sum(), 1e-12)), dtype=np.float64)

    def voxel_weights(self, target: FloatArray) -> FloatArray:
        """The voxels' weights at ``target``: trilinear over the corners of its voxel that
        lie in the hull (renormalised; ``weights`` where none does)."""
        n = self.table.shape[0]
        x = np.clip((target - self.lo) / self.step, 0, n - 1 - 1e-9)
        i0 = np.floor(x).astype(int)
        f = x - i0
        acc, wsum = np.zeros(self.table.shape[-1]), 0.0
        for corner in np.ndindex(2, 2, 2):
            v = self.table[tuple(np.minimum(i0 + np.array(corner), n - 1))]
            if np.isfinite(v).all():
                w = float(np.prod(np.where(np.array(corner), f, 1.0 - f)))
                acc += w * v
                wsum += w
        return acc / wsum if wsum > 0 else self.weights(target)

    # --- requests ------------------------------------------------------------------

    def request(
        self, target: FloatArray | tuple[float, float, float], voxels: bool = False
    ) -> Blend:
        """The blend that puts the effector at ``target`` (action frame) at the key frame:
        its weights solved (``solve``), or with ``voxels`` read from the precomputed
        grid (faster, less exact: ``benchmarks/bench_parametric.py``)."""
        t = np.asarray(target, dtype=np.float64)
        if t.shape != (3,) or not np.isfinite(t).all():
            raise ValueError(f"a target is three finite numbers (x, y, z), got {target!r}")
        near = self.clamp(t)
        clamped = not _same_point(near, t)
        if clamped:
            t = near
        w = self.voxel_weights(t) if voxels else self.solve(t)
        if w.max() == 1.0:  # an example's own parameter: that example, as captured
            i = int(np.argmax(w))
            root, quats = self.roots[i].copy(), self.quats[i].copy()
        else:
            root, quats = _blend_frames(self.roots, self.quats, w)
            quats = _plant(self.skeleton, self.fps, root, quats)
        motion = Motion(self.skeleton, root, quats, self.fps, name="blend", source="parametric")
        return Blend(motion, w, t, self._track(root, quats)[self.key], clamped)


def _same_point(a: FloatArray, b: FloatArray) -> bool:
    """Whether a target and its nearest point of the hull are one (within 1e-6)."""
    return bool(np.linalg.norm(np.asarray(a) - np.asarray(b)) < 1e-6)


def _resampled(
    root: FloatArray, quats: FloatArray, where: FloatArray | None
) -> tuple[FloatArray, FloatArray]:
    """An example at fractional frames ``where`` (``None``: as it is), in its action
    frame (heading 0 and floor position 0 at the first frame)."""
    if where is not None:
        lo = np.floor(where).astype(np.int64)
        hi = np.minimum(lo + 1, root.shape[0] - 1)
        f = (where - lo)[:, None]
        root = root[lo] * (1.0 - f) + root[hi] * f
        q_hi = quats[hi] * np.sign(np.sum(quats[lo] * quats[hi], axis=-1, keepdims=True))
        quats = quats[lo] * (1.0 - f[..., None]) + q_hi * f[..., None]
        quats = quats / np.linalg.norm(quats, axis=-1, keepdims=True)
    yaw = float(yaw_of(quats[0, 0]))
    out_r = rotate_y(root - np.array([root[0, 0], 0.0, root[0, 2]]), -yaw)
    out_q = quats.copy()
    out_q[:, 0] = qmul(yaw_q(-yaw), quats[:, 0])
    return out_r, out_q


def _blend_frames(
    roots: FloatArray, quats: FloatArray, w: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The weighted average ``(m, 3), (m, J, 4)`` of examples ``(E, m, 3), (E, m, J, 4)``:
    root positions averaged, rotations as sign-aligned weighted quaternion sums."""
    lead = int(np.argmax(w))
    sign = np.sign(np.sum(quats * quats[lead], axis=-1, keepdims=True))
    sign[sign == 0] = 1.0
    q = np.einsum("e,e...->...", w, quats * sign)
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return np.einsum("e,e...->...", w, roots), q


def _plant(
    skeleton: Skeleton, fps: float, root: FloatArray, quats: FloatArray, fade: int = 3
) -> FloatArray:
    """``quats`` with each foot held still while the blended motion's own contacts say it
    is down: at the run's mean place, the correction fading in and out over ``fade``
    frames either side (a foot snapped to its place would jerk the knee)."""
    motion = Motion(skeleton, root, quats, fps)
    pose = forward_kinematics(motion)
    states = detect_contacts(motion, pose).states
    out = quats.copy()
    n = root.shape[0]
    for foot, side in enumerate(("left", "right")):
        chain = leg_chain(skeleton, side)
        ankle = pose.positions[:, chain[2]]
        shift = np.zeros_like(ankle)
        weight = np.zeros(n)
        c = np.concatenate(([0], states[:, foot].astype(np.int8), [0]))
        edges = np.diff(c)
        for s, e in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True):
            r = ankle[s:e].mean(axis=0) - ankle[s:e]  # inside the run: held at its mean
            shift[s:e] = r
            weight[s:e] = 1.0
            for k in range(1, fade + 1):  # outside it: the run's end corrections, fading
                x = 1.0 - k / (fade + 1)
                w = x * x * (3.0 - 2.0 * x)
                for f, edge in ((s - k, s), (e - 1 + k, e - 1)):
                    if 0 <= f < n and w > weight[f]:
                        shift[f], weight[f] = r[edge - s], w
        target = ankle + shift * weight[:, None]
        todo = np.flatnonzero(np.linalg.norm(target - ankle, axis=1) > 1e-5)
        if todo.size:
            hinge = knee_hinge(pose.positions, pose.orientations, chain)
            new = solve_leg(
                skeleton, pose.positions[todo], pose.orientations[todo], chain, target[todo], hinge
            )
            out[todo[:, None], np.array(chain)[None, :]] = new
    return out
