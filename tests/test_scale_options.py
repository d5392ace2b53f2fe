"""``bench_scale`` measures the graph ``mimic perform`` builds."""

from __future__ import annotations

from benchmarks.bench_scale import PERFORM_GRAPH
from mimic.args import graph_options
from mimic.cli import build_parser
from vision import VISION_COORDS


def test_the_scale_benchmarks_graph_is_the_one_perform_builds() -> None:
    args = build_parser().parse_args(["perform", "--video", "x.mkv"])
    assert graph_options(args) == PERFORM_GRAPH and PERFORM_GRAPH.coords == VISION_COORDS
