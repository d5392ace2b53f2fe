"""A pose model that takes the performer's left for their right in some frames and not
in others (``PoseDescriptor.sides``), as it does reading a performer from behind."""

from __future__ import annotations

import numpy as np
import pytest

from silhouette_bank import Bank, PoseDescriptor
from vision import Matcher


def test_a_window_whose_sides_flip_is_found_as_if_none_did(setup, pose_bank: Bank, monkeypatch):
    """A library window seen from behind (view 9 of 18: every frame's shoulders and hips
    in the back's left-right order), with the sides swapped in two frames of three: the
    matcher finds the window it finds for the frames as they were, at the same cost.
    Read only as given, the mixture fits no window nearly as well."""
    _, layer, _ = setup
    m = Matcher(layer, pose_bank)
    desc = m.desc
    assert isinstance(desc, PoseDescriptor)
    rows = m.windows.to_bank[np.arange(100, 100 + m.n)]
    performer = pose_bank.features[rows, 9].astype(np.float64)
    shoulders, hips = performer[:, 0] - performer[:, 2], performer[:, 12] - performer[:, 14]
    assert (shoulders < -desc.side_margin).all() and (hips < -desc.side_margin).all()
    flipped = np.arange(m.n) % 3 != 0
    mixed = performer.copy()
    mixed[flipped] = desc.swap(performer[flipped])
    assert len(desc.variants(mixed)) == 3 and len(desc.variants(performer)) == 1
    clean = m.find_window(performer, exact=True)
    assert clean is not None and clean[1] == 9
    assert m.find_window(mixed, exact=True) == pytest.approx(clean)
    monkeypatch.setattr(PoseDescriptor, "sides", lambda self, x: [])
    as_given = m.find_window(mixed, exact=True)
    assert as_given is None or as_given[2] > 2.0 * clean[2]
