"""The digest of a set of clips: what the caches and the bank key their artifacts by."""

from __future__ import annotations

import threading
import weakref
from collections.abc import Sequence
from hashlib import blake2b, sha256

import numpy as np

from ._library import Clip

__all__ = ["clips_digest"]

#: the last few digests, by the clips' identities (``clips_digest``)
_RECENT: dict[tuple[int, ...], tuple[list[weakref.ref[Clip]], str, str]] = {}
_KEEP = 4
_LOCK = threading.Lock()


def _arrays(c: Clip) -> tuple[np.ndarray, ...]:
    """The arrays of a clip that its digest covers."""
    m = c.motion
    return (m.root_pos, m.quats, m.skeleton.offsets, c.contacts.states)


def _writeable_part(clips: Sequence[Clip]) -> str:
    """A digest of the clips' arrays that are not read-only (the contact states): what
    could change in place under a remembered digest."""
    h = blake2b(digest_size=16)
    for c in clips:
        for arr in _arrays(c):
            if arr.flags.writeable:
                h.update(np.ascontiguousarray(arr).tobytes())
    return h.hexdigest()


def clips_digest(clips: Sequence[Clip]) -> str:
    """SHA-256 of the clips' names, rates, motions and contacts.

    A start-up asks for it three times (graph, bank, bank check): at 500,000 frames each
    took 0.3 s. The last few are remembered by the clips' identities (a ``Clip`` is
    frozen and compared by identity; its motion's arrays are read-only) together with a
    digest of its arrays that are writeable, so an array changed in place is noticed."""
    key = tuple(id(c) for c in clips)
    loose = _writeable_part(clips)
    with _LOCK:
        got = _RECENT.get(key)
    if got is not None:
        refs, digest, was = got
        if was == loose and all(r() is c for r, c in zip(refs, clips, strict=True)):
            return digest
    h = sha256()
    for c in clips:
        m = c.motion
        h.update(f"{c.name}|{m.fps}|{m.n_frames}|{','.join(m.skeleton.names)}".encode())
        for arr in _arrays(c):
            h.update(np.ascontiguousarray(arr).tobytes())
    digest = h.hexdigest()
    with _LOCK:
        _RECENT[key] = ([weakref.ref(c) for c in clips], digest, loose)
        while len(_RECENT) > _KEEP:
            del _RECENT[next(iter(_RECENT))]
    return digest
