"""Fixtures shared by the vision tests: a small real library (13_30), its graph, layer
and default bank, built once per session, and its pose bank."""

from __future__ import annotations

from pathlib import Path

import pytest

from control.clusters import HigherLayer, LayerSettings, build_higher_layer
from control.graph import GraphOptions, build_graph
from control.motion import Library, load_library
from silhouette_bank import Bank, BankSettings, cached_bank
from tests.conftest import REPO, Prebuild
from vision import person_segmentation_available

RECORDING = REPO / "recordings" / "13_29_first12s_160x120.mkv"


@pytest.fixture(scope="session")
def setup(mocap: Path, prebuild: Prebuild) -> tuple[Library, HigherLayer, Bank]:
    # the bank goes into the tests' shared cache (conftest's _private_cache): it is the
    # one `mimic perform --clips 13_30` uses, so that the command-line tests load it
    # rather than build it again; tests/prebuild.py builds it in the background
    lib = load_library(mocap, clips=["13_30"])
    g = build_graph(lib.clips, GraphOptions(coords="relative", threshold=0.03))
    layer = build_higher_layer(g, lib.clips, LayerSettings(k=12))
    prebuild.wait("bank")
    bank, _, _ = cached_bank(lib.clips, BankSettings(), workers=2)
    return lib, layer, bank


@pytest.fixture(scope="session")
def pose_bank(setup: tuple[Library, HigherLayer, Bank]) -> Bank:
    """The pose bank of ``setup``'s library (the one ``mimic perform --clips 13_30``
    builds for a silhouette video's landmarks: tests/prebuild.py, part ``bank``)."""
    if not person_segmentation_available():
        pytest.fail("MediaPipe is needed here (see the README's install line)")
    lib, _, _ = setup
    bank, _, _ = cached_bank(lib.clips, BankSettings(descriptor="pose"), workers=2)
    return bank
