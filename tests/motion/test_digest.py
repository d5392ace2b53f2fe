"""The clips' digest, which keys the graph, layer and bank caches, and its memory."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from control.motion import Contacts, Library, clips_digest


def test_the_digest_is_remembered_and_still_sees_a_change(
    walk_lib: Library, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Asked again for the same clips, the digest is the remembered one (no hashing of
    the motions); the same content in new clips gives the same digest; a contact state
    changed in place (the one writeable array) or another motion gives another."""
    from control.motion import _digest

    clips = list(walk_lib.clips)
    first = clips_digest(clips)
    hashed: list[int] = []
    real = _digest.sha256

    def counted(*args: object) -> object:
        hashed.append(1)
        return real(*args)

    monkeypatch.setattr(_digest, "sha256", counted)
    assert clips_digest(clips) == first and not hashed
    copies = [dataclasses.replace(c) for c in clips]
    assert clips_digest(copies) == first and hashed  # new clips: hashed again
    states = clips[0].contacts.states
    assert states.flags.writeable
    states[0, 0] = not states[0, 0]
    try:
        assert clips_digest(clips) != first
    finally:
        states[0, 0] = not states[0, 0]
    assert clips_digest(clips) == first
    st = clips[1].contacts
    other = dataclasses.replace(
        clips[1], contacts=Contacts(np.roll(st.states, 1, axis=0), st.ankle_rest, st.toe_rest)
    )
    assert clips_digest([clips[0], other, *clips[2:]]) != first
