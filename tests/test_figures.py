"""The headline figures on the README and the benchmarks' page are the results' own:
``benchmarks/figures.py`` makes the table from ``benchmarks/results/*.json``."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from benchmarks import figures


@pytest.mark.parametrize("page", figures.PAGES, ids=lambda p: p.name)
def test_the_table_on_each_page_is_made_from_the_results(page: Path) -> None:
    text = page.read_text()
    block = text.split(figures.START)[1].split(figures.END)[0]
    assert block.strip() == figures.table().strip(), (
        f"{page}: the figures differ from benchmarks/results (python -m benchmarks.figures --write)"
    )


def test_a_page_without_its_markers_is_named() -> None:
    with pytest.raises(ValueError, match=r"page\.md: needs one"):
        figures.replaced("no markers here", "| a |\n", "page.md")
    text = f"a\n{figures.START}\nold\n{figures.END}\nb\n"
    assert (
        figures.replaced(text, "| new |\n", "p")
        == f"a\n{figures.START}\n| new |\n{figures.END}\nb\n"
    )


def _result(curves: list[list[dict[str, float | None]]]) -> dict[str, object]:
    """A ``bench_accuracy`` result of one fold whose runs have these pose curves."""
    runs = [
        {
            "curve": [{"lag": c["lag"], "label_agreement_known_actions": 0.9, **c} for c in curve],
            "switches_per_minute": {
                "avatar": 12.0,
                "avatar_brief_actions_under_0.5s": 1.0,
                "performer": 8.0,
            },
        }
        for curve in curves
    ]
    return {"folds": [{"runs": runs}]}


def test_the_pose_score_where_the_library_has_the_action_is_told_where_known(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(figures, "RESULTS", tmp_path)
    both = [
        [
            {"lag": 0.0, "score": 0.5, "score_known_actions": 0.8},
            {"lag": 0.5, "score": 0.4, "score_known_actions": 0.7},
        ],
        [
            {"lag": 0.0, "score": 0.6, "score_known_actions": 0.6},
            {"lag": 2.0, "score": 0.9, "score_known_actions": 0.9},
        ],
    ]
    (tmp_path / "a.json").write_text(json.dumps(_result(both)))
    runs = figures._runs("a.json")
    # each run's best within 1 s of lag, as the pose score itself is taken
    assert runs["pose"] == pytest.approx(0.55)
    assert runs["pose_known"] == pytest.approx(0.7)
    assert figures._known(runs) == " (0.700 where the library has the performer's action)"
    # a result written before the figure existed (or a run without it) says nothing of it
    older = [[{"lag": 0.0, "score": 0.5, "score_known_actions": 0.8}], [{"lag": 0.0, "score": 0.6}]]
    (tmp_path / "b.json").write_text(json.dumps(_result(older)))
    runs = figures._runs("b.json")
    assert math.isnan(runs["pose_known"]) and figures._known(runs) == ""
