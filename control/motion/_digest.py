"""The digest of a set of clips: what the caches and the bank key their artifacts by."""

from __future__ import annotations

import hashlib
from collections.abc import Sequence

import numpy as np

from ._library import Clip

__all__ = ["clips_digest"]


def clips_digest(clips: Sequence[Clip]) -> str:
    """SHA-256 of the clips' names, rates, motions and contacts."""
    h = hashlib.sha256()
    for c in clips:
        m = c.motion
        h.update(f"{c.name}|{m.fps}|{m.n_frames}|{','.join(m.skeleton.names)}".encode())
        for arr in (m.root_pos, m.quats, m.skeleton.offsets, c.contacts.states):
            h.update(np.ascontiguousarray(arr).tobytes())
    return h.hexdigest()
