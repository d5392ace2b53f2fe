"""How fast this machine renders the bank: silhouettes a second of one worker, measured
on a few frames of a clip (``mimic library info``'s estimate of a cold build)."""

from __future__ import annotations

import time

import numpy as np

from control.motion import Clip

from ._body import capsule_body
from ._render import motion_features
from ._settings import BankSettings

__all__ = ["render_rate"]


def render_rate(
    clip: Clip, settings: BankSettings | None = None, frames: int = 60, repeats: int = 3
) -> float:
    """Silhouettes a second that one worker renders here: ``frames`` frames of ``clip``
    (spread over it) in every view of ``settings``' ring, with its body and descriptor,
    as the bank's shards are made (after a frame's render that compiles the kernels);
    the best of ``repeats`` renders, the one least held up by other work."""
    st = settings or BankSettings()
    motion = clip.motion
    if motion.n_frames == 0:
        raise ValueError(f"{clip.name}: no frames to render")
    body = capsule_body(motion.skeleton, st.body)
    pick = np.unique(np.linspace(0, motion.n_frames - 1, frames).round().astype(np.int64))
    motion_features(motion, body, st.ring, pick[:1], descriptor=st.descriptor)  # (compile)
    took = float("inf")
    for _ in range(max(1, repeats)):
        t0 = time.perf_counter()
        motion_features(motion, body, st.ring, pick, descriptor=st.descriptor)
        took = min(took, max(time.perf_counter() - t0, 1e-9))
    return pick.size * st.ring.n_views / took
