"""Two processes that ask for the same graph and layer at once: one builds each, the
other waits and loads it, and the cache holds one good entry of each."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import REPO

CHILD = """
import json, sys, time
from control.clusters import LayerSettings, cached_higher_layer
from control.graph import GraphOptions, cached_graph
from control.motion import load_library
lib = load_library(sys.argv[1], clips=["13_30"])
while time.time() < float(sys.argv[3]):  # (both start together)
    time.sleep(0.005)
g, _, built_g = cached_graph(lib.clips, GraphOptions(coords="relative"), cache_dir=sys.argv[2])
layer, _, built_l = cached_higher_layer(g, lib.clips, LayerSettings(k=12), cache_dir=sys.argv[2])
print(json.dumps({"graph": built_g, "layer": built_l, "k": int(layer.clustering.k)}))
"""


@pytest.mark.slow
def test_two_processes_build_a_graph_and_a_layer_once(mocap: Path, tmp_path: Path) -> None:
    import time

    cache = tmp_path / "cache"
    start = str(time.time() + 3.0)
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", CHILD, str(mocap), str(cache), start],
            cwd=REPO,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for _ in range(2)
    ]
    got = []
    for p in procs:
        out, err = p.communicate(timeout=300)
        assert p.returncode == 0, err
        got.append(json.loads(out.strip().splitlines()[-1]))
    assert sorted(g["graph"] for g in got) == [False, True]  # one built it, one loaded it
    assert sorted(g["layer"] for g in got) == [False, True]
    assert len(list(cache.glob("graph-*.npz"))) == 1 and len(list(cache.glob("layer-*.npz"))) == 1
    assert not list(cache.glob(".*.tmp"))
