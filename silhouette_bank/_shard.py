"""One shard of a bank rendered: the features and root motion of its frames in every view
(and body variant) of the bank's settings, by the rasterizer, the GL renderer or, for the
pose descriptor, the projected joints. A job of ``control.jobs.run_jobs``."""

from __future__ import annotations

import numpy as np

from control.motion import Motion

from ._body import BodyShape, capsule_body
from ._pose import motion_pose_features
from ._render import motion_features_both
from ._settings import BankSettings

__all__ = ["ShardJob", "shard_job"]

#: ``(index, [(motion, first, stop)], settings, file)``: a shard's pieces of clips
ShardJob = tuple[int, list[tuple[Motion, int, int]], BankSettings, str]


def shard_job(
    job: ShardJob,
) -> tuple[int, dict[str, np.ndarray]]:
    """Render one shard (``[(motion, first, stop)]`` pieces of clips): its index and
    arrays (the process that runs the build writes them: ``_write_shard``)."""
    index, pieces, settings, _ = job
    feats, moves = [], []
    gl = None
    for motion, a, b in pieces:
        frames = np.arange(a, b)
        if settings.descriptor == "pose":
            f, m = motion_pose_features(motion, settings.ring, frames)
        elif settings.renderer == "raster":
            parts = _variant_features(motion, settings, frames)
            f = np.concatenate([p[0] for p in parts], axis=1)
            m = np.concatenate([p[1] for p in parts], axis=1)
        else:
            from ._gl import GLRenderer
            from ._render import gl_features

            gl = gl or GLRenderer(settings.ring)
            body = capsule_body(motion.skeleton, settings.body)
            f, m = gl_features(gl, motion, body, settings.ring, frames, settings.descriptor)
        feats.append(f)
        moves.append(m)
    if gl is not None:
        gl.close()
    return index, {"features": np.concatenate(feats), "root_motion": np.concatenate(moves)}


def _variant_features(
    motion: Motion, settings: BankSettings, frames: np.ndarray
) -> list[tuple[np.ndarray, np.ndarray]]:
    """``motion_features`` of each of ``settings.variants``, in bank order; a body with
    and without a shadow rasterized once (``motion_features_both``)."""
    shadows: dict[BodyShape, list[bool]] = {}
    for shape, sh in settings.variants:
        shadows.setdefault(shape, []).append(sh)
    got = {}
    for shape, which in shadows.items():
        body = capsule_body(motion.skeleton, shape)
        seen = motion_features_both(
            motion, body, settings.ring, frames, descriptor=settings.descriptor, shadows=(*which,)
        )
        got.update({(shape, sh): fm for sh, fm in zip(which, seen, strict=True)})
    return [got[v] for v in settings.variants]
