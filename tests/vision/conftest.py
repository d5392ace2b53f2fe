"""Fixtures shared by the vision tests: a small real library (13_30), its graph, layer
and default bank, built once per session."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from control.clusters import HigherLayer, build_higher_layer
from control.graph import GraphOptions, build_graph
from control.motion import Library, Motion, load_library
from silhouette_bank import Bank, BankSettings, ensure_bank, with_proportions
from tests.conftest import REPO, Prebuild

RECORDING = REPO / "recordings" / "13_29_first12s_160x120.mkv"


def landmark_points(motion: Motion, frames: np.ndarray, seed: int) -> np.ndarray:
    """Image points ``(F, 12, 2)`` of ``motion``'s joints at ``frames`` as a pose model
    would give them: on ``mimic record``'s default body, seen by its camera, with noise
    of 3% of the torso length (as ``benchmarks/_landmarks.py``)."""
    from silhouette_bank._pose import joint_points
    from vision import RecordSettings

    rs = RecordSettings()
    ring = rs.ring()
    pts = joint_points(with_proportions(motion, rs.body), frames)
    pose = ring.poses(motion.root_pos[frames].mean(axis=0))[0]
    px = ring.project(ring.to_camera(pts, np.broadcast_to(pose, (frames.size, 4, 4))))
    torso = np.linalg.norm(px[:, :2].mean(axis=1) - px[:, 6:8].mean(axis=1), axis=-1)
    noise = np.random.default_rng(seed).normal(0.0, 0.03, px.shape)
    return np.asarray(px + noise * torso[:, None, None])


@pytest.fixture(scope="session")
def setup(mocap: Path, prebuild: Prebuild) -> tuple[Library, HigherLayer, Bank]:
    # the bank goes into the tests' shared cache (conftest's _private_cache): it is the
    # one `mimic perform --clips 13_30` uses, so that the command-line tests load it
    # rather than build it again; tests/prebuild.py builds it in the background
    lib = load_library(mocap, clips=["13_30"])
    g = build_graph(lib.clips, GraphOptions(coords="relative", threshold=0.03))
    layer = build_higher_layer(g, lib.clips, k=12)
    prebuild.wait("bank")
    bank, _ = ensure_bank(lib.clips, BankSettings(), workers=2)
    return lib, layer, bank
