"""What the slowest session fixtures build, built in a background process from the
session's start (``conftest.prebuild``) while the first tests run on the other core: the
playground's graph and higher layer (the choice tests), the walks' higher layer (the
sketch tests), the 13_30 bank (the vision fixtures), what ``mimic perform --clips 13_30``
builds for landmarks (13_30 and its mirror image) and the colour films of 13_29 that the
view tests read with the pose model, into the tests' cache ($MIMIC_CACHE).

Each part, once built, leaves a marker ``prebuilt-<part>`` in the cache. A fixture that
needs a part waits for its marker (or for this process to end, whatever its outcome) and
then loads or builds as it would alone: the cache's entries are content-addressed and
checked on load, so a part built here is the one the fixture would build, and a part that
failed here is built by the fixture. The bank's build lock keeps a test that builds the
same bank meanwhile from building it twice.

Run as ``python -m tests.prebuild PART...`` with PART in ``PARTS``.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

#: the parts, in the order the tests need them (clusters, sketch, the commands run on
#: 13_30 with landmarks, then vision tests)
PARTS = ("playground", "walks", "bank", "mirrored", "films")


def build(part: str) -> None:
    """Build ``part`` into the cache, as its fixture does."""
    from control.motion import load_library
    from tests.conftest import MOCAP

    if part == "playground":  # tests/clusters/test_choice.py: playground
        from control.clusters import LayerSettings, cached_higher_layer
        from control.graph import GraphOptions, cached_graph

        lib = load_library(MOCAP, clips=["01_*"])
        graph, _, _ = cached_graph(lib.clips, GraphOptions())
        cached_higher_layer(graph, lib.clips, LayerSettings(k=25))
    elif part == "walks":  # tests/sketch/test_sketch.py: walks and actions
        from control.clusters import LayerSettings, cached_higher_layer
        from control.graph import GraphOptions, build_graph
        from tests.sketch.test_sketch import ACTIONS_LAYER, WALKS

        lib = load_library(MOCAP, clips=WALKS)
        graph = build_graph(lib.clips, GraphOptions(coords="relative"))
        cache = Path(os.environ["MIMIC_CACHE"]) / "graph"
        cached_higher_layer(graph, lib.clips, ACTIONS_LAYER, cache_dir=cache)
    elif part == "bank":  # tests/vision/conftest.py: setup
        from silhouette_bank import BankSettings, cached_bank

        lib = load_library(MOCAP, clips=["13_30"])
        cached_bank(lib.clips, BankSettings(), workers=1)
        # the pose bank that scores the landmarks read from a silhouette video's masks
        # (``mimic perform --clips 13_30`` on a silhouette video: ``vision._voice``)
        cached_bank(lib.clips, BankSettings(descriptor="pose"), workers=1)
    elif part == "mirrored":  # mimic perform --clips 13_30 --k 12 with landmarks
        build_mirrored()
    elif part == "films":  # tests/vision/test_views.py: films
        from tests.vision.test_views import FILMS, film

        for seconds, how in FILMS:
            film(MOCAP, Path(os.environ["MIMIC_CACHE"]) / "films", seconds, **how)
    elif part == "kernels":  # started apart from the others (conftest.prebuild)
        warm_kernels()
    else:
        raise ValueError(f"unknown part {part!r}: the parts are {', '.join(PARTS)}, kernels")


def build_mirrored() -> None:
    """The graph, higher layer and banks that ``mimic perform --clips 13_30 --k 12``
    builds for a colour video (13_30 and its mirror image: ``mimic.args.mirror_copies``),
    made by the command's own functions so that they are the ones it looks for."""
    from control.clusters import cached_higher_layer
    from control.graph import cached_graph
    from mimic.cli import build_parser
    from mimic.run import _clips, _graph_clips
    from mimic.run_args import run_settings
    from silhouette_bank import BankSettings, cached_bank
    from tests.conftest import MOCAP

    argv = ["perform", "--video", "-", str(MOCAP), "--clips", "13_30", "--k", "12"]
    settings = run_settings(build_parser().parse_args(argv))
    clips = _clips(settings, "pose")
    graph, _, _ = cached_graph(clips, settings.graph)
    clips = _graph_clips(graph, clips)
    cached_higher_layer(graph, clips, settings.layer)
    for bank in (BankSettings(descriptor="pose"), BankSettings()):  # (and the fallback's)
        cached_bank(clips, bank, workers=1)


def warm_kernels() -> None:
    """Compile, into numba's cache, the kernels that the tests use and the README's first
    command does not (3.6 s of compiling on a fresh checkout), with the one signature
    their wrappers give them (``control.kernels.kernel_input``): a test that gets there
    later loads them."""
    import numpy as np

    from control.clusters._paths import _viterbi
    from control.dtw import dtw_batch
    from control.kernels import kernel_input
    from control.sketch import Environment
    from control.transition._examples import _dtw_path, _subsequence_dtw

    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    Environment(obstacles=(square,), bounds=(-2.0, -2.0, 2.0, 2.0)).clearance(np.zeros((1, 2)))
    dtw_batch(np.zeros((2, 3)), np.zeros((2, 2, 3)), group=np.array([0, 1]), window=1)
    cost = kernel_input(np.ones((2, 3)), np.float64)
    _subsequence_dtw(cost)
    _dtw_path(cost)
    ints = kernel_input([0, 1], np.int64)
    zeros = kernel_input([0.0, 0.0], np.float64)
    _viterbi(
        0, ints, ints, zeros, kernel_input([0, 1, 1], np.int64), ints[1:], zeros[:1], zeros, 2, 10
    )


def main(parts: list[str]) -> None:
    cache = Path(os.environ["MIMIC_CACHE"])
    for part in parts:
        build(part)
        (cache / f"prebuilt-{part}").touch()


if __name__ == "__main__":
    main(sys.argv[1:])
