"""Two processes that ask for the same graph, layer, bank and window index at once (the
cache front doors): one builds each, the other waits and loads it, and the cache holds one
good entry of each."""

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
from silhouette_bank import BankSettings, CameraRing, cached_bank
lib = load_library(sys.argv[1], clips=["13_30"])
while time.time() < float(sys.argv[3]):  # (both start together)
    time.sleep(0.005)
g, _, built_g = cached_graph(lib.clips, GraphOptions(coords="relative"), cache_dir=sys.argv[2])
layer, _, built_l = cached_higher_layer(g, lib.clips, LayerSettings(k=12), cache_dir=sys.argv[2])
small = BankSettings(CameraRing(n_views=4, width=64, height_px=48), descriptor="hu")
bank, _, built_b = cached_bank(lib.clips, small, cache_dir=sys.argv[2], workers=1)
from pathlib import Path
from vision import Matcher, MatchSettings, _index_store, _summaries
m = Matcher(layer, bank, MatchSettings())
shape, centre, starts = m.windows.tables()
# the window index: one process has done its jobs (kept as parts) and not yet filled its
# lists when the other asks for the index
kept = Path(sys.argv[2]).with_name("jobs-kept")
if sys.argv[4] == "first":
    jobs = _summaries.run_jobs
    _summaries.run_jobs = lambda *a: (jobs(*a), kept.touch(), time.sleep(2.0))[0]
else:
    deadline = time.time() + 120
    while not kept.exists() and time.time() < deadline:
        time.sleep(0.01)
# (an inverted file, as a large library's: built in jobs kept as parts)
_index_store.cached_window_index(shape, centre, starts, m.n, bank.path, m.windows.key, flat_below=0)
out = {"graph": built_g, "layer": built_l, "bank": built_b, "k": int(layer.clustering.k)}
print(json.dumps({**out, "frames": bank.n_frames}))
"""


@pytest.mark.slow
def test_two_processes_build_a_graph_a_layer_and_a_bank_once(mocap: Path, tmp_path: Path) -> None:
    import time

    cache = tmp_path / "cache"
    start = str(time.time() + 3.0)
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", CHILD, str(mocap), str(cache), start, pace],
            cwd=REPO,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for pace in ("first", "second")
    ]
    got = []
    for p in procs:
        out, err = p.communicate(timeout=300)
        assert p.returncode == 0, err
        got.append(json.loads(out.strip().splitlines()[-1]))
    assert sorted(g["graph"] for g in got) == [False, True]  # one built it, one loaded it
    assert sorted(g["layer"] for g in got) == [False, True]
    assert sorted(g["bank"] for g in got) == [False, True] and got[0]["frames"] == got[1]["frames"]
    manifests = list(cache.glob("*/manifest.json"))
    assert len(manifests) == 1 and json.loads(manifests[0].read_text())["complete"]
    assert len(list(cache.glob("graph-*.npz"))) == 1 and len(list(cache.glob("layer-*.npz"))) == 1
    assert not list(cache.glob(".*.tmp"))
    bank = manifests[0]
    assert len(list(bank.parent.glob("index-*.npz"))) == 1
    assert not list(bank.parent.glob("index-*.parts"))
